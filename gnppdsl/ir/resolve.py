"""Name resolution and checking: lang.ast files -> `gnppdsl.ir.model` (Domain, Problem, Module).

Why one `Workspace` object: modules are shared by domains (the prelude by all of them), so
they are parsed and resolved once per run and cached by path; every phase reports to one
`Reporter`, so `gnpp check a.pntc b.pntc` lists every error of every file together.

The expression half (template bodies, frames, template-call arguments) is delegated to
`gnppdsl.ir.typecheck`; this module handles files, modules, types, the logic (state variables,
derived predicates, actions, initial state, goal), rules, settings and the scene reference.
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from pathlib import Path

from gnppdsl.ir import builtins as B
from gnppdsl.ir import model as M
from gnppdsl.ir.builtins import Space
from gnppdsl.ir.expr import Obj, Param, Span
from gnppdsl.ir.typecheck import (ANY, INT, OBJ, STRING, VAL, Checker, Scope, Ty, compatible,
                                  fold)
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter, did_you_mean
from gnppdsl.lang.parser import parse_file

PRELUDE = "prelude"
VALUE_SPACES = {"R", "SE2", "SE3", "quat", "joints"}
RESERVED_TYPE_NAMES = VALUE_SPACES | {"value", "string", "int", "bool", "none", "true", "false"}
MEASURES = ("travel",)


def _sig_ty(p: M.Signature) -> Ty:
    if p.kind == "object":
        return OBJ((p.type or M.ROOT_TYPE,))
    if p.kind == "string":
        return STRING
    if p.kind == "any":
        return ANY
    if p.space.kind == "int":
        return INT
    return VAL(p.space)


@dataclass
class ModuleEnv:
    """A module resolved independently of any domain (templates are checked per domain)."""

    name: str
    path: str
    file: ast.FileAst
    uses: list["ModuleEnv"] = field(default_factory=list)
    consts: dict[str, object] = field(default_factory=dict)
    scene_attrs: dict[str, M.SceneAttr] = field(default_factory=dict)
    primitives: dict[str, M.Primitive] = field(default_factory=dict)
    templates: dict[str, ast.TemplateDecl] = field(default_factory=dict)   # short name -> ast

    def closure(self) -> list["ModuleEnv"]:
        """This module and everything it uses, transitively (each once)."""
        out: list[ModuleEnv] = []
        todo = [self]
        while todo:
            m = todo.pop()
            if any(m is x for x in out):
                continue
            out.append(m)
            todo.extend(m.uses)
        return out


class Workspace:
    """Loads and resolves .pntc files; all diagnostics go to `self.reporter`."""

    def __init__(self, reporter: Reporter | None = None, stdlib: Path | None = None) -> None:
        self.reporter = reporter or Reporter()
        self._stdlib = stdlib
        self._asts: dict[str, ast.FileAst | None] = {}
        self._modules: dict[str, ModuleEnv | None] = {}
        self._loading: set[str] = set()
        self._domains: dict[str, M.Domain | None] = {}

    # ------------------------------------------------------------------ files
    @property
    def stdlib(self) -> Path:
        if self._stdlib is None:
            from gnppdsl.resources import stdlib_dir

            self._stdlib = stdlib_dir()
        return self._stdlib

    def parse(self, path: str | Path) -> ast.FileAst | None:
        key = str(Path(path))
        if key not in self._asts:
            self._asts[key] = parse_file(key, self.reporter)
        return self._asts[key]

    def err(self, span, msg, kind="error", hint=None):
        self.reporter.error(span, msg, kind, hint)

    # ------------------------------------------------------------------ modules
    def find_module(self, name: str, from_dir: Path) -> Path | None:
        for d in (from_dir, self.stdlib):
            p = d / f"{name}.pntc"
            if p.is_file():
                return p
        return None

    def available_modules(self, from_dir: Path) -> list[str]:
        names = []
        for d in (from_dir, self.stdlib):
            try:
                names.extend(p.stem for p in d.glob("*.pntc"))
            except OSError:
                pass
        return names

    def use(self, name: ast.Name, from_dir: Path) -> ModuleEnv | None:
        path = self.find_module(name.value, from_dir)
        if path is None:
            self.err(name.span, f"unknown module '{name.value}'", "unknown-module",
                     did_you_mean(name.value, self.available_modules(from_dir))
                     or f"modules are looked up in {from_dir} and {self.stdlib}")
            return None
        return self.module_at(path, name)

    def module_at(self, path: Path, name: ast.Name | None = None) -> ModuleEnv | None:
        key = str(path)
        if key in self._modules:
            return self._modules[key]
        if key in self._loading:
            self.err(name.span if name else None, f"module '{path.stem}' uses itself (cycle)", "cycle")
            return None
        self._loading.add(key)
        try:
            f = self.parse(path)
            env = None
            if f is not None:
                if f.header.kind != "module":
                    self.err(name.span if name else f.header.span,
                             f"'{path.name}' is a {f.header.kind}, not a module", "not-a-module")
                else:
                    if name is not None and f.header.name.value != name.value:
                        self.err(f.header.name.span, f"module file '{path.name}' declares "
                                 f"module '{f.header.name.value}'", "module-name",
                                 f"write `module {name.value}`")
                    env = self._resolve_module(f)
            self._modules[key] = env
            return env
        finally:
            self._loading.discard(key)

    def prelude(self) -> ModuleEnv | None:
        p = self.stdlib / f"{PRELUDE}.pntc"
        if not p.is_file():
            self.err(None, f"the standard library has no {PRELUDE}.pntc ({self.stdlib})", "missing-file")
            return None
        return self.module_at(p)

    def _uses(self, f: ast.FileAst) -> list[ModuleEnv]:
        here = Path(f.path).parent
        mods: list[ModuleEnv] = []
        if f.header.name.value != PRELUDE:
            pre = self.prelude()
            if pre is not None:
                mods.append(pre)
        for d in f.items:
            if isinstance(d, ast.UseDecl):
                for n in d.names:
                    m = self.use(n, here)
                    if m is not None and not any(m is x for x in mods):
                        mods.append(m)
        return mods

    def _resolve_module(self, f: ast.FileAst) -> ModuleEnv:
        env = ModuleEnv(f.header.name.value, f.path, f)
        env.uses = self._uses(f)
        allowed = (ast.UseDecl, ast.ConstDecl, ast.TemplateDecl, ast.SceneAttrDecl, ast.PrimitiveDecl)
        self._reject(f, allowed, "a module")
        qconsts = _qconsts(env.uses)
        env.consts = self._consts(f, qconsts, {})
        for d in f.items:
            if isinstance(d, ast.SceneAttrDecl):
                self._add_unique(env.scene_attrs, d.name, M.SceneAttr(
                    d.name.value, self._signature(d.params, None), self._space(d.space, None, result=True),
                    env.name, d.span), "scene attribute")
            elif isinstance(d, ast.PrimitiveDecl):
                self._add_unique(env.primitives, d.name, M.Primitive(
                    d.name.value, self._signature(d.params, None), self._space(d.space, None, result=True),
                    env.name, d.span), "primitive")
            elif isinstance(d, ast.TemplateDecl):
                if d.name.value in env.templates:
                    self.err(d.name.span, f"template '{d.name.value}' is declared twice", "duplicate")
                env.templates[d.name.value] = d
        return env

    def check_module(self, path: str | Path) -> M.Module | None:
        """Resolve a module on its own (templates checked in an open world)."""
        env = self.module_at(Path(path))
        if env is None:
            return None
        attrs, prims = _merged_decls(env.closure())
        templates = {}
        for short, decl in env.templates.items():
            # the world space (SE2 or SE3) is the using domain's: accept either
            best = None
            for world in (B.SE2, B.SE3):
                rep = Reporter()
                scope = Scope(consts=dict(env.consts), qconsts=_qconsts(env.uses), scene_attrs=attrs,
                              primitives=prims, open_world=True, world_space=world)
                t = self._template(decl, env.name, scope, None, reporter=rep)
                if best is None or len(rep.errors) < len(best[1].errors):
                    best = (t, rep)
            templates[f"{env.name}.{short}"] = best[0]
            for dgn in best[1].diagnostics:
                self.reporter.diagnostics.append(dgn) if dgn not in self.reporter.diagnostics else None
        return M.Module(env.name, env.path, tuple(m.name for m in env.uses), dict(env.consts),
                        templates, dict(env.scene_attrs), dict(env.primitives), env.file.header.span)

    # ------------------------------------------------------------------ shared pieces
    def _reject(self, f: ast.FileAst, allowed: tuple, what: str) -> None:
        for d in f.items:
            if not isinstance(d, allowed):
                word = _decl_word(d)
                self.err(d.span, f"'{word}' is not allowed in {what}", "misplaced",
                         _where_allowed(word))

    def _add_unique(self, table: dict, name: ast.Name, value, what: str) -> None:
        if name.value in table:
            self.err(name.span, f"{what} '{name.value}' is declared twice", "duplicate")
        else:
            table[name.value] = value

    def _consts(self, f: ast.FileAst, qconsts: dict, objects: dict) -> dict:
        consts: dict[str, object] = {}
        for d in f.items:
            if not isinstance(d, ast.ConstDecl):
                continue
            scope = Scope(consts=dict(consts), qconsts=qconsts, objects=objects, allow_prime=False,
                          prime_context="in a constant")
            x, t = Checker(scope, self.reporter).expr(d.expr)
            if t.kind == "error":
                continue
            v = fold(x)
            if v is not None:
                val: object = v
            elif hasattr(x, "items") and all(fold(i) is not None for i in x.items):
                val = tuple(fold(i) for i in x.items)
            else:
                self.err(d.expr.span, "a constant must be a number or a vector of numbers",
                         "const")
                continue
            if d.name.value in consts or d.name.value == "pi":
                self.err(d.name.span, f"constant '{d.name.value}' is declared twice", "duplicate")
            consts[d.name.value] = val
        return consts

    def _space(self, s: ast.SpaceAst, params: tuple[str, ...] | None, result: bool = False,
               allow_object: bool = False) -> Space | None:
        """A value space; None for `value` (any). Errors are reported."""
        n = s.name.value
        if n == "R":
            if s.arg is not None:
                self.err(s.span, "write R[n] for a vector space", "space")
            if s.dim is not None and s.dim < 1:
                self.err(s.span, "a vector space needs at least one dimension", "space")
            return B.R(s.dim or 1)
        if s.dim is not None or (s.arg is not None and n != "joints"):
            self.err(s.span, f"'{n}' takes no {'[n]' if s.dim is not None else 'argument'}", "space")
        if n in ("SE2", "SE3"):
            return B.SE2 if n == "SE2" else B.SE3
        if n == "quat":
            return B.QUAT
        if n == "int":
            return Space("int", 1)
        if n == "joints":
            robot = s.arg.value if s.arg is not None else None
            if params is not None and robot is None:
                self.err(s.span, "write joints(r) with r a parameter of this declaration", "space")
            if params is not None and robot is not None and robot not in params:
                self.err(s.arg.span, f"'{robot}' is not a parameter here", "unknown-name",
                         did_you_mean(robot, params))
            return Space("joints", 0, robot)
        if n == "value" and (result or allow_object):
            return None
        if n == "object" and result:
            return Space("object", 1)
        self.err(s.name.span, f"unknown space '{n}'", "unknown-space",
                 did_you_mean(n, ["R", "SE2", "SE3", "quat", "joints"])
                 or "spaces are R, R[n], SE2, SE3, quat, joints(r)")
        return B.SCALAR

    def _signature(self, params: tuple[ast.SigParam, ...], types: dict | None) -> tuple[M.Signature, ...]:
        out = []
        seen = set()
        for p in params:
            if p.name.value in seen:
                self.err(p.name.span, f"parameter '{p.name.value}' is declared twice", "duplicate")
            seen.add(p.name.value)
            n = p.space.name.value
            if n == "value":
                out.append(M.Signature(p.name.value, "any", span=p.span))
            elif n == "string":
                out.append(M.Signature(p.name.value, "string", span=p.span))
            elif n in VALUE_SPACES or n == "int":
                out.append(M.Signature(p.name.value, "value", space=self._space(p.space, None),
                                       span=p.span))
            else:
                if p.space.dim is not None or p.space.arg is not None:
                    self.err(p.space.span, f"unknown space '{n}'", "unknown-space")
                elif types is not None and n not in types:
                    self.err(p.space.name.span, f"unknown type or space '{n}'", "unknown-type",
                             did_you_mean(n, list(types) + ["R", "SE2", "SE3", "quat", "joints", "value"]))
                out.append(M.Signature(p.name.value, "object", type=n, span=p.span))
        return tuple(out)

    # ------------------------------------------------------------------ domains
    def domain(self, path: str | Path) -> M.Domain | None:
        key = str(Path(path))
        if key not in self._domains:
            self._domains[key] = None
            f = self.parse(key)
            if f is None:
                return None
            if f.header.kind != "domain":
                self.err(f.header.span, f"expected a domain file, but this is a {f.header.kind}",
                         "not-a-domain")
                return None
            self._domains[key] = DomainResolver(self, f).run()
        return self._domains[key]

    def problem(self, path: str | Path, domain_path: str | Path | None = None) -> M.Problem | None:
        f = self.parse(path)
        if f is None:
            return None
        if f.header.kind != "problem":
            self.err(f.header.span, f"expected a problem file, but this is a {f.header.kind}",
                     "not-a-problem")
            return None
        if domain_path is None:
            domain_path = self.find_domain(f)
            if domain_path is None:
                return None
        dom = self.domain(domain_path)
        if dom is None:
            return None
        if dom.name != f.header.domain.value:
            self.err(f.header.domain.span, f"problem is for domain '{f.header.domain.value}', "
                     f"but {domain_path} declares domain '{dom.name}'", "wrong-domain")
            return None
        return ProblemResolver(self, f, dom).run()

    def find_domain(self, f: ast.FileAst, candidates: list[str] | None = None) -> str | None:
        """Domain discovery: given files, `domain.pntc` next to the problem, any sibling file
        declaring `domain NAME`."""
        want = f.header.domain.value
        here = Path(f.path).parent
        ordered = sorted(candidates or [], key=lambda c: Path(c).resolve().parent != here.resolve())
        for c in ordered:                       # given files, those next to the problem first
            g = self.parse(c)
            if g is not None and g.header.kind == "domain" and g.header.name.value == want:
                return c
        seen_domains = []
        first = here / "domain.pntc"
        siblings = [first] if first.is_file() else []
        try:
            siblings += sorted(p for p in here.glob("*.pntc") if p != first)
        except OSError:
            pass
        for p in siblings:
            if str(p) == f.path:
                continue
            head = _peek_header(p)
            if head is None:
                continue
            kind, name = head
            if kind == "domain":
                seen_domains.append(name)
                if name == want:
                    return str(p)
        self.err(f.header.domain.span, f"cannot find domain '{want}'", "missing-domain",
                 did_you_mean(want, seen_domains)
                 or f"put it in {here / 'domain.pntc'} or pass the domain file: gnpp check DOMAIN PROBLEM")
        return None


_HEADER = re.compile(r"^\s*(domain|problem|module)\s+([A-Za-z_]\w*)", re.M)


def _peek_header(path: Path) -> tuple[str, str] | None:
    """The header of a file without parsing it all (comments skipped)."""
    try:
        with open(path, encoding="utf-8", errors="replace") as fh:
            for line in fh:
                s = line.split("#", 1)[0].strip()
                if not s:
                    continue
                m = _HEADER.match(s)
                return (m.group(1), m.group(2)) if m else None
    except OSError:
        return None
    return None


def _qconsts(mods: list[ModuleEnv]) -> dict:
    out = {}
    for m in mods:
        for k, v in m.consts.items():
            out[f"{m.name}.{k}"] = v
    return out


def _merged_decls(mods: list[ModuleEnv]) -> tuple[dict, dict]:
    attrs: dict = {}
    prims: dict = {}
    for m in mods:
        attrs.update(m.scene_attrs)
        prims.update(m.primitives)
    return attrs, prims


_DECL_WORDS = {
    ast.UseDecl: "use", ast.TypeDecl: "type", ast.ConstDecl: "const", ast.ConstantsDecl: "constants",
    ast.StateDecl: "state", ast.DerivedDecl: "derived", ast.ActionDecl: "action",
    ast.FrameDecl: "frame", ast.TemplateDecl: "template", ast.SceneAttrDecl: "scene",
    ast.PrimitiveDecl: "primitive", ast.RuleDecl: "rule", ast.RelaxationsDecl: "relaxations",
    ast.SolverDecl: "solver", ast.ReachabilityDecl: "reachability", ast.SceneRef: "scene",
    ast.ObjectsDecl: "objects", ast.InitDecl: "init", ast.GoalDecl: "goal",
}


def _decl_word(d) -> str:
    if isinstance(d, ast.ContinuousDecl):
        return "traj" if d.traj else "continuous"
    return _DECL_WORDS.get(type(d), type(d).__name__)


def _where_allowed(word: str) -> str:
    if word in ("objects", "init", "goal"):
        return f"'{word}' belongs in a problem file"
    if word == "scene":
        return "a problem names its scene with `scene \"file.yaml\"`; domains and modules declare attributes with `scene name(o: object) : R`"
    if word in ("template", "const", "primitive", "use"):
        return f"'{word}' belongs in a domain or a module"
    if word in ("solver", "relaxations", "reachability"):
        return f"'{word}' belongs in a domain or a problem"
    return f"'{word}' belongs in a domain file"


# ============================================================================================
# Domains
# ============================================================================================
class DomainResolver:
    def __init__(self, ws: Workspace, f: ast.FileAst) -> None:
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
        seen = set()
        for p in params:
            if p.name.value in seen:
                self.err(p.name.span, f"parameter '{p.name.value}' is declared twice", "duplicate")
            seen.add(p.name.value)
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
        allowed = tuple(t for t in _DECL_WORDS if t not in (ast.SceneRef, ast.ObjectsDecl,
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
                    for n in g.names:
                        if n.value in self.constants or n.value in M.BUILTIN_VALUES:
                            self.err(n.span, f"object '{n.value}' is declared twice"
                                     if n.value in self.constants else f"'{n.value}' is a builtin value",
                                     "duplicate")
                        else:
                            self.constants[n.value] = g.type.value
        self.qconsts = _qconsts(self.modules)
        self.consts = self.ws._consts(f, self.qconsts, self.constants)
        # scene attributes and primitives: modules (transitively) + the domain's own
        self.scene_attrs, self.primitives = _merged_decls(self.closure)
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
            if isinstance(d, ast.ActionDecl):
                a = logic.action(d)
                if a is not None:
                    self.ws._add_unique(self.actions, d.name, a, "action")
        # continuous side
        for d in items:
            if isinstance(d, ast.ContinuousDecl):
                self.continuous_decl(d)
        self.world_space = B.SE3
        frames = self.frames([d for d in items if isinstance(d, ast.FrameDecl)])
        templates = self.templates()
        rules = tuple(r for d in items if isinstance(d, ast.RuleDecl)
                      if (r := RuleResolver(self, logic).rule(d)) is not None)
        relax = ()
        settings = M.SolverSettings()
        reach = []
        for d in items:
            if isinstance(d, ast.RelaxationsDecl):
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
            span=f.header.span)

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
            consts, qconsts = dict(module.consts), _qconsts(module.uses)
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
                             did_you_mean(short, cands))
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


def _template(self: Workspace, d: ast.TemplateDecl, module: str, scope: Scope, types: dict | None,
              reporter: Reporter | None = ...) -> M.Template:
    """Check a template body in `scope`; `reporter=None` discards the diagnostics."""
    rep = self.reporter if reporter is ... else (reporter or Reporter())
    sig = self._signature(d.params, types)
    scope.params = {p.name: (Param(p.name), _sig_ty(p)) for p in sig}
    scope.allow_prime = True
    body = Checker(scope, rep).statements(d.body)
    return M.Template(f"{module}.{d.name.value}", sig, body, frozenset(t.value for t in d.tags),
                      module, scope.used_prime, d.span)


Workspace._template = _template


# ============================================================================================
# Logic
# ============================================================================================
_FLIP = {"=": "!=", "!=": "=", "<": ">=", ">=": "<", ">": "<=", "<=": ">"}


class LogicResolver:
    """Literals, formulas, effects and actions over a domain's state variables."""

    def __init__(self, dom: DomainResolver, objects: dict[str, str] | None = None) -> None:
        self.d = dom
        self.objects = dict(dom.constants) if objects is None else objects

    def err(self, span, msg, kind="logic", hint=None):
        self.d.err(span, msg, kind, hint)

    def term(self, t: ast.LTerm, scope: dict[str, tuple[str, ...]]) -> tuple[object, tuple[str, ...]] | None:
        if t.args is not None:
            self.err(t.span, f"expected an object or a variable, got '{t.text()}'", "logic",
                     "state values cannot be nested; introduce a parameter")
            return None
        n = t.name.value
        if n in scope:
            return Param(n, t.span), scope[n]
        if n in self.objects:
            return Obj(n, t.span), (self.objects[n],)
        if n in M.BUILTIN_VALUES:
            return Obj(n, t.span), (n,)
        self.err(t.span, f"unknown object or variable '{n}'", "unknown-name",
                 did_you_mean(n, list(scope) + list(self.objects) + list(M.BUILTIN_VALUES)))
        return None

    def is_atom_name(self, t: ast.LTerm, scope) -> bool:
        n = t.name.value
        if t.args is not None:
            return True
        return n not in scope and n not in self.objects and n not in M.BUILTIN_VALUES and (
            n in self.d.state_vars or n in self.d.derived)

    def args(self, t: ast.LTerm, params: tuple[M.TypedParam, ...], scope, what: str):
        args = t.args or ()
        if len(args) != len(params):
            self.err(t.span, f"{what} '{t.name.value}' takes {len(params)} argument"
                     f"{'s' * (len(params) != 1)}, got {len(args)}", "arity")
            return None
        out = []
        for a, p in zip(args, params):
            r = self.term(a, scope)
            if r is None:
                return None
            term, types = r
            if p.types and not self.fits(types, p.types):
                self.err(a.span, f"'{a.text()}' ({' | '.join(types)}) is not {_article(' | '.join(p.types))}",
                         "type", f"{what} '{t.name.value}' expects {' | '.join(p.types)} for '{p.name}'")
                return None
            out.append(term)
        return tuple(out)

    def fits(self, have: tuple[str, ...], want: tuple[str, ...]) -> bool:
        if not have:
            return True
        return all(any(self.d.is_subtype(h, w) or h == w for w in want) for h in have)

    def atom(self, t: ast.LTerm, scope):
        """(kind, name, args) for a state variable or derived predicate reference."""
        n = t.name.value
        if n in self.d.state_vars:
            v = self.d.state_vars[n]
            a = self.args(t, v.params, scope, "state variable")
            return None if a is None else ("state", v, a)
        if n in self.d.derived:
            v = self.d.derived[n]
            a = self.args(t, v.params, scope, "derived predicate")
            return None if a is None else ("derived", v, a)
        self.err(t.name.span, f"unknown state variable or predicate '{n}'", "unknown-name",
                 did_you_mean(n, list(self.d.state_vars) + list(self.d.derived) + list(scope)))
        return None

    def value(self, v: M.StateVar, rhs: ast.LTerm, scope):
        r = self.term(rhs, scope)
        if r is None:
            return None
        term, types = r
        if v.is_bool:
            if not (isinstance(term, Obj) and term.name in (M.TRUE, M.FALSE)):
                self.err(rhs.span, f"'{v.name}' is boolean: its value is true or false", "type")
                return None
            return term
        if isinstance(term, Obj) and term.name in (M.TRUE, M.FALSE):
            self.err(rhs.span, f"'{v.name}' is not boolean", "type",
                     f"its values are {' | '.join(v.domain)}")
            return None
        if isinstance(term, Obj) and term.name == M.NONE:
            if not v.allows_none:
                self.err(rhs.span, f"'{v.name}' cannot be none", "type",
                         f"declare `state {v.name}(...) : {' | '.join(v.domain)} | none`")
                return None
            return term
        if not self.fits(types, v.value_types):
            self.err(rhs.span, f"'{rhs.text()}' ({' | '.join(types)}) is not a possible value of "
                     f"'{v.name}'", "type", f"its values are {' | '.join(v.domain)}")
            return None
        return term

    def literal(self, lit: ast.Lit, scope, negate: bool = False):
        """A literal -> StateLit / DerivedLit / Compare (or None after an error)."""
        if lit.kind in ("atom", "not"):
            neg = (lit.kind == "not") != negate
            if not self.is_atom_name(lit.lhs, scope):
                r = self.term(lit.lhs, scope) if lit.lhs.name.value not in self.d.state_vars else None
                if r is not None:
                    self.err(lit.span, f"'{lit.lhs.text()}' is not a condition", "logic",
                             "compare it, e.g. `x = y`")
                return None
            a = self.atom(lit.lhs, scope)
            if a is None:
                return None
            kind, v, args = a
            if kind == "derived":
                return M.DerivedLit(v.name, args, neg, lit.span)
            if not v.is_bool:
                self.err(lit.span, f"'{v.name}' is not boolean; compare its value",
                         "logic", f"e.g. `{lit.lhs.text()} = ...` (values: {' | '.join(v.domain)})")
                return None
            return M.StateLit(v.name, args, Obj(M.FALSE if neg else M.TRUE), False, lit.span)
        op = lit.op
        lhs, rhs = lit.lhs, lit.rhs
        if not self.is_atom_name(lhs, scope) and self.is_atom_name(rhs, scope):
            lhs, rhs = rhs, lhs
            op = {"<": ">", ">": "<", "<=": ">=", ">=": "<="}.get(op, op)
        if self.is_atom_name(lhs, scope):
            if op not in ("=", "!="):
                self.err(lit.span, f"'{op}' compares objects; a state variable is tested with = or !=",
                         "logic")
                return None
            a = self.atom(lhs, scope)
            if a is None:
                return None
            kind, v, args = a
            if kind == "derived":
                self.err(lhs.span, f"'{v.name}' is a derived predicate: write `{lhs.text()}` or "
                         f"`not {lhs.text()}`", "logic")
                return None
            val = self.value(v, rhs, scope)
            if val is None:
                return None
            neg = (op == "!=") != negate
            if v.is_bool and neg:
                val = Obj(M.FALSE if val.name == M.TRUE else M.TRUE, val.span)
                neg = False
            return M.StateLit(v.name, args, val, neg, lit.span)
        l, r = self.term(lhs, scope), self.term(rhs, scope)
        if l is None or r is None:
            return None
        return M.Compare(l[0], _FLIP[op] if negate else op, r[0], lit.span)

    def formula(self, f, scope, negate: bool = False):
        if isinstance(f, ast.Lit):
            return self.literal(f, scope, negate)
        if isinstance(f, ast.FNot):
            return self.formula(f.item, scope, not negate)
        if isinstance(f, (ast.FAnd, ast.FOr)):
            items = [self.formula(x, scope) for x in f.items]
            if any(i is None for i in items):
                return None
            node = (M.And if isinstance(f, ast.FAnd) else M.Or)(tuple(items), f.span)
            return M.Not(node, f.span) if negate else node
        if isinstance(f, ast.FExists):
            params = self.d.typed_params(f.params, "exists", allow_union=True)
            inner = dict(scope)
            for p in params:
                if p.name in scope:
                    self.err(p.span, f"'{p.name}' is already a variable here", "duplicate")
                inner[p.name] = p.types
            body = self.formula(f.body, inner)
            if body is None:
                return None
            node = M.Exists(params, body, f.span)
            return M.Not(node, f.span) if negate else node
        return None

    def conjunction(self, f, scope) -> list | None:
        """A condition that must be a conjunction of literals (effect conditions)."""
        if isinstance(f, ast.FAnd):
            out = []
            for x in f.items:
                r = self.conjunction(x, scope)
                if r is None:
                    return None
                out.extend(r)
            return out
        if isinstance(f, ast.Lit):
            lit = self.literal(f, scope)
            return None if lit is None else [lit]
        if isinstance(f, ast.FNot) and isinstance(f.item, ast.Lit):
            lit = self.literal(f.item, scope, negate=True)
            return None if lit is None else [lit]
        self.err(f.span, "a condition here must be a conjunction of literals", "logic",
                 "use a derived predicate for disjunctions and quantifiers")
        return None

    def effects(self, effs, scope, conds: tuple = ()) -> list[M.Effect]:
        out = []
        for e in effs:
            if isinstance(e, ast.EffWhen):
                c = self.conjunction(e.cond, scope)
                if c is None:
                    continue
                out.extend(self.effects(e.effects, scope, conds + tuple(c)))
                continue
            lhs = e.lhs
            if not self.is_atom_name(lhs, scope):
                self.err(lhs.span, f"'{lhs.text()}' is not a state variable", "logic")
                continue
            a = self.atom(lhs, scope)
            if a is None:
                continue
            kind, v, args = a
            if kind == "derived":
                self.err(lhs.span, f"'{v.name}' is derived: it cannot be assigned", "logic",
                         "assign the state variables it is derived from")
                continue
            if isinstance(e, ast.EffBool):
                if not v.is_bool:
                    self.err(e.span, f"'{v.name}' is not boolean; assign it with `:=`", "logic",
                             f"e.g. `{lhs.text()} := ...`")
                    continue
                val = Obj(M.TRUE if e.value else M.FALSE, e.span)
            else:
                val = self.value(v, e.rhs, scope)
                if val is None:
                    continue
            out.append(M.Effect(M.Assign(v.name, args, val, e.span), conds, e.span))
        return out

    def action(self, d: ast.ActionDecl) -> M.Action | None:
        params = self.d.typed_params(d.params, "an action")
        scope = {p.name: p.types for p in params}
        for dup in d.duplicates:
            self.err(dup.span, f"'{dup.value}' appears twice in action '{d.name.value}'", "duplicate",
                     "list all items after one keyword, separated by commas")
        pre = []
        for lit in d.pre:
            x = self.literal(lit, scope)
            if x is not None:
                pre.append(x)
        effs = self.effects(d.effects, scope)
        seen: dict = {}
        for e in effs:
            key = (e.assign.var, e.assign.args, e.conditions)
            if key in seen and seen[key] != e.assign.value:
                self.err(e.span, f"'{e.assign.var}' is assigned twice", "duplicate")
            seen[key] = e.assign.value
        cost = 1
        if d.cost is not None:
            if not float(d.cost.value).is_integer() or d.cost.value < 0:
                self.err(d.cost.span, "an action cost is a non-negative integer", "cost")
            else:
                cost = int(d.cost.value)
        return M.Action(d.name.value, params, tuple(pre), tuple(effs), cost, d.span)


def _article(s: str) -> str:
    return ("an " if s[:1] in "aeiou" else "a ") + s


# ============================================================================================
# Rules
# ============================================================================================
class RuleResolver:
    def __init__(self, dom: DomainResolver, logic: LogicResolver) -> None:
        self.d = dom
        self.logic = logic

    def err(self, span, msg, kind="rule", hint=None):
        self.d.err(span, msg, kind, hint)

    def infer(self, params: list[M.TypedParam], lits) -> list[M.TypedParam]:
        """Untyped rule parameters take the types of their first use in the pattern."""
        untyped = {p.name for p in params if not p.types}
        found: dict[str, tuple[str, ...]] = {}
        for lit in lits:
            terms = []
            if lit.kind != "cmp" and lit.lhs.args is not None:
                terms.append((lit.lhs, None))
            if lit.kind == "cmp":
                terms.append((lit.lhs, lit.rhs))
            for lhs, rhs in terms:
                name = lhs.name.value
                decl = self.d.state_vars.get(name) or self.d.derived.get(name)
                if decl is None or lhs.args is None:
                    continue
                for a, p in zip(lhs.args, decl.params):
                    if a.args is None and a.name.value in untyped and a.name.value not in found:
                        found[a.name.value] = p.types
                if rhs is not None and rhs.args is None and rhs.name.value in untyped \
                        and isinstance(decl, M.StateVar) and rhs.name.value not in found:
                    found[rhs.name.value] = decl.value_types or (M.ROOT_TYPE,)
        out = []
        for p in params:
            if p.types:
                out.append(p)
            elif p.name in found:
                out.append(M.TypedParam(p.name, found[p.name], p.span))
            else:
                self.err(p.span, f"cannot infer the type of '{p.name}'", "missing-type",
                         f"write `{p.name}: TYPE` (it does not appear in the rule's pattern)")
                out.append(M.TypedParam(p.name, (M.ROOT_TYPE,), p.span))
        return out

    def pattern(self, lits, scope) -> tuple | None:
        out = []
        ok = True
        for lit in lits:
            x = self.logic.literal(lit, scope)
            if x is None:
                ok = False
                continue
            if isinstance(x, M.Compare):
                self.err(lit.span, "a pattern holds state facts; put comparisons in `where`", "pattern",
                         f"e.g. `rule r(...) where {lit.lhs.text()} {lit.op} {lit.rhs.text()} : ...`")
                ok = False
                continue
            if isinstance(x, M.StateLit) and x.negated:
                self.err(lit.span, "a pattern is a partial state: '!=' cannot be matched", "pattern",
                         "bind the value to a parameter and add `where P != value`")
                ok = False
                continue
            out.append(x)
        vars_ = [(l.var, l.args) for l in out if isinstance(l, M.StateLit)]
        for i, k in enumerate(vars_):
            if k in vars_[:i]:
                self.err(lits[i].span if i < len(lits) else None,
                         f"'{k[0]}' appears twice in one partial state", "pattern")
                ok = False
        return tuple(out) if ok else None

    def rule(self, d: ast.RuleDecl) -> M.Rule | None:
        params = list(self.d.typed_params(d.params, "a rule", allow_untyped=True, allow_union=True))
        params = self.infer(params, d.pre + d.post)
        scope = {p.name: p.types for p in params}
        used = _names_in((d.where, d.pre, d.post, d.calls))
        for p in params:
            if p.name not in used:
                self.d.r.warning(p.span, f"parameter '{p.name}' of rule '{d.name.value}' is not used: "
                                 "the rule is instantiated once per object of its type", "unused")
        where = []
        for lit in d.where:
            x = self.logic.literal(lit, scope)
            if x is None:
                continue
            if not isinstance(x, M.Compare):
                self.err(lit.span, "`where` compares parameters (`a != b`, `a < b`); "
                         "state facts belong in the pattern", "where")
                continue
            where.append(x)
        pre = self.pattern(d.pre, scope)
        post = self.pattern(d.post, scope)
        tags = frozenset(t.value for t in d.tags)
        self.d.tags_seen |= tags
        two_step = d.kind == "transition"
        calls = []
        for c in d.calls:
            q = self.d.lookup_template(c)
            if q is None:
                continue
            tpl_ast, module = self.d.template_asts[q]
            sig = self.d.ws._signature(tpl_ast.params, None) if module is not None else \
                self.d.ws._signature(tpl_ast.params, None)
            tpl_tags = frozenset(t.value for t in tpl_ast.tags)
            call = self.call(c, q, sig, scope, two_step, d)
            if call is None:
                continue
            uses_prime = _template_uses_prime(tpl_ast)
            if uses_prime and not two_step:
                self.err(c.span, f"template '{q}' relates steps i and i+1 (it uses '), but rule "
                         f"'{d.name.value}' matches a single state", "prime",
                         "write the pattern as `p -> p'`, or `always -> always` for every transition")
                continue
            calls.append(M.TemplateCall(q, call, tpl_tags | tags, c.span))
        if pre is None or post is None:
            return None
        return M.Rule(d.name.value, tuple(params), d.kind, pre, post, tuple(calls), tuple(where),
                      tags, d.span)

    def call(self, c: ast.TCall, q: str, sig: tuple[M.Signature, ...], scope, two_step: bool,
             d: ast.RuleDecl):
        if len(c.args) != len(sig):
            self.err(c.span, f"template '{q}' takes {len(sig)} argument{'s' * (len(sig) != 1)}, "
                     f"got {len(c.args)}", "arity",
                     "parameters: " + ", ".join(f"{p.name}: {p.type or p.space or 'value'}"
                                                if p.kind != "any" else f"{p.name}: value" for p in sig))
            return None
        sc = self.d.scope(params={n: (Param(n), OBJ(t)) for n, t in scope.items()},
                          allow_prime=two_step,
                          prime_context=f"in rule '{d.name.value}': it matches a single state "
                                        "(write `p -> p'` to relate two steps)")
        ch = Checker(sc, self.d.r)
        out = []
        any_ty: Ty | None = None
        ok = True
        for a, p in zip(c.args, sig):
            x, t = ch.expr(a)
            if t.kind == "error":
                ok = False
                continue
            if p.kind == "object":
                if t.kind != "object":
                    self.err(a.span, f"argument '{p.name}' of '{q}' is an object ({p.type}), got "
                             f"{_article(str(t))}", "type")
                    ok = False
                elif p.type and p.type in self.d.types and not self.logic.fits(t.types, (p.type,)):
                    self.err(a.span, f"argument '{p.name}' of '{q}' must be {_article(p.type)}, "
                             f"got {t}", "type")
                    ok = False
            elif p.kind == "string":
                if t.kind != "string":
                    self.err(a.span, f"argument '{p.name}' of '{q}' must be a string", "type")
                    ok = False
            else:
                if t.kind in ("object", "traj", "string"):
                    hint = "pass world(...) for a pose" if t.kind == "object" else None
                    self.err(a.span, f"argument '{p.name}' of '{q}' is a value, got "
                             f"{'an object' if t.kind == 'object' else str(t)}", "type", hint)
                    ok = False
                elif p.kind == "any":
                    if any_ty is not None and not compatible(any_ty, t):
                        self.err(a.span, f"argument '{p.name}' of '{q}' must have the same space as "
                                 f"the other 'value' arguments ({any_ty}), got {t}", "dimension")
                        ok = False
                    elif any_ty is None or any_ty.kind == "any":
                        any_ty = t
                else:
                    want = INT if p.space.kind == "int" else VAL(p.space)
                    if not compatible(want, t):
                        self.err(a.span, f"argument '{p.name}' of '{q}' must be {p.space}, got {t}",
                                 "dimension")
                        ok = False
            out.append(x)
        return tuple(out) if ok else None


def _names_in(x, out: set | None = None) -> set:
    """Every identifier written in an AST fragment."""
    out = set() if out is None else out
    if isinstance(x, ast.Name):
        out.add(x.value)
    elif isinstance(x, tuple):
        for i in x:
            _names_in(i, out)
    elif hasattr(x, "__dataclass_fields__"):
        for f in x.__dataclass_fields__:
            if f != "span":
                _names_in(getattr(x, f), out)
    return out


def _template_uses_prime(d: ast.TemplateDecl) -> bool:
    def walk(x) -> bool:
        if isinstance(x, ast.EPrime):
            return True
        if isinstance(x, tuple):
            return any(walk(i) for i in x)
        if hasattr(x, "__dataclass_fields__"):
            return any(walk(getattr(x, f)) for f in x.__dataclass_fields__ if f != "span")
        return False
    return walk(d.body)


# ============================================================================================
# Settings blocks
# ============================================================================================
def _setting_value(res, s: ast.Setting, want: type):
    v = s.value
    if want in (int, float):
        if v.kind != "number":
            res.err(v.span, f"'{s.key.value}' must be a number", "setting")
            return None
        if want is int and not float(v.value).is_integer():
            res.err(v.span, f"'{s.key.value}' must be an integer", "setting")
            return None
        return want(v.value)
    if want is str:
        if v.kind not in ("string", "name"):
            res.err(v.span, f"'{s.key.value}' must be a name or a string", "setting")
            return None
        return v.value
    return v


def _new_known_key(res, s, fields, seen, block: str) -> bool:
    """A `key = value` of a settings block is usable: a known key, not set before in the block.
    Reports the problem (with a did-you-mean hint) otherwise."""
    k = s.key.value
    if k not in fields:
        res.err(s.key.span, f"unknown {block} setting '{k}'", "unknown-setting",
                did_you_mean(k, fields) or "settings: " + ", ".join(fields))
        return False
    if k in seen:
        res.err(s.key.span, f"'{k}' is set twice", "duplicate")
        return False
    return True


def settings_solver(res, d: ast.SolverDecl, base: M.SolverSettings) -> M.SolverSettings:
    vals = {}
    for s in d.settings:
        k = s.key.value
        if not _new_known_key(res, s, M.SOLVER_FIELDS, vals, "solver"):
            continue
        v = _setting_value(res, s, M.SOLVER_FIELDS[k])
        if v is None:
            continue
        if k == "algorithm" and v not in M.SOLVER_ALGORITHMS:
            res.err(s.value.span, f"unknown algorithm '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_ALGORITHMS) or "one of " + ", ".join(M.SOLVER_ALGORITHMS))
            continue
        if k == "nlp" and v not in M.SOLVER_NLPS:
            res.err(s.value.span, f"unknown NLP solver '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_NLPS) or "one of " + ", ".join(M.SOLVER_NLPS))
            continue
        if k == "order" and v not in M.SOLVER_ORDERS:
            res.err(s.value.span, f"unknown order '{v}'", "setting",
                    did_you_mean(v, M.SOLVER_ORDERS) or "one of " + ", ".join(M.SOLVER_ORDERS))
            continue
        if k == "switches" and (set(v) - set("trng") or len(set(v)) != len(v)):
            res.err(s.value.span, f"switches are letters among t, r, n, g (each once), got '{v}'", "setting")
            continue
        if k in ("tolerance", "time_limit") and v <= 0 or k in ("waypoints",) and v < 2 \
                or k in ("max_horizon", "max_iter") and v < 1 or k == "seed" and v < 0:
            res.err(s.value.span, f"'{k}' = {v} is out of range", "setting")
            continue
        vals[k] = v
    return base.merged(**vals)


def settings_relaxations(res, d: ast.RelaxationsDecl) -> tuple[M.Relaxation, ...]:
    out = []
    known = sorted(res.tags_seen)
    for item in d.items:
        if any(r.name == item.name.value for r in out):
            res.err(item.name.span, f"relaxation '{item.name.value}' is declared twice", "duplicate")
            continue
        ok = True
        for t in item.drop:
            if t.value not in res.tags_seen:
                res.err(t.span, f"unknown tag '{t.value}'", "unknown-tag",
                        did_you_mean(t.value, known) or ("tags in use: " + ", ".join(known) if known
                                                         else "no declaration has tags"))
                ok = False
        if ok:
            out.append(M.Relaxation(item.name.value, frozenset(t.value for t in item.drop), item.span))
    return tuple(out)


def _numbers(res, v: ast.Value, n: int | None, what: str):
    if v.kind != "list" or any(x.kind != "number" for x in v.value) or (n is not None and len(v.value) != n):
        res.err(v.span, f"'{what}' must be a list of {n if n else 'some'} numbers", "setting")
        return None
    return tuple(float(x.value) for x in v.value)


def settings_reachability(res, d: ast.ReachabilityDecl) -> M.Reachability | None:
    kw: dict = {}
    for s in d.settings:
        k = s.key.value
        if not _new_known_key(res, s, M.REACHABILITY_FIELDS, kw, "reachability"):
            continue
        if k == "workspace":
            v = s.value
            if v.kind != "list" or len(v.value) != 2:
                res.err(v.span, "'workspace' is [[lower...], [upper...]]", "setting")
                continue
            lo, hi = _numbers(res, v.value[0], None, k), _numbers(res, v.value[1], None, k)
            if lo is None or hi is None:
                continue
            if len(lo) != len(hi) or len(lo) not in (2, 3) or any(a > b for a, b in zip(lo, hi)):
                res.err(v.span, "'workspace' needs lower <= upper bounds of equal length (2 or 3)", "setting")
                continue
            kw[k] = (lo, hi)
        elif k == "weights":
            w = _numbers(res, s.value, 3, k)
            if w is not None:
                kw[k] = w
        else:
            v = _setting_value(res, s, M.REACHABILITY_FIELDS[k])
            if v is None:
                continue
            if isinstance(v, (int, float)) and v < 0 or k in ("samples", "neighbours") and v < 1:
                res.err(s.value.span, f"'{k}' = {v} is out of range", "setting")
                continue
            kw[k] = v
    if "robot" not in kw:
        res.err(d.name.span, f"reachability '{d.name.value}' needs `robot = NAME`", "setting")
        return None
    heur = []
    actions = getattr(res, "actions", None) or getattr(getattr(res, "dom", None), "actions", {})
    for h in d.heuristics:
        a = actions.get(h.action.value)
        if a is None:
            res.err(h.action.span, f"unknown action '{h.action.value}'", "unknown-name",
                    did_you_mean(h.action.value, actions))
            continue
        if len(h.params) != len(a.params):
            res.err(h.span, f"action '{a.name}' has {len(a.params)} parameters, got {len(h.params)}", "arity")
            continue
        if h.measure.value not in MEASURES:
            res.err(h.measure.span, f"unknown heuristic measure '{h.measure.value}'", "unknown-name",
                    did_you_mean(h.measure.value, MEASURES) or "measures: " + ", ".join(MEASURES))
            continue
        names = [p.value for p in h.params]
        bad = [x for x in h.args if x.value not in names]
        if bad:
            res.err(bad[0].span, f"'{bad[0].value}' is not a parameter of this heuristic", "unknown-name",
                    did_you_mean(bad[0].value, names))
            continue
        if len(h.args) != 2:
            res.err(h.span, "travel(r, x) takes a robot and a target", "arity")
            continue
        heur.append(M.Heuristic(a.name, tuple(names), h.measure.value, tuple(x.value for x in h.args), h.span))
    warm = []
    cont = getattr(res, "continuous", None) or getattr(getattr(res, "dom", None), "continuous", {})
    for w in d.warmstarts:
        c = cont.get(w.traj.value)
        if c is None or not c.traj:
            res.err(w.traj.span, f"'{w.traj.value}' is not a trajectory", "unknown-name",
                    did_you_mean(w.traj.value, [k for k, v in cont.items() if v.traj]))
            continue
        if len(w.args) != len(c.params):
            res.err(w.span, f"trajectory '{c.name}' takes {len(c.params)} arguments, got {len(w.args)}", "arity")
            continue
        warm.append(M.Warmstart(c.name, tuple(x.value for x in w.args), w.span))
    return M.Reachability(d.name.value, heuristics=tuple(heur), warmstarts=tuple(warm), span=d.span, **kw)


# ============================================================================================
# Problems
# ============================================================================================
class ProblemResolver:
    def __init__(self, ws: Workspace, f: ast.FileAst, dom: M.Domain) -> None:
        self.ws = ws
        self.f = f
        self.dom = dom
        self.r = ws.reporter
        self.actions = dom.actions
        self.continuous = dom.continuous
        self.tags_seen = _domain_tags(dom)

    def err(self, span, msg, kind="error", hint=None):
        self.r.error(span, msg, kind, hint)

    def run(self) -> M.Problem | None:
        f, dom = self.f, self.dom
        allowed = (ast.SceneRef, ast.ObjectsDecl, ast.InitDecl, ast.GoalDecl, ast.SolverDecl,
                   ast.RelaxationsDecl, ast.ReachabilityDecl)
        self.ws._reject(f, allowed, "a problem")
        objects = dict(dom.constants)
        for d in f.items:
            if isinstance(d, ast.ObjectsDecl):
                for g in d.groups:
                    if g.type.value not in dom.types:
                        self.err(g.type.span, f"unknown type '{g.type.value}'", "unknown-type",
                                 did_you_mean(g.type.value, dom.types))
                        continue
                    for n in g.names:
                        if n.value in objects:
                            self.err(n.span, f"object '{n.value}' is declared twice"
                                     + (" (it is a domain constant)" if n.value in dom.constants else ""),
                                     "duplicate")
                        elif n.value in M.BUILTIN_VALUES:
                            self.err(n.span, f"'{n.value}' is a builtin value", "reserved")
                        else:
                            objects[n.value] = g.type.value
        # a stand-in DomainResolver view for literal resolution
        view = _DomainView(dom, self.r)
        logic = LogicResolver(view, objects)
        init: dict[tuple, M.Assign] = {}
        init_span = None
        for d in f.items:
            if isinstance(d, ast.InitDecl):
                init_span = init_span or d.span
                for lit in d.lits:
                    x = logic.literal(lit, {})
                    if x is None:
                        continue
                    if not isinstance(x, M.StateLit) or x.negated:
                        self.err(lit.span, "the initial state assigns state variables: `var(...) = value` "
                                 "or a boolean `var(...)` / `not var(...)`", "init")
                        continue
                    key = (x.var, x.args)
                    if key in init:
                        self.err(lit.span, f"{_fact(x.var, x.args)} is assigned twice", "duplicate")
                        continue
                    init[key] = M.Assign(x.var, x.args, x.value, x.span)
        goal = []
        have_goal = False
        for d in f.items:
            if isinstance(d, ast.GoalDecl):
                have_goal = True
                for lit in d.lits:
                    x = logic.literal(lit, {})
                    if x is None:
                        continue
                    if isinstance(x, M.Compare) or (isinstance(x, M.StateLit) and x.negated):
                        self.err(lit.span, "a goal is a partial state: `var(...) = value`, boolean "
                                 "literals and derived predicates", "goal")
                        continue
                    goal.append(x)
        if not have_goal:
            self.err(f.header.span, "the problem has no goal", "goal", "add `goal { ... }`")
        # complete the initial state: defaults, and everything else must be given
        probe = M.Problem(f.header.name.value, f.path, dom, objects, (), ())
        missing = []
        full = []
        for v in dom.state_vars.values():
            for combo in probe.groundings(v.params):
                args = tuple(Obj(o) for o in combo)
                a = init.get((v.name, args))
                if a is None:
                    if v.is_bool:
                        a = M.Assign(v.name, args, Obj(M.FALSE))
                    elif v.allows_none:
                        a = M.Assign(v.name, args, Obj(M.NONE))
                    else:
                        missing.append(_fact(v.name, args))
                        continue
                full.append(a)
        if missing:
            shown = ", ".join(missing[:5]) + (f" and {len(missing) - 5} more" if len(missing) > 5 else "")
            self.err(init_span or f.header.span, f"the initial state gives no value to {shown}", "init",
                     "state variables without `none` in their domain must be assigned")
        settings = dom.settings
        relax = dom.relaxations
        reach = list(dom.reachability)
        scene_path = None
        scene = None
        scene_ref_span = None
        for d in f.items:
            if isinstance(d, ast.SolverDecl):
                settings = settings_solver(self, d, settings)
            elif isinstance(d, ast.RelaxationsDecl):
                relax = settings_relaxations(self, d)
            elif isinstance(d, ast.ReachabilityDecl):
                rb = settings_reachability(self, d)
                if rb is not None:
                    reach = [x for x in reach if x.name != rb.name] + [rb]
            elif isinstance(d, ast.SceneRef):
                if scene_path is not None:
                    self.err(d.span, "the problem names a second scene", "duplicate")
                    continue
                scene_path = str((Path(f.path).parent / d.path))
                scene_ref_span = d.span
                from gnppdsl.ir.scene import OBJECT_KEYS, ROBOT_KEYS, load_scene_with_spans

                scene, spans = load_scene_with_spans(scene_path, self.r, d.span)
                declared = set(dom.scene_attrs)
                for (entity, key), kspan in spans.items():
                    if key in declared:
                        continue
                    known = sorted(declared | set(OBJECT_KEYS) | set(ROBOT_KEYS))
                    hint = did_you_mean(key, known)
                    if hint is not None:
                        self.err(kspan, f"unknown key '{key}' in '{entity}'", "unknown-key", hint)
        if scene is not None:
            self.check_scene_objects(dom, objects, scene, scene_ref_span)
            for rb in reach:
                if rb.robot not in scene.robots:
                    self.err(rb.span, f"reachability '{rb.name}': robot '{rb.robot}' is not in the scene",
                             "unknown-name", did_you_mean(rb.robot, scene.robots))
        return M.Problem(f.header.name.value, f.path, dom, objects, tuple(full), tuple(goal), settings,
                         tuple(relax), tuple(reach), scene_path, scene, f.header.span)


    def check_scene_objects(self, dom: M.Domain, objects: dict[str, str], scene, span) -> None:
        """Objects with a geometric role must be in the scene: robots of `joints(r)` variables
        among its robots, objects with a frame or a continuous variable among its entries."""
        probe = M.Problem("", "", dom, objects, (), ())
        robots: dict[str, str] = {}
        placed: dict[str, str] = {}
        for c in dom.continuous.values():
            for combo in probe.groundings(c.params):
                for p, o in zip(c.params, combo):
                    if c.space.kind == "joints" and p.name == c.space.robot:
                        robots.setdefault(o, f"joints of '{c.name}'")
                    else:
                        placed.setdefault(o, f"a continuous variable '{c.name}'")
        for o, t in objects.items():
            if dom.frame_of(t) is not None:
                placed.setdefault(o, f"a frame (type '{dom.frame_of(t).param.type}')")
        where = f"scene {Path(scene.path).name}"
        for o, why in robots.items():
            if o not in scene.robots:
                self.err(span, f"object '{o}' needs a robot in {where} ({why})", "scene-missing",
                         did_you_mean(o, scene.robots) or "add it under `robots:`")
        for o, why in placed.items():
            if o not in robots and scene.entity(o) is None:
                self.err(span, f"object '{o}' has no entry in {where} (it has {why})", "scene-missing",
                         did_you_mean(o, list(scene.objects) + list(scene.robots))
                         or "add it under `objects:` (or `robots:`)")


def _fact(var: str, args) -> str:
    return f"{var}({', '.join(a.name for a in args)})" if args else var


def _domain_tags(dom: M.Domain) -> set[str]:
    tags: set[str] = set()
    for c in dom.continuous.values():
        tags |= c.tags
    for t in dom.templates.values():
        tags |= t.tags
    for r in dom.rules:
        tags |= r.tags
    return tags


class _DomainView:
    """The part of DomainResolver that LogicResolver needs, over a finished Domain."""

    def __init__(self, dom: M.Domain, reporter: Reporter) -> None:
        self.dom = dom
        self.r = reporter
        self.state_vars = dom.state_vars
        self.derived = dom.derived
        self.constants = dom.constants

    def err(self, span, msg, kind="error", hint=None):
        self.r.error(span, msg, kind, hint)

    def is_subtype(self, a: str, b: str) -> bool:
        return self.dom.is_subtype(a, b)


# ============================================================================================
# `gnpp check`
# ============================================================================================
@dataclass
class CheckReport:
    """Result of checking files: diagnostics (rendered by `render()`) and what was checked."""

    reporter: Reporter
    counts: dict[str, int]
    files: list[str]

    @property
    def ok(self) -> bool:
        return not self.reporter.has_errors()

    def render(self) -> str:
        return self.reporter.render()

    def summary(self) -> str:
        parts = [f"{n} {k}{'s' if n != 1 else ''}" for k, n in self.counts.items() if n]
        what = ", ".join(parts) if parts else f"{len(self.files)} file{'s' * (len(self.files) != 1)}"
        n_err = len(self.reporter.errors)
        n_warn = len(self.reporter.diagnostics) - n_err
        warn = f", {n_warn} warning{'s' if n_warn != 1 else ''}" if n_warn else ""
        if n_err:
            return f"{n_err} error{'s' if n_err != 1 else ''}{warn} in {what}"
        return f"ok: {what} checked{warn}"


def expand_paths(paths) -> list[str]:
    """Files as given; directories expand to their *.pntc files (sorted)."""
    out: list[str] = []
    for p in paths:
        pp = Path(p)
        if pp.is_dir():
            out.extend(str(x) for x in sorted(pp.glob("*.pntc")))
        else:
            out.append(str(pp))
    return out


def check_files(paths) -> CheckReport:
    """Check domains, problems, modules (.pntc) and scenes (.yaml); never raises for bad input."""
    ws = Workspace()
    files = expand_paths(paths)
    counts = {"domain": 0, "problem": 0, "module": 0, "scene": 0}
    for path in files:
        suffix = Path(path).suffix.lower()
        if suffix in (".yaml", ".yml"):
            from gnppdsl.ir.scene import load_scene

            counts["scene"] += 1
            load_scene(path, ws.reporter)
            continue
        if suffix != ".pntc":
            ws.err(None, f"{path}: not a .pntc or scene .yaml file", "file-kind",
                   ) if Path(path).exists() else ws.err(None, f"file not found: {path}", "missing-file")
            continue
        f = ws.parse(path)
        if f is None:
            continue
        kind = f.header.kind
        counts[kind] += 1
        if kind == "domain":
            ws.domain(path)
        elif kind == "module":
            ws.check_module(path)
        else:
            dom_path = ws.find_domain(f, [c for c in files if c != path and _peek_header(Path(c))
                                          and _peek_header(Path(c))[0] == "domain"])
            if dom_path is not None:
                ws.problem(path, dom_path)
    return CheckReport(ws.reporter, counts, files)
