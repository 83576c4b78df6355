"""A small numeric evaluator of resolved (stage-2) factor bodies, for tests only.

Independent of the nlp layer on purpose: it lets the factory tests check that the bodies mean
what the templates say, by evaluating them on hand-built geometric solutions.
"""
from __future__ import annotations

import math

import numpy as np

from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Str, Vec


def _se2(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def _inv(a):
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2]])


FUNCS = {
    "add": lambda a, b: a + b, "sub": lambda a, b: a - b, "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b, "neg": lambda a: -a, "pow": lambda a, b: a ** b,
    "sqnorm": lambda a: float(np.dot(a, a)), "norm": lambda a: float(np.linalg.norm(a)),
    "compose_se2": _se2, "inv_se2": _inv, "pos_se2": lambda a: np.asarray(a[:2]),
    "angle_se2": lambda a: a[2],
}


def evaluate(e, values):
    if isinstance(e, Num):
        return e.value
    if isinstance(e, Vec):
        return np.array([evaluate(x, values) for x in e.items], dtype=float)
    if isinstance(e, Slot):
        return np.asarray(values[e.index], dtype=float)
    if isinstance(e, Index):
        return evaluate(e.base, values)[int(evaluate(e.index, values))]
    if isinstance(e, Call):
        if e.fn == "waypoint":
            traj = evaluate(e.args[0], values)
            return traj.reshape(-1, 3)[int(evaluate(e.args[1], values))]
        return FUNCS[e.fn](*(evaluate(a, values) for a in e.args))
    if isinstance(e, (Obj, Str)):
        raise TypeError(f"cannot evaluate {e!r} numerically")
    raise TypeError(e)


def violation(c: Constraint, values) -> float:
    d = np.atleast_1d(evaluate(c.lhs, values) - evaluate(c.rhs, values))
    if c.op == "==":
        return float(np.max(np.abs(d)))
    if c.op == "<=":
        return float(max(0.0, np.max(d)))
    return float(max(0.0, np.max(-d)))
