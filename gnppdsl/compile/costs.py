"""Action costs of ground operators: the `cost` expressions of `gnppdsl.ir.resolve_costs`,
evaluated per ground action from the problem and its scene.

`Operator.cost` of the SAS+ task is a float >= 0 in the units the user wrote (e.g. metres of
travel plus a unit per action); `SASTask.integer_costs` gives the integers the logic planners
need. Scene attributes and consts are folded by the graph-NLP factory's resolver (the one the
constraints use, so `pose0(o)` means the same in a cost as in a template); what remains is a
tree of numbers, vectors and value builtins, evaluated here with numpy.

Why a small evaluator of its own: the independent numpy interpreter (`gnppdsl.nlp.evaluate`)
belongs to the nlp layer, above compile, and needs a geometry; a cost uses only the value
builtins listed in `_NUMERIC`, and a builtin outside it (a pose composition, a quaternion) is a
located error rather than a silent approximation.
"""
from __future__ import annotations

import math
from typing import Sequence

import numpy as np

from gnppdsl.compile.factory import GraphNLPFactory
from gnppdsl.compile.ground import Binding, error_at
from gnppdsl.compile.sas import Operator, SASTask
from gnppdsl.ir import model as m
from gnppdsl.ir.expr import Call, Index, Num, Vec

__all__ = ["ground_costs"]


def _vec(x) -> np.ndarray:
    return np.atleast_1d(np.asarray(x, dtype=float))


_NUMERIC = {
    "add": lambda a, b: np.add(a, b), "sub": lambda a, b: np.subtract(a, b),
    "mul": lambda a, b: np.multiply(a, b), "div": lambda a, b: np.divide(a, b),
    "neg": lambda a: np.negative(a), "pow": lambda a, b: np.power(a, b),
    "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "atan2": np.arctan2, "abs": np.abs,
    "exp": np.exp, "min": np.minimum, "max": np.maximum,
    "norm": lambda a: float(np.linalg.norm(_vec(a))), "sqnorm": lambda a: float(np.dot(_vec(a), _vec(a))),
    "dot": lambda a, b: float(np.dot(_vec(a), _vec(b))), "sum": lambda a: float(np.sum(a)),
    "concat": lambda *xs: np.concatenate([_vec(x) for x in xs]),
    "pos_se2": lambda p: _vec(p)[:2], "angle_se2": lambda p: float(_vec(p)[2]),
    "pos_se3": lambda p: _vec(p)[:3],
    "angle_diff": lambda a, b: math.atan2(math.sin(a - b), math.cos(a - b)),
}


def _evaluate(e, where: str):
    if isinstance(e, Num):
        return float(e.value)
    if isinstance(e, Vec):
        return np.array([float(np.squeeze(_evaluate(x, where))) for x in e.items])
    if isinstance(e, Index):
        base = _vec(_evaluate(e.base, where))
        k = int(_evaluate(e.index, where))
        if e.stop is None:
            return float(base[k])
        return base[k:int(_evaluate(e.stop, where))]
    if isinstance(e, Call) and e.fn in _NUMERIC:
        with np.errstate(all="ignore"):
            return _NUMERIC[e.fn](*(_evaluate(a, where) for a in e.args))
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
        value = np.squeeze(_evaluate(factory.constant(act.cost_expr, dict(b), where), where))
        if value.shape != () or not math.isfinite(float(value)) or float(value) < 0:
            raise error_at(getattr(act.cost_expr, "span", None),
                           f"{where} is {value}, but an action cost is a finite number >= 0")
        ops.append(Operator(op.name, op.pre, op.effects, float(value)))
    task.operators = ops
    return task
