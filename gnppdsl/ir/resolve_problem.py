"""A problem file -> `model.Problem`: objects, initial state (completed with defaults), goal,
settings blocks and the scene (loaded, and checked against the objects with a geometric role).

Separate because a problem is resolved against a finished `model.Domain`, not a domain being
built: the logic resolver sees the domain through `_DomainView`.
"""
from __future__ import annotations

import dataclasses
from pathlib import Path

from gnppdsl.ir import model as M
from gnppdsl.ir.expr import Call, Obj, Param, Str
from gnppdsl.ir.families import FactExpander, group_names
from gnppdsl.ir.resolve_logic import LogicResolver
from gnppdsl.ir.resolve_settings import settings_reachability, settings_relaxations, settings_solver
from gnppdsl.ir.modules import ModuleLibrary
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter, did_you_mean


class ProblemResolver:
    """Resolves one problem file against its resolved domain; `run()` returns the `model.Problem`."""

    def __init__(self, ws: ModuleLibrary, f: ast.FileAst, dom: M.Domain) -> None:
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
                    for n in group_names(g, self.r):
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
        expander = FactExpander(objects, dom.types, dom.is_subtype,
                                set(dom.state_vars) | set(dom.derived) | set(M.BUILTIN_VALUES), self.r)
        init: dict[tuple, M.Assign] = {}
        init_span = None
        init_compound = False          # an `or` / `and` in init, reported: no follow-up errors
        for d in f.items:
            if isinstance(d, ast.InitDecl):
                init_span = init_span or d.span
                for lit in expander.expand(d.lits):
                    if isinstance(lit, (ast.FOr, ast.FAnd)):
                        init_compound = True
                        self.err(lit.span, f"the initial state is one value per state variable: "
                                 f"no `{'or' if isinstance(lit, ast.FOr) else 'and'}` here", "init",
                                 "`or` and `and` combine goal facts")
                        continue
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
                for lit in expander.expand(d.lits):
                    x = logic.formula(lit, {})
                    if x is None:
                        continue
                    bad = _non_goal_literal(x, lit)
                    if bad is not None:
                        self.err(bad.span, "a goal is a partial state: `var(...) = value`, boolean "
                                 "literals and derived predicates (combined by `or` / `and`)", "goal")
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
        if missing and not init_compound:
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
                from gnppdsl.ir.instances import RANDOM_KEYS
                from gnppdsl.ir.scene import OBJECT_KEYS, ROBOT_KEYS, load_scene_with_spans

                scene, spans = load_scene_with_spans(scene_path, self.r, d.span)
                declared = set(dom.scene_attrs)
                for (entity, key), kspan in spans.items():
                    if key in declared or key in RANDOM_KEYS:     # draw ranges: not attributes
                        continue
                    known = sorted(declared | set(OBJECT_KEYS) | set(ROBOT_KEYS))
                    hint = did_you_mean(key, known)
                    if hint is not None:
                        self.err(kspan, f"unknown key '{key}' in '{entity}'", "unknown-key", hint)
        if scene is not None:
            self.check_scene_objects(dom, objects, scene, scene_ref_span)
            self.check_link_names(dom, scene)
            self.check_scene_attributes(dom, objects, scene)
            for rb in reach:
                if scene.dimension != 3:
                    # the graph samples IK solutions of a URDF robot: refused here rather than
                    # when `rlgp` first builds it (gnppdsl.reach.integration)
                    travels = [h for h in rb.heuristics if h.measure == "travel"]
                    for x in travels or [rb]:
                        what = "travel(...) costs come from" if travels else "reachability blocks describe"
                        self.err(x.span, f"reachability '{rb.name}': {what} a reachability graph, "
                                 f"which needs a 3-D scene with a URDF robot; scene '{scene.name}' is "
                                 f"planar", "scene", "drop the block for planar problems, or give "
                                 "the action a `cost` expression (e.g. a scene distance)")
                    continue
                if rb.robot not in scene.robots:
                    self.err(rb.span, f"reachability '{rb.name}': robot '{rb.robot}' is not in the scene",
                             "unknown-name", did_you_mean(rb.robot, scene.robots))
        return M.Problem(f.header.name.value, f.path, dom, objects, tuple(full), tuple(goal), settings,
                         tuple(relax), tuple(reach), scene_path, scene, f.header.span)


    def check_link_names(self, dom: M.Domain, scene) -> None:
        """Every `link(r, "NAME")` of a template some rule calls names, for a robot of the
        scene, a role of its `links:` or a link of its URDF that has collision geometry, and every
        `fk(r, q, "NAME")` a role, a link or a joint (a frame of the model); else
        the error stands at the name (read from the URDF's text, as the scene's `links:` are:
        no robot model is loaded). Which robot `r` is, grounding decides; here any URDF robot
        of the scene will do, which catches misspelt names and another robot's links."""
        from gnppdsl.ir.scene import urdf_collision_links, urdf_frames

        names: set[str] = set()
        frames: set[str] = set()
        for spec in scene.robots.values():
            if spec.kind != "urdf":
                continue
            known, every = urdf_collision_links(spec.model, spec.urdf), urdf_frames(spec.model, spec.urdf)
            if known is None or every is None:
                return                  # the robot cannot be read: loading it reports that
            names |= set(known) | set(spec.links)
            frames |= set(every) | set(spec.links) | ({spec.ee} if spec.ee else set())
        if not names:
            return
        called = {c.template for rule in dom.rules for c in rule.calls}
        robots = ", ".join(sorted(n for n, r in scene.robots.items() if r.kind == "urdf"))
        # primitive -> (its name argument, the names it accepts, what they are, the hint's last resort)
        checked = {"link": (1, names, "link", "a link or a `links:` role",
                            "name a role of the scene robot's `links:` or a URDF link with collision geometry"),
                   "fk": (2, frames, "frame", "a link, joint or `links:` role",
                          "name a role of the scene robot's `links:` or a link of its URDF")}
        seen: set[int] = set()
        for t in (dom.templates[n] for n in called if n in dom.templates):
            for node in _walk(t.body):
                if not isinstance(node, Call) or node.fn not in checked or id(node) in seen:
                    continue
                arg, known, what, has, fallback = checked[node.fn]
                if len(node.args) != arg + 1 or not isinstance(node.args[arg], Str) \
                        or node.args[arg].value in known:
                    continue
                seen.add(id(node))
                name = node.args[arg].value
                self.err(node.args[arg].span or node.span or t.span,
                         f"{what} '{name}' (template {t.name}): no robot of scene {Path(scene.path).name} "
                         f"({robots}) has {has} of that name", "unknown-link",
                         did_you_mean(name, sorted(known)) or fallback)

    def check_scene_attributes(self, dom: M.Domain, objects: dict[str, str], scene) -> None:
        """A scene attribute a template reads of one of its parameters (`base_clearance(r)`),
        called by a rule with one of the rule's parameters there, must be in the scene entry of
        every problem object of that parameter's type; else the solve stops at the first
        grounding that reads it (a located error, but after loading, grounding and planning).
        An error when the rule applies at every step to every grounding (`always`, no `where`);
        a warning otherwise, since the rule's pattern may never hold for that object. Attributes
        the factory derives from the entry itself (`size`, `home`, `pose0`, ...) are not
        checked: whether those exist depends on the entry's kind, not on its keys."""
        from gnppdsl.ir.scene_model import DERIVED_ATTRIBUTES

        declared = {n for n in dom.scene_attrs if n not in DERIVED_ATTRIBUTES}
        if not declared:
            return
        probe = M.Problem("", "", dom, objects, (), ())
        reported: set[tuple[str, str]] = set()
        for rule in dom.rules:
            types = {p.name: p for p in rule.params}
            certain = rule.kind == "always" and not rule.where
            for call in rule.calls:
                t = dom.templates.get(call.template)
                if t is None:
                    continue
                bound = {sig.name: a.name for sig, a in zip(t.params, call.args)
                         if isinstance(a, Param) and a.name in types}
                # reads in the template's body (of its parameters) and in the call's arguments
                # (of the rule's: `planar.within(q(g), reach_min(g), reach_max(g))`)
                reads = [(node, bound) for node in _walk(t.body)] + \
                    [(node, {n: n for n in types}) for node in _walk(call.args)]
                for node, names in reads:
                    if not (isinstance(node, Call) and node.fn in declared and len(node.args) == 1
                            and isinstance(node.args[0], Param) and node.args[0].name in names):
                        continue
                    param = types[names[node.args[0].name]]
                    for (obj,) in probe.groundings((param,)):
                        ent = scene.entity(obj)
                        if ent is None or node.fn in ent.attributes or (node.fn, obj) in reported:
                            continue
                        reported.add((node.fn, obj))
                        report = self.err if certain else self.r.warning
                        report(node.span or call.span or rule.span,
                               f"scene entry '{obj}' of {Path(scene.path).name} has no attribute "
                               f"'{node.fn}', which rule {rule.name} reads of it (calling {t.name})",
                               "scene-missing", f"add `{node.fn}:` to '{obj}' in the scene")

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


def _non_goal_literal(x, lit):
    """The first literal of a goal item that is not a partial-state fact (a comparison or a
    `!=`), or None. `x` is the resolved item (a literal, or M.Or / M.And of them)."""
    if isinstance(x, (M.Or, M.And)):
        for sub, sub_ast in zip(x.items, lit.items):
            bad = _non_goal_literal(sub, sub_ast)
            if bad is not None:
                return bad
        return None
    if isinstance(x, M.Compare) or (isinstance(x, M.StateLit) and x.negated):
        return lit
    return None


def _walk(node):
    """Every expression node below `node` (statements, tuples, dataclass fields), pre-order."""
    if isinstance(node, (tuple, list)):
        for x in node:
            yield from _walk(x)
        return
    if not dataclasses.is_dataclass(node):
        return
    yield node
    for f in dataclasses.fields(node):
        if f.name != "span":
            yield from _walk(getattr(node, f.name))
