"""An independent numpy interpreter of resolved (stage-2) bodies, to re-check solutions.

Why a second implementation: a solution is only trusted if the constraints hold when evaluated
by code that shares nothing with the solver path (`casadi_expr` + ipopt). This module walks the
body tree directly, keeps every numeric constant in place (no lifting), and implements rotations
through explicit rotation matrices and angles (casadi_expr uses quaternion algebra), so a bug in
one is unlikely to be repeated in the other. Geometry goes through the numeric methods of the
injected `Geometry`.

Violation of a row: |h| for `==`, max(h, 0) for `<=`/`>=` (after moving everything to h <= 0).
"""
from __future__ import annotations

import math
from typing import Any, Iterable, Mapping

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Call, Index, Num, Obj, Slot, Vec
from gnppdsl.nlp.geometry_protocol import Body, Geometry


class EvaluationError(ValueError):
    pass


def _rot(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion [qx, qy, qz, qw], normalised first (Rodrigues form)."""
    q = np.asarray(q, float)
    nq = np.linalg.norm(q)
    x, y, z, w = q / nq if nq > 0 else (0.0, 0.0, 0.0, 1.0)
    angle = 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), w)
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-15:
        return np.eye(3)
    k = np.array([x, y, z]) / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _quat(R: np.ndarray, like: np.ndarray | None = None) -> np.ndarray:
    """Quaternion [qx, qy, qz, qw] of a rotation matrix (sign chosen to match `like`)."""
    t = np.trace(R)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = np.array([(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s,
                      (R[1, 0] - R[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k]) * 2
        q = np.zeros(4)
        q[i] = 0.25 * s
        q[j] = (R[j, i] + R[i, j]) / s
        q[k] = (R[k, i] + R[i, k]) / s
        q[3] = (R[k, j] - R[j, k]) / s
    if like is not None and float(np.dot(q, like)) < 0:
        q = -q
    return q


def _hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product via the 4x4 left-multiplication matrix of a (xyzw layout)."""
    x, y, z, w = a
    L = np.array([[w, -z, y, x],
                  [z, w, -x, y],
                  [-y, x, w, z],
                  [-x, -y, -z, w]])
    return L @ np.asarray(b, float)


def _r2(t: float) -> np.ndarray:
    return np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])


def _scalar(v: np.ndarray) -> float:
    if v.size != 1:
        raise EvaluationError(f"expected a scalar, got length {v.size}")
    return float(v.reshape(-1)[0])


def _const(e: Any) -> float:
    if isinstance(e, Num):
        return float(e.value)
    if isinstance(e, Call) and e.fn in ("add", "sub", "mul", "div", "neg"):
        a = [_const(x) for x in e.args]
        return -a[0] if e.fn == "neg" else {"add": a[0] + a[1], "sub": a[0] - a[1],
                                             "mul": a[0] * a[1], "div": a[0] / a[1]}[e.fn]
    raise EvaluationError(f"expected a constant, got {e!r}")


class _Interp:
    def __init__(self, factor: FactorInstance, values: Mapping[VarInstance, Any],
                 geometry: Geometry | None):
        self.f, self.geometry = factor, geometry
        try:
            self.x = [np.asarray(values[v], float).reshape(-1) for v in factor.variables]
        except KeyError as err:
            raise EvaluationError(f"no value for variable {err.args[0]}") from None

    def waypoint(self, e: Any, k: int) -> np.ndarray:
        if not isinstance(e, Slot) or not self.f.variables[e.index].waypoints:
            raise EvaluationError("waypoint of a non-trajectory")
        v = self.f.variables[e.index]
        pts = self.x[e.index].reshape(v.waypoints, v.point_dim)
        return pts[k]

    def body(self, e: Any) -> Body:
        if isinstance(e, Obj):
            return Body(e.name)
        if isinstance(e, Call) and e.fn == "link":
            return Body(e.args[0].name, link=e.args[1].value)
        raise EvaluationError(f"not a body: {e!r}")

    def ev(self, e: Any) -> np.ndarray:
        if isinstance(e, Num):
            return np.array([float(e.value)])
        if isinstance(e, Slot):
            return self.x[e.index]
        if isinstance(e, Vec):
            return np.concatenate([self.ev(i) for i in e.items])
        if isinstance(e, Index):
            i = int(_const(e.index))
            if isinstance(e.base, Slot) and self.f.variables[e.base.index].waypoints \
                    and e.stop is None:
                return self.waypoint(e.base, i)
            b = self.ev(e.base)
            if e.stop is None:
                return b[[i]]
            return b[i:int(_const(e.stop))]
        if isinstance(e, Call):
            return np.atleast_1d(np.asarray(self.call(e), float)).reshape(-1)
        raise EvaluationError(f"cannot evaluate {e!r}")

    def call(self, e: Call):
        fn, A = e.fn, e.args
        if fn == "pow":
            return self.ev(A[0]) ** _const(A[1])
        if fn == "waypoint":
            return self.waypoint(A[0], int(_const(A[1])))
        if fn == "axis_se3":
            return _rot(self.ev(A[0])[3:7])[:, int(_const(A[1]))]
        if fn == "quat_axis":
            return _rot(self.ev(A[0]))[:, int(_const(A[1]))]
        g = self.geometry
        if fn == "fk":
            return g.fk_numeric(A[0].name, self.ev(A[1]), A[2].value, self.ev(A[3]))
        if fn == "sdist":
            return g.sdist_numeric(self.body(A[0]), self.ev(A[1]), self.body(A[2]), self.ev(A[3]))
        if fn == "sdist2":
            return g.sdist2_numeric(self.body(A[0]), self.ev(A[1]), self.body(A[2]),
                                    self.ev(A[3]))
        v = [self.ev(a) for a in A]
        return _NUMERIC[fn](*v)


def _compose_se2(a, b):
    return np.concatenate([a[:2] + _r2(a[2]) @ b[:2], [a[2] + b[2]]])


def _inv_se2(a):
    return np.concatenate([-_r2(a[2]).T @ a[:2], [-a[2]]])


def _compose_se3(a, b):
    Ra, Rb = _rot(a[3:7]), _rot(b[3:7])
    q = _quat(Ra @ Rb, like=_hamilton(a[3:7], b[3:7]))
    return np.concatenate([a[:3] + Ra @ b[:3], q])


def _inv_se3(a):
    R = _rot(a[3:7])
    q = _quat(R.T, like=np.array([-a[3], -a[4], -a[5], a[6]]))
    return np.concatenate([-R.T @ a[:3], q])


def _angle_diff(a, b):
    d = math.fmod(_scalar(a) - _scalar(b), 2 * math.pi)
    if d > math.pi:
        d -= 2 * math.pi
    elif d <= -math.pi:
        d += 2 * math.pi
    return d


_NUMERIC = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
    "neg": lambda a: -a,
    "sqrt": np.sqrt,
    "sin": np.sin,
    "cos": np.cos,
    "atan2": np.arctan2,
    "abs": np.abs,
    "exp": np.exp,
    "min": np.minimum,
    "max": np.maximum,
    "norm": lambda v: math.sqrt(float(v @ v)),
    "sqnorm": lambda v: float(v @ v),
    "dot": lambda a, b: float(a @ b),
    "cross": np.cross,
    "sum": np.sum,
    "concat": lambda *xs: np.concatenate(xs),
    "se2": lambda x, y, t: np.concatenate([x, y, t]),
    "compose_se2": _compose_se2,
    "inv_se2": _inv_se2,
    "pos_se2": lambda a: a[:2],
    "angle_se2": lambda a: a[2],
    "apply_se2": lambda a, p: a[:2] + _r2(a[2]) @ p,
    "angle_diff": _angle_diff,
    "se3": lambda p, q: np.concatenate([p, q]),
    "compose_se3": _compose_se3,
    "inv_se3": _inv_se3,
    "pos_se3": lambda a: a[:3],
    "rot_se3": lambda a: a[3:7],
    "apply_se3": lambda a, p: a[:3] + _rot(a[3:7]) @ p,
    "quat_mul": lambda a, b: _quat(_rot(a) @ _rot(b), like=_hamilton(a, b))
    * (np.linalg.norm(a) * np.linalg.norm(b)),
    "quat_conj": lambda q: np.array([-q[0], -q[1], -q[2], q[3]]),
    "quat_rotate": lambda q, v: _rot(q) @ v,
    "quat_dist": lambda a, b: 1.0 - float(a @ b) ** 2,
}

EVALUATED = frozenset(_NUMERIC) | {"pow", "waypoint", "axis_se3", "quat_axis", "fk", "sdist",
                                   "sdist2", "link"}


def constraint_rows(factor: FactorInstance, values: Mapping[VarInstance, Any],
                    geometry: Geometry | None = None) -> list[tuple[str, float]]:
    """[(kind, h)] for every row of the factor, kind "eq" (h = 0) or "ineq" (h <= 0)."""
    it = _Interp(factor, values, geometry)
    rows: list[tuple[str, float]] = []
    for c in factor.body:
        lhs, rhs = it.ev(c.lhs), it.ev(c.rhs)
        h = lhs - rhs if c.op != ">=" else rhs - lhs
        kind = "eq" if c.op == "==" else "ineq"
        rows += [(kind, float(v)) for v in np.atleast_1d(h)]
    return rows


def factor_violation(factor: FactorInstance, values: Mapping[VarInstance, Any],
                     geometry: Geometry | None = None) -> float:
    """Largest violation over the factor's rows (0 when satisfied, NaN counts as infinite)."""
    worst = 0.0
    for kind, h in constraint_rows(factor, values, geometry):
        v = abs(h) if kind == "eq" else max(h, 0.0)
        if math.isnan(v):
            return math.inf
        worst = max(worst, v)
    return worst


def max_violation(factors: Iterable[FactorInstance], values: Mapping[VarInstance, Any],
                  geometry: Geometry | None = None) -> tuple[float, FactorInstance | None]:
    """(largest violation over all factors, the factor attaining it; None if no factor)."""
    best, arg = 0.0, None
    for f in factors:
        v = factor_violation(f, values, geometry)
        if arg is None or v > best:
            best, arg = v, f
    return best, arg
