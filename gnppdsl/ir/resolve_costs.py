"""Action costs as expressions: `cost 10.5`, `cost 1 + norm(pos(pose0(o)) - pos(pose0(to)))`.

An action's cost is a non-negative scalar of the *problem and the scene*: numbers, `const`s,
the action's parameters as arguments of scene attributes (`pose0`, `radius`, any attribute a
module declares), and the value builtins (`norm`, `pos`, `dot`, `+`, ...). It is evaluated once
per ground operator when the problem is compiled (`gnppdsl.compile.costs`) and becomes
`Operator.cost` (a float) of the SAS+ task, so the logic planner can minimise it (clingo
`#minimize`, Fast Downward action costs).

Why not continuous variables, state values or `world(...)`: the logic planner decides on costs
before any NLP is solved, so a cost must be known per ground action; what depends on the motion
belongs in a template's `minimize` statement (the optimisation phase). Each such use is a
located error of `gnpp check` (kind `cost`) naming what the cost may use instead.

The reachability graph's travel is a cost too: `travel(r, a, b)`, the path cost (Eq. 3 of paper
002) of robot r's end effector from the target of a to the target of b, and `travel_lb(r, a, b)`,
its straight-line lower bound from the scene. Both take three objects and are numbers; only a
cost may call them (`Scope.allow_travel`). What they need of the problem (a 3-D scene, a
`reachability` block for the ground robot, targets in the scene) is checked when the costs are
grounded (`gnppdsl.compile.costs`), where the ground robot is known.

Checked after the continuous declarations, so that `cost norm(q(r))` is reported as a use of a
continuous variable rather than as an unknown function.
"""
from __future__ import annotations

from dataclasses import replace as dc_replace

from gnppdsl.ir import model as M
from gnppdsl.ir.expr import Call, CVar, IterVar, Param, StateValue, With
from gnppdsl.ir.typecheck import OBJ, Checker, fold
from gnppdsl.lang import ast

__all__ = ["resolve_action_cost"]

# user-level functions whose value needs a symbolic state, a configuration or a trajectory
_STATEFUL = {"world": "the world pose world(...) (it depends on the symbolic state)",
             "sdist": "the signed distance sdist(...) (it depends on the motion)",
             "fk": "forward kinematics fk(...) (it depends on the configuration)",
             "link": "a robot link (only meaningful with fk or sdist)",
             "waypoints": "waypoints(...) of a trajectory",
             "next": "a primed value"}
_HINT = ("a cost is evaluated when the problem is compiled: use numbers, consts and scene "
         "attributes of the parameters (e.g. norm(pos(pose0(a)) - pos(pose0(b)))); costs of the "
         "motion belong in a template's `minimize` statement")


def resolve_action_cost(dom, action: M.Action, d: ast.ActionDecl) -> M.Action:
    """`action` with its `cost` (a constant) or `cost_expr` (an expression of the parameters,
    evaluated per ground operator) from the declaration's `cost` part; errors go to `dom.err`."""
    if d.cost is None:
        return action
    sc = dom.scope(params={p.name: (Param(p.name), OBJ(p.types)) for p in action.params},
                   allow_prime=False,
                   prime_context="in an action cost (a cost is a number per ground action)")
    sc.allow_travel = True
    # `pose0(o)` is the object's world pose in the scene: of the domain's pose space (SE2 or
    # SE3, known from the frames), so that `pos(pose0(o))` has a type in a cost
    pose0 = sc.scene_attrs.get("pose0")
    if pose0 is not None and pose0.space is None and sc.world_space is not None:
        sc.scene_attrs = {**sc.scene_attrs, "pose0": dc_replace(pose0, space=sc.world_space)}
    reporter = dom.r
    before = len(reporter.errors)
    x, t = Checker(sc, reporter).expr(d.cost)
    if len(reporter.errors) > before or t.kind == "error":
        return action
    bad = _stateful(x, sc)
    if bad is not None:
        node, what = bad
        dom.err(getattr(node, "span", None) or d.cost.span,
                f"an action cost cannot use {what}", "cost", _HINT)
        return action
    scalar = t.kind == "any" or (t.kind == "value" and t.space is not None and t.space.dim == 1
                                 and t.space.kind in ("R", "int"))
    if not scalar:
        dom.err(d.cost.span, f"an action cost is a number (R), but this is {t}", "cost",
                "e.g. norm(v) or v[0] for a vector v")
        return action
    value = fold(x)
    if value is not None:
        if not value >= 0 or value == float("inf"):
            dom.err(d.cost.span, f"an action cost is a finite number >= 0, got {value:g}", "cost")
            return action
        return M.Action(action.name, action.params, action.pre, action.effects, float(value),
                        action.span)
    return M.Action(action.name, action.params, action.pre, action.effects, 1.0, action.span,
                    cost_expr=x)


def _stateful(e, sc) -> tuple[object, str] | None:
    """The first node of a typed expression that a compile-time cost cannot evaluate."""
    if isinstance(e, CVar):
        return e, f"the continuous variable '{e.name}'"
    if isinstance(e, StateValue):
        return e, f"the state value '{e.name}(...)' (the cost is per ground action, not per state)"
    if isinstance(e, With):
        return e, "`with` (it substitutes continuous variables)"
    if isinstance(e, IterVar):
        return e, f"the index '{e.name}'"
    if isinstance(e, Call):
        if e.fn in _STATEFUL:
            return e, _STATEFUL[e.fn]
        if e.fn in sc.primitives:
            return e, f"the primitive '{e.fn}' (it is evaluated on the motion)"
    for child in _children(e):
        found = _stateful(child, sc)
        if found is not None:
            return found
    return None


def _children(e) -> tuple:
    if isinstance(e, Call):
        return e.args
    items = getattr(e, "items", None)
    if items is not None:
        return tuple(items)
    out = []
    for name in ("base", "index", "stop"):
        child = getattr(e, name, None)
        if child is not None and not isinstance(child, (int, float, str)):
            out.append(child)
    return tuple(out)

