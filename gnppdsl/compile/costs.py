"""Action costs of ground operators: the `cost` expressions of `gnppdsl.ir.resolve_costs`,
evaluated per ground action from the problem and its scene.

`Operator.cost` of the SAS+ task is a float >= 0 in the units the user wrote (e.g. metres of
travel plus a unit per action); `SASTask.integer_cost` gives the integers the logic planners
need. Scene attributes and consts are folded by the graph-NLP factory's resolver (the one the
constraints use, so `pose0(o)` means the same in a cost as in a template); what remains is a
tree of numbers, vectors and value builtins, evaluated here in plain Python (no numpy, so
`gnpp check`, which grounds costs, stays free of heavy imports).

Why a small evaluator of its own: the independent numpy interpreter (`gnppdsl.nlp.evaluate`)
belongs to the nlp layer, above compile, and needs a geometry; a cost uses only the value
builtins listed in `_NUMERIC`, and a builtin outside it (a pose composition, a quaternion) is a
located error rather than a silent approximation.

Travel (`travel(r, a, b)`, `travel_lb(r, a, b)`, see `gnppdsl.ir.resolve_costs`): the targets of a
and b are the scene positions R-LGP's `heuristic` uses (`gnppdsl.reach.integration.target_position`:
a movable object's centre, a little above a static place's top face). `travel_lb` is
w_x * |(x_a, y_a) - (x_b, y_b)|, w_x the Eq. 3 weight of r's `reachability` block: an admissible
lower bound of the graph's travel, because every edge of a graph path costs at least w_x times
the distance between its end-effector positions, the path's ends are the two targets themselves
(a query attaches a node at each), and the horizontal distance is at most the 3-D one. It needs
only the scene, so it is evaluated here. `travel` needs the graph, which lives above this layer
(`gnppdsl.reach`, built by the solve layer): `ground_costs` evaluates it as its lower bound, and
the solve layer replaces those costs by the graph's (`ground_travel_costs` with a `TravelFn`),
so the compiled task (`gnpp compile`, the exports) carries the bound and a solve the travel.
"""

from __future__ import annotations

import math
from dataclasses import replace as dc_replace
from typing import Callable, Sequence

from gnppdsl.compile.factory import SCALAR_FOLD, GraphNLPFactory
from gnppdsl.compile.ground import Binding, bindings, error_at, operator_name
from gnppdsl.compile.sas import Operator, SASTask
from gnppdsl.errors import UserError
from gnppdsl.ir import model as m
from gnppdsl.ir.expr import Call, Index, Num, Obj, Param, Vec
from gnppdsl.lang.diagnostics import Diagnostic, DiagnosticError

__all__ = ["ground_costs", "ground_travel_costs", "uses_travel", "TravelFn", "UNREACHABLE_TRAVEL"]

# (robot, from entity, to entity) -> the reachability graph's travel cost (inf: no path)
TravelFn = Callable[[str, str, str], float]
# what `travel` costs between targets the graph cannot connect (metres-like units of Eq. 3): far
# more than any travel in a room, finite so that the planner can still weigh such actions
UNREACHABLE_TRAVEL = 1e4


def _ew(f):
    """An elementwise function of scalars and equal-length vectors (a scalar broadcasts)."""

    def apply(*xs):
        n = max((len(x) for x in xs if isinstance(x, tuple)), default=None)
        if n is None:
            return float(f(*xs))
        if any(isinstance(x, tuple) and len(x) != n for x in xs):
            raise ValueError("vectors of different lengths")
        return tuple(float(f(*(x[k] if isinstance(x, tuple) else x for x in xs))) for k in range(n))

    return apply


def _t(x) -> tuple[float, ...]:
    return x if isinstance(x, tuple) else (x,)


_NUMERIC = {
    **{fn: _ew(f) for fn, f in SCALAR_FOLD.items()},     # the factory's scalar folding, elementwise
    "norm": lambda a: math.hypot(*_t(a)), "sqnorm": lambda a: math.fsum(x * x for x in _t(a)),
    "dot": lambda a, b: math.fsum(x * y for x, y in zip(_t(a), _t(b), strict=True)),
    "sum": lambda a: math.fsum(_t(a)), "concat": lambda *xs: tuple(v for x in xs for v in _t(x)),
    "pos_se2": lambda p: _t(p)[:2], "angle_se2": lambda p: _t(p)[2], "pos_se3": lambda p: _t(p)[:3],
    "angle_diff": lambda a, b: math.atan2(math.sin(a - b), math.cos(a - b)),
}


def _evaluate(e, where: str) -> float | tuple[float, ...]:
    """The value of a constant stage-2 body: a float or a tuple of floats."""
    if isinstance(e, Num):
        return float(e.value)
    if isinstance(e, Vec):
        items = [_evaluate(x, where) for x in e.items]
        return tuple(v for x in items for v in _t(x))
    if isinstance(e, Index):
        base = _t(_evaluate(e.base, where))
        k = int(_evaluate(e.index, where))
        if e.stop is None:
            return base[k]
        return base[k:int(_evaluate(e.stop, where))]
    if isinstance(e, Call) and e.fn in _NUMERIC:
        args = [_evaluate(a, where) for a in e.args]
        try:
            return _NUMERIC[e.fn](*args)
        except (ValueError, ZeroDivisionError, OverflowError) as exc:
            raise error_at(getattr(e, "span", None), f"{where}: {e.fn} fails ({exc})") from None
    name = e.fn if isinstance(e, Call) else type(e).__name__
    raise error_at(getattr(e, "span", None), f"{where}: '{name}' cannot be evaluated in an action "
                                             f"cost (value builtins only: {', '.join(sorted(_NUMERIC))})")


def ground_costs(problem: m.Problem, task: SASTask, sources: Sequence[tuple[m.Action, Binding]],
                 travel: TravelFn | None = None) -> SASTask:
    """`task` with the cost of each operator whose action has a `cost_expr` evaluated for its
    binding (`sources[i]` is operator i's action and binding). A value that is not a finite
    number >= 0 is a located error at the cost expression, naming the ground action. `travel`
    gives `travel(r, a, b)` its graph value; without it, its lower bound `travel_lb`."""
    if not any(a.cost_expr is not None for a, _ in sources):
        return task
    factory = GraphNLPFactory(problem, task)
    terms = _Travel(problem, travel)
    ops: list[Operator] = []
    for op, (act, b) in zip(task.operators, sources):
        if act.cost_expr is None:
            ops.append(op)
            continue
        ops.append(dc_replace(op, cost=_ground_cost(factory, terms, op, act, b)))
    task.operators = ops
    return task


def ground_travel_costs(problem: m.Problem, task: SASTask, travel: TravelFn) -> SASTask:
    """A copy of `task` whose operators with `travel(...)` in their action's cost carry the
    graph's travel (`travel`, from the solve layer) instead of its lower bound. An operator is
    matched to its action and binding by the name the grounding gave it (`ground.operator_name`,
    over the same `bindings`); the other operators are kept."""
    sources = {operator_name(a.name, a.params, b): (a, b)
               for a in problem.domain.actions.values()
               if a.cost_expr is not None and uses_travel(a.cost_expr, ("travel",))
               for b in bindings(problem, a.params)}
    if not sources:
        return task
    factory = GraphNLPFactory(problem, task)
    terms = _Travel(problem, travel)
    ops: list[Operator] = []
    for op in task.operators:
        source = sources.get(op.name)
        if source is None:
            ops.append(op)
            continue
        act, b = source
        ops.append(dc_replace(op, cost=_ground_cost(factory, terms, op, act, b)))
    return dc_replace(task, operators=ops)


def uses_travel(e, fns: Sequence[str] = ("travel", "travel_lb")) -> bool:
    """Does the (typed) cost expression call one of `fns`?"""
    if isinstance(e, Call):
        return e.fn in fns or any(uses_travel(a, fns) for a in e.args)
    if isinstance(e, Vec):
        return any(uses_travel(a, fns) for a in e.items)
    if isinstance(e, Index):
        return any(uses_travel(a, fns) for a in (e.base, e.index, e.stop) if a is not None)
    return False


def _ground_cost(factory: GraphNLPFactory, terms: "_Travel", op: Operator, act: m.Action, b) -> float:
    where = f"the cost of {op.name}"
    expr = terms.substitute(act.cost_expr, dict(b), where)
    value = _evaluate(factory.constant(expr, dict(b), where), where)
    if isinstance(value, tuple) and len(value) == 1:
        value = value[0]
    if isinstance(value, tuple) or not math.isfinite(value) or value < 0:
        raise _cost_error(act, f"{where} is {value}, but an action cost is a finite number >= 0")
    return float(value)


class _Travel:
    """The `travel` / `travel_lb` terms of one problem's costs: their checks (located at the
    call, kind `cost`) and their values."""

    def __init__(self, problem: m.Problem, travel: TravelFn | None):
        self.problem, self.travel = problem, travel
        self.blocks = {b.robot: b for b in getattr(problem, "reachability", ()) or ()}

    def substitute(self, e, binding: dict[str, str], where: str):
        """`e` with each travel call replaced by its number for `binding`."""
        if isinstance(e, Call):
            if e.fn in ("travel", "travel_lb"):
                return Num(self.value(e, binding, where), e.span)
            return dc_replace(e, args=tuple(self.substitute(a, binding, where) for a in e.args))
        if isinstance(e, Vec):
            return dc_replace(e, items=tuple(self.substitute(a, binding, where) for a in e.items))
        if isinstance(e, Index):
            return dc_replace(e, base=self.substitute(e.base, binding, where))
        return e

    def value(self, call: Call, binding: dict[str, str], where: str) -> float:
        names = []
        for a in call.args:
            if isinstance(a, Param) and a.name in binding:
                names.append(binding[a.name])
            elif isinstance(a, Obj):
                names.append(a.name)
            else:
                raise _at(call, f"{where}: {call.fn}(...) takes objects (parameters or constants)")
        r, a, b = names
        w_x = self._block(call, r, where).weights[0]
        (xa, ya), (xb, yb) = self._target(call, a, where), self._target(call, b, where)
        bound = float(w_x) * math.hypot(xa - xb, ya - yb)
        if call.fn == "travel_lb" or self.travel is None:
            return bound
        c = float(self.travel(r, a, b))
        return c if math.isfinite(c) else UNREACHABLE_TRAVEL

    def _block(self, call: Call, robot: str, where: str):
        p, scene = self.problem, self.problem.scene
        if scene is None:
            raise _at(call, f"{where}: {call.fn}(...) needs the problem's scene (`scene \"file.yaml\"`)")
        if getattr(scene, "dimension", 3) != 3:
            raise _at(call, f"{where}: {call.fn}(...) is the travel of a reachability graph, which "
                            f"needs a 3-D scene with a URDF robot; scene '{scene.name}' is planar",
                      "use a scene distance instead, e.g. norm(pos(pose0(a)) - pos(pose0(b)))")
        if not self.blocks:
            raise _at(call, f"{where}: {call.fn}(...) needs a `reachability` block for robot '{robot}', "
                            f"and problem '{p.name}' has none",
                      f"add `reachability NAME {{ robot = {robot} ... }}` to the domain or the problem")
        block = self.blocks.get(robot)
        if block is None:
            have = ", ".join(f"'{b.name}' for {b.robot}" for b in self.blocks.values())
            what = "a scene robot" if robot in scene.robots else "not a scene robot"
            raise _at(call, f"{where}: '{robot}' ({what}) has no reachability graph; the first argument "
                            f"of {call.fn} is the robot of a `reachability` block ({have})")
        return block

    def _target(self, call: Call, name: str, where: str) -> tuple[float, float]:
        o = self.problem.scene.objects.get(name)
        if o is None:
            what = "a robot" if name in self.problem.scene.robots else "not in the scene"
            raise _at(call, f"{where}: '{name}' ({what}) is no target of {call.fn}: the end effector "
                            "travels between scene objects")
        return float(o.pose[0]), float(o.pose[1])


def _at(node, message: str, hint: str | None = None) -> UserError:
    span = getattr(node, "span", None)
    if span is None:
        return UserError(message)
    return DiagnosticError([Diagnostic(message, span, kind="cost", hint=hint)])


def _cost_error(act: m.Action, message: str) -> UserError:
    """A located error (kind `cost`) at the action's cost expression."""
    span = getattr(act.cost_expr, "span", None) or act.span
    if span is None:
        return UserError(message)
    return DiagnosticError([Diagnostic(message, span, kind="cost")])
