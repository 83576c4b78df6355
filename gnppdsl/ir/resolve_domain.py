"""A domain file -> `model.Domain`: types, constants, state and continuous declarations,
frames and templates, then the logic, rules and settings blocks by their own resolvers.

Separate from the module library because a domain is resolved once per file against modules the
workspace has already loaded; separate from `resolve_logic`, `resolve_rules` and
`resolve_settings` because those are also used for problems (logic, settings) or are a
language of their own (rules), and read only what this resolver has collected.
"""
from __future__ import annotations

from pathlib import Path

from gnppdsl.ir import builtins as B
from gnppdsl.ir import model as M
from gnppdsl.ir.expr import Param, Span
from gnppdsl.ir.families import group_names
from gnppdsl.ir.resolve_costs import resolve_action_cost
from gnppdsl.ir.resolve_logic import LogicResolver
from gnppdsl.ir.resolve_rules import RuleResolver
from gnppdsl.ir.resolve_settings import settings_reachability, settings_relaxations, settings_solver
from gnppdsl.ir.typecheck import OBJ, Checker, Scope
from gnppdsl.ir.modules import (DECL_WORDS, PRELUDE, RESERVED_TYPE_NAMES, VALUE_SPACES, ModuleEnv,
                                ModuleLibrary, merged_decls, note_param, qualified_consts)
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter, did_you_mean


class DomainResolver:
    """Resolves one domain file into a `model.Domain`; mistakes go to the workspace's reporter."""

    def __init__(self, ws: ModuleLibrary, f: ast.FileAst) -> None:
        self.ws = ws
        self.f = f
        self.r = ws.reporter
        self.name = f.header.name.value
        self.types: dict[str, M.Type] = {M.ROOT_TYPE: M.Type(M.ROOT_TYPE, None)}
        self.constants: dict[str, str] = {}
        self.state_vars: dict[str, M.StateVar] = {}
        self.derived: dict[str, M.Derived] = {}
        self.derived_ast: dict[str, ast.DerivedDecl] = {}
        self.actions: dict[str, M.Action] = {}
        self.continuous: dict[str, M.Continuous] = {}
        self.tags_seen: set[str] = set()

    def err(self, span, msg, kind="error", hint=None):
        self.r.error(span, msg, kind, hint)

    # ---- helpers for type names
    def is_subtype(self, sub: str, sup: str) -> bool:
        t: str | None = sub
        seen = set()
        while t is not None and t not in seen:
            if t == sup:
                return True
            seen.add(t)
            t = self.types[t].parent if t in self.types else None
        return False

    def check_type(self, n: ast.Name, extra: tuple[str, ...] = ()) -> bool:
        if n.value in self.types or n.value in extra:
            return True
        hint = did_you_mean(n.value, list(self.types) + list(extra))
        if n.value in VALUE_SPACES:
            hint = f"'{n.value}' is a value space; object types are declared with `type`"
        self.err(n.span, f"unknown type '{n.value}'", "unknown-type", hint)
        return False

    def typed_params(self, params: tuple[ast.Param, ...], what: str,
                     allow_untyped: bool = False, allow_union: bool = False) -> tuple[M.TypedParam, ...]:
        out = []
        seen: set[str] = set()
        for p in params:
            note_param(self.err, seen, p.name)
            if p.name.value in M.BUILTIN_VALUES:
                self.err(p.name.span, f"'{p.name.value}' is a builtin value and cannot be a parameter name",
                         "reserved")
            if not p.types:
                if not allow_untyped:
                    self.err(p.span, f"parameter '{p.name.value}' of {what} needs a type",
                             "missing-type", f"write `{p.name.value}: object` or a declared type")
                out.append(M.TypedParam(p.name.value, (), p.span))
                continue
            if len(p.types) > 1 and not allow_union:
                self.err(p.types[1].span, f"parameters of {what} have a single type", "type-union",
                         "declare a common supertype (`type a < t`, `type b < t`)")
            ok = all([self.check_type(t) for t in p.types])
            types = tuple(t.value for t in p.types) if ok else (M.ROOT_TYPE,)
            out.append(M.TypedParam(p.name.value, types, p.span))
        return tuple(out)

    # ---- main
    def run(self) -> M.Domain | None:
        f = self.f
        allowed = tuple(t for t in DECL_WORDS if t not in (ast.SceneRef, ast.ObjectsDecl,
                                                             ast.InitDecl, ast.GoalDecl)) + (ast.ContinuousDecl,)
        self.ws._reject(f, allowed, "a domain")
        self.modules = self.ws._uses(f)
        self.closure: list[ModuleEnv] = []
        for m in self.modules:
            for x in m.closure():
                if not any(x is y for y in self.closure):
                    self.closure.append(x)
        self.resolve_types()
        items = f.items
        for d in items:
            if isinstance(d, ast.ConstantsDecl):
                for g in d.groups:
                    if not self.check_type(g.type):
                        continue
                    for n in group_names(g, self.r):
                        if n.value in self.constants or n.value in M.BUILTIN_VALUES:
                            self.err(n.span, f"object '{n.value}' is declared twice"
                                     if n.value in self.constants else f"'{n.value}' is a builtin value",
                                     "duplicate")
                        else:
                            self.constants[n.value] = g.type.value
        self.qconsts = qualified_consts(self.modules)
        self.consts = self.ws._consts(f, self.qconsts, self.constants)
        # scene attributes and primitives: modules (transitively) + the domain's own
        self.scene_attrs, self.primitives = merged_decls(self.closure)
        for d in items:
            if isinstance(d, ast.SceneAttrDecl):
                self.ws._add_unique(self.scene_attrs, d.name, M.SceneAttr(
                    d.name.value, self.ws._signature(d.params, self.types),
                    self.ws._space(d.space, None, result=True), self.name, d.span), "scene attribute")
            elif isinstance(d, ast.PrimitiveDecl):
                self.ws._add_unique(self.primitives, d.name, M.Primitive(
                    d.name.value, self.ws._signature(d.params, self.types),
                    self.ws._space(d.space, None, result=True), self.name, d.span), "primitive")
        # logic
        for d in items:
            if isinstance(d, (ast.StateDecl, ast.DerivedDecl, ast.ActionDecl)) and d.name.value in M.RESERVED_LOGIC_NAMES:
                self.err(d.name.span, f"'{d.name.value}' is reserved: the compiler adds a state variable "
                         f"and a step of that name for `: {d.name.value} =>` rules", "reserved")
                continue
            if isinstance(d, ast.StateDecl):
                self.state_decl(d)
            elif isinstance(d, ast.DerivedDecl):
                if d.name.value in self.state_vars or d.name.value in self.derived_ast:
                    self.err(d.name.span, f"'{d.name.value}' is already declared", "duplicate")
                    continue
                self.derived_ast[d.name.value] = d
                self.derived[d.name.value] = M.Derived(
                    d.name.value, self.typed_params(d.params, "a derived predicate", allow_union=True),
                    M.And(()), d.span)
        logic = LogicResolver(self)
        for name, d in self.derived_ast.items():
            dv = self.derived[name]
            body = logic.formula(d.body, {p.name: p.types for p in dv.params})
            self.derived[name] = M.Derived(name, dv.params, body if body is not None else M.And(()), d.span)
        for d in items:
            if isinstance(d, ast.ActionDecl) and d.name.value not in M.RESERVED_LOGIC_NAMES:
                a = logic.action(d)
                if a is not None:
                    self.ws._add_unique(self.actions, d.name, a, "action")
        # continuous side
        for d in items:
            if isinstance(d, ast.ContinuousDecl):
                self.continuous_decl(d)
        self.world_space = B.SE3
        frames = self.frames([d for d in items if isinstance(d, ast.FrameDecl)])
        for d in items:
            if isinstance(d, ast.ActionDecl) and d.cost is not None and d.name.value in self.actions:
                a = self.actions[d.name.value]
                self.actions[d.name.value] = resolve_action_cost(self, a, d)
        templates = self.templates()
        rules = tuple(r for d in items if isinstance(d, ast.RuleDecl)
                      if (r := RuleResolver(self, logic).rule(d)) is not None)
        relax = ()
        settings = M.SolverSettings()
        reach = []
        avoid = None
        for d in items:
            if isinstance(d, ast.AvoidDecl):
                if avoid is not None:
                    self.err(d.span, "a second avoid declaration", "duplicate")
                avoid = self.avoid_decl(d)
            elif isinstance(d, ast.RelaxationsDecl):
                if relax:
                    self.err(d.span, "a second relaxations block", "duplicate")
                relax = settings_relaxations(self, d)
            elif isinstance(d, ast.SolverDecl):
                settings = settings_solver(self, d, settings)
            elif isinstance(d, ast.ReachabilityDecl):
                rb = settings_reachability(self, d)
                if rb is not None:
                    if any(x.name == rb.name for x in reach):
                        self.err(d.name.span, f"reachability '{rb.name}' is declared twice", "duplicate")
                    reach.append(rb)
        modules = {}
        for m in self.closure:
            mt = {k: v for k, v in templates.items() if v.module == m.name}
            modules[m.name] = M.Module(m.name, m.path, tuple(u.name for u in m.uses), dict(m.consts), mt,
                                       dict(m.scene_attrs), dict(m.primitives), m.file.header.span)
        return M.Domain(
            name=self.name, path=f.path, types=dict(self.types), constants=dict(self.constants),
            consts=dict(self.consts), state_vars=dict(self.state_vars), derived=dict(self.derived),
            actions=dict(self.actions), continuous=dict(self.continuous), frames=frames,
            templates=templates, rules=rules, relaxations=tuple(relax), settings=settings,
            reachability=tuple(reach), scene_attrs=dict(self.scene_attrs),
            primitives=dict(self.primitives), modules=modules, world_space=self.world_space,
            span=f.header.span, avoid=avoid)

    def avoid_decl(self, d: ast.AvoidDecl) -> M.Avoid | None:
        cats = []
        for n in d.categories:
            if n.value not in M.AVOID_CATEGORIES:
                self.err(n.span, f"unknown avoid category '{n.value}'", "unknown-name",
                         did_you_mean(n.value, M.AVOID_CATEGORIES) or "one of " + ", ".join(M.AVOID_CATEGORIES))
                return None
            if n.value in cats:
                self.err(n.span, f"'{n.value}' is named twice", "duplicate")
                return None
            cats.append(n.value)
        margin = 0.0
        if d.margin is not None:
            v = d.margin.value if isinstance(d.margin, ast.ENum) else None
            if v is None or v < 0:
                self.err(d.margin.span, "the avoid margin must be a number >= 0", "setting")
                return None
            margin = v
        return M.Avoid(tuple(cats), float(margin), d.span)

    # ---- types
    def resolve_types(self) -> None:
        decls: list[tuple[ast.Name, ast.Name | None, Span]] = []
        for d in self.f.items:
            if isinstance(d, ast.TypeDecl):
                for n in d.names:
                    decls.append((n, d.parent, d.span))
        for n, parent, span in decls:
            if n.value in self.types:
                self.err(n.span, f"type '{n.value}' is declared twice" if n.value != M.ROOT_TYPE
                         else "'object' is the implicit root type", "duplicate")
                continue
            if n.value in RESERVED_TYPE_NAMES:
                self.err(n.span, f"'{n.value}' is reserved and cannot name a type", "reserved")
                continue
            self.types[n.value] = M.Type(n.value, parent.value if parent else M.ROOT_TYPE, span)
        for n, parent, _ in decls:
            if parent is not None and parent.value not in self.types:
                self.err(parent.span, f"unknown type '{parent.value}'", "unknown-type",
                         did_you_mean(parent.value, self.types))
                t = self.types.get(n.value)
                if t is not None:
                    self.types[n.value] = M.Type(t.name, M.ROOT_TYPE, t.span)
        for name in list(self.types):         # cycles
            seen = []
            t: str | None = name
            while t is not None and t not in seen:
                seen.append(t)
                t = self.types[t].parent
            if t is not None:
                ty = self.types[name]
                self.err(ty.span, f"type '{name}' is its own ancestor ({' < '.join(seen + [t])})", "cycle")
                self.types[name] = M.Type(name, M.ROOT_TYPE, ty.span)

    # ---- state variables
    def state_decl(self, d: ast.StateDecl) -> None:
        name = d.name.value
        if name in self.state_vars:
            self.err(d.name.span, f"state variable '{name}' is declared twice", "duplicate")
            return
        params = self.typed_params(d.params, "a state variable")
        dom = []
        for n in d.domain:
            if n.value == "bool":
                if len(d.domain) > 1:
                    self.err(n.span, "'bool' cannot be combined with other values", "state-domain",
                             "a boolean state variable is declared `: bool`")
                    continue
            elif n.value != M.NONE and not self.check_type(n):
                continue
            if n.value in dom:
                self.err(n.span, f"'{n.value}' is listed twice", "duplicate")
                continue
            dom.append(n.value)
        if not dom:
            dom = [M.ROOT_TYPE]
        self.state_vars[name] = M.StateVar(name, params, tuple(dom), d.span)

    def continuous_decl(self, d: ast.ContinuousDecl) -> None:
        name = d.name.value
        what = "trajectory" if d.traj else "continuous variable"
        for table, other in ((self.state_vars, "a state variable"), (self.derived, "a derived predicate"),
                             (self.scene_attrs, "a scene attribute"), (self.primitives, "a primitive")):
            if name in table:
                self.err(d.name.span, f"'{name}' is already {other}", "duplicate")
                return
        if name in B.BUILTINS or name in ("world", "waypoints", "inv", "pos", "rot", "angle", "axis",
                                          "apply", "conj", "pi"):
            self.err(d.name.span, f"'{name}' is a builtin function and cannot name a {what}", "reserved")
            return
        params = self.typed_params(d.params, f"a {what}")
        space = self.ws._space(d.space, tuple(p.name for p in params))
        wp = None
        if d.waypoints is not None:
            if not float(d.waypoints.value).is_integer() or d.waypoints.value < 2:
                self.err(d.waypoints.span, "a trajectory needs an integer number of waypoints >= 2",
                         "waypoints")
            else:
                wp = int(d.waypoints.value)
        tags = frozenset(t.value for t in d.tags)
        self.tags_seen |= tags
        c = M.Continuous(name, params, space or B.SCALAR, tags, d.traj, wp, d.span)
        self.ws._add_unique(self.continuous, d.name, c, "continuous variable")

    # ---- expressions
    def scope(self, module: ModuleEnv | None = None, **kw) -> Scope:
        if module is None:
            consts, qconsts = dict(self.consts), dict(self.qconsts)
        else:
            consts, qconsts = dict(module.consts), qualified_consts(module.uses)
            qconsts.update(self.qconsts)
        return Scope(consts=consts, qconsts=qconsts, objects=dict(self.constants),
                     continuous=self.continuous, state_vars=self.state_vars,
                     scene_attrs=self.scene_attrs, primitives=self.primitives,
                     world_space=self.world_space, is_subtype=self.is_subtype, **kw)

    def frames(self, decls: list[ast.FrameDecl]) -> tuple[M.Frame, ...]:
        # pass 1 (world pose unknown, diagnostics discarded): find the pose space of frames
        spaces = []
        for d in decls:
            if d.type.value not in self.types:
                continue
            sc = self.scope(params={d.var.value: (Param(d.var.value), OBJ((d.type.value,)))},
                            allow_prime=False)
            sc.world_space = None
            _, t = Checker(sc, Reporter()).expr(d.expr)
            if t.kind == "value" and t.space.kind in ("SE2", "SE3"):
                spaces.append((t.space, d))
        if spaces:
            self.world_space = spaces[0][0]
            for sp, d in spaces[1:]:
                if sp != self.world_space:
                    self.err(d.expr.span, f"this frame is {sp}, but the first frame is {self.world_space}",
                             "frame", "all frames of a domain live in the same space (SE2 or SE3)")
        out = []
        seen: dict[str, ast.FrameDecl] = {}
        for d in decls:
            if not self.check_type(d.type):
                continue
            if d.type.value in seen:
                self.err(d.type.span, f"type '{d.type.value}' already has a frame", "duplicate")
                continue
            seen[d.type.value] = d
            sc = self.scope(params={d.var.value: (Param(d.var.value), OBJ((d.type.value,)))},
                            allow_prime=False, prime_context="in a frame (frames are per step)")
            x, t = Checker(sc, self.r).expr(d.expr)
            if t.kind == "error":
                continue
            if not (t.kind == "any" or (t.kind == "value" and t.space == self.world_space)):
                self.err(d.expr.span, f"a frame must be a pose ({self.world_space}), got {t}", "frame")
                continue
            out.append(M.Frame(M.TypedParam(d.var.value, (d.type.value,), d.var.span), x, d.span))
        return tuple(out)

    def templates(self) -> dict[str, M.Template]:
        """All templates visible to the domain, checked in its context; module templates that
        no rule calls are checked leniently (open world: they may refer to variables of
        other domains)."""
        self.template_index: dict[str, list[str]] = {}      # short name -> qualified names
        self.template_asts: dict[str, tuple[ast.TemplateDecl, ModuleEnv | None]] = {}
        for d in self.f.items:
            if isinstance(d, ast.TemplateDecl):
                q = f"{self.name}.{d.name.value}"
                if q in self.template_asts:
                    self.err(d.name.span, f"template '{d.name.value}' is declared twice", "duplicate")
                    continue
                self.template_asts[q] = (d, None)
        for m in self.modules:
            for short, d in m.templates.items():
                self.template_asts[f"{m.name}.{short}"] = (d, m)
        for q in self.template_asts:
            self.template_index.setdefault(q.rsplit(".", 1)[1], []).append(q)
        called = set()
        for d in self.f.items:
            if isinstance(d, ast.RuleDecl):
                for c in d.calls:
                    q = self.lookup_template(c, report=False)
                    if q:
                        called.add(q)
        out = {}
        for q, (d, m) in self.template_asts.items():
            open_world = m is not None and q not in called
            sc = self.scope(m, open_world=open_world)
            out[q] = self.ws._template(d, m.name if m else self.name, sc, self.types,
                                       reporter=self.r if not open_world else None)
            self.tags_seen |= out[q].tags
        return out

    def lookup_template(self, c: ast.TCall, report: bool = True) -> str | None:
        if len(c.qname) > 2:
            if report:
                self.err(c.span, f"unknown template '{c.text}'", "unknown-template")
            return None
        if len(c.qname) == 2:
            mod, short = c.qname[0].value, c.qname[1].value
            mods = [m.name for m in self.modules if m.name != PRELUDE] + [self.name]
            if mod not in mods:
                if report:
                    exists = self.ws.find_module(mod, Path(self.f.path).parent) is not None
                    self.err(c.qname[0].span, f"unknown module '{mod}' (not used by this domain)",
                             "unknown-module", f"add `use {mod}`" if exists
                             else did_you_mean(mod, mods) or f"no module '{mod}' exists")
                return None
            q = f"{mod}.{short}"
            if q not in self.template_asts:
                if report:
                    cands = [k.rsplit(".", 1)[1] for k in self.template_asts if k.startswith(mod + ".")]
                    self.err(c.qname[1].span, f"unknown template '{q}'", "unknown-template",
                             did_you_mean(short, cands, prefix=f"{mod}."))
                return None
            return q
        short = c.qname[0].value
        qs = self.template_index.get(short, [])
        local = f"{self.name}.{short}"
        if local in qs:
            return local
        if len(qs) == 1:
            return qs[0]
        if report:
            if not qs:
                self.err(c.qname[0].span, f"unknown template '{short}'", "unknown-template",
                         did_you_mean(short, list(self.template_index)))
            else:
                self.err(c.qname[0].span, f"template '{short}' is ambiguous", "ambiguous",
                         "write one of " + ", ".join(sorted(qs)))
        return None
