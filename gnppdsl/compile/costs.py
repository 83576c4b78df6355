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
"""
from __future__ import annotations

import math
from typing import Sequence

from gnppdsl.compile.factory import SCALAR_FOLD, GraphNLPFactory
from gnppdsl.compile.ground import Binding, error_at
from gnppdsl.compile.sas import Operator, SASTask
from gnppdsl.errors import UserError
from gnppdsl.ir import model as m
from gnppdsl.ir.expr import Call, Index, Num, Vec
from gnppdsl.lang.diagnostics import Diagnostic, DiagnosticError

__all__ = ["ground_costs"]


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


def ground_costs(problem: m.Problem, task: SASTask, sources: Sequence[tuple[m.Action, Binding]]) -> SASTask:
    """`task` with the cost of each operator whose action has a `cost_expr` evaluated for its
    binding (`sources[i]` is operator i's action and binding). A value that is not a finite
    number >= 0 is a located error at the cost expression, naming the ground action."""
    if not any(a.cost_expr is not None for a, _ in sources):
        return task
    factory = GraphNLPFactory(problem, task)
    ops: list[Operator] = []
    for op, (act, b) in zip(task.operators, sources):
        if act.cost_expr is None:
            ops.append(op)
            continue
        where = f"the cost of {op.name}"
        value = _evaluate(factory.constant(act.cost_expr, dict(b), where), where)
        if isinstance(value, tuple) and len(value) == 1:
            value = value[0]
        if isinstance(value, tuple) or not math.isfinite(value) or value < 0:
            raise _cost_error(act, f"{where} is {value}, but an action cost is a finite number >= 0")
        ops.append(Operator(op.name, op.pre, op.effects, float(value)))
    task.operators = ops
    return task


def _cost_error(act: m.Action, message: str) -> UserError:
    """A located error (kind `cost`) at the action's cost expression."""
    span = getattr(act.cost_expr, "span", None) or act.span
    if span is None:
        return UserError(message)
    return DiagnosticError([Diagnostic(message, span, kind="cost")])
