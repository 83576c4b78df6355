"""The reference the compiled evaluator (`gnppdsl.nlp.evaluate`) is checked against: a direct
walk of the body tree for every row, no compilation, no sharing of nodes, no memo -- and its own
numeric kernels, written here from the builtins' definitions (docs/reference.md), importing
nothing from `gnppdsl.nlp.evaluate` (issue 25: a reference that calls the checked code's kernels
repeats its bugs). Rotations use the closed-form quaternion-to-matrix map and the Hamilton
product (the evaluator uses Rodrigues' formula and matrix products), so the two agree to
rounding, not bit for bit: the tests compare within a relative 1e-10. The geometry's numeric
methods (fk, sdist) are the geometry layer's, checked against pinocchio and coal in tests/geometry.
"""
from __future__ import annotations

import math
from typing import Any, Mapping

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Call, Index, Num, Slot, Vec
from gnppdsl.nlp.geometry_protocol import Body, Geometry


class ReferenceError_(ValueError):
    """What the reference cannot evaluate (the tests expect the evaluator to refuse it too)."""


def _unit(q: np.ndarray) -> np.ndarray:
    n = float(np.linalg.norm(q))
    return np.asarray(q, float) / n if n > 0 else np.array([0.0, 0.0, 0.0, 1.0])


def rotation(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of the quaternion [x, y, z, w] after normalisation (closed form)."""
    x, y, z, w = _unit(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """a * b for quaternions stored [x, y, z, w]."""
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return np.array([aw * bx + ax * bw + ay * bz - az * by,
                     aw * by - ax * bz + ay * bw + az * bx,
                     aw * bz + ax * by - ay * bx + az * bw,
                     aw * bw - ax * bx - ay * by - az * bz])


def _conj(q):
    return np.array([-q[0], -q[1], -q[2], q[3]])


def _r2(t: float) -> np.ndarray:
    c, s = math.cos(t), math.sin(t)
    return np.array([[c, -s], [s, c]])


def _scalar(v) -> float:
    v = np.asarray(v, float).reshape(-1)
    if v.size != 1:
        raise ReferenceError_(f"expected a scalar, got length {v.size}")
    return float(v[0])


def _wrap(d: float) -> float:
    """An angle in (-pi, pi]."""
    d = d - 2 * math.pi * math.floor(d / (2 * math.pi))       # [0, 2 pi)
    return d - 2 * math.pi if d > math.pi else d


KERNELS = {
    "add": lambda a, b: a + b, "sub": lambda a, b: a - b, "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b, "neg": lambda a: -a,
    "sqrt": np.sqrt, "sin": np.sin, "cos": np.cos, "atan2": np.arctan2, "abs": np.abs, "exp": np.exp,
    "min": np.minimum, "max": np.maximum,
    "norm": lambda v: math.sqrt(float(np.sum(v * v))),
    "sqnorm": lambda v: float(np.sum(v * v)),
    "dot": lambda a, b: float(np.sum(a * b)),
    "cross": np.cross, "sum": np.sum,
    "concat": lambda *xs: np.concatenate(xs),
    "se2": lambda x, y, t: np.concatenate([x, y, t]),
    "compose_se2": lambda a, b: np.array([a[0] + math.cos(a[2]) * b[0] - math.sin(a[2]) * b[1],
                                          a[1] + math.sin(a[2]) * b[0] + math.cos(a[2]) * b[1], a[2] + b[2]]),
    "inv_se2": lambda a: np.array([-math.cos(a[2]) * a[0] - math.sin(a[2]) * a[1],
                                   math.sin(a[2]) * a[0] - math.cos(a[2]) * a[1], -a[2]]),
    "pos_se2": lambda a: a[:2], "angle_se2": lambda a: a[2],
    "apply_se2": lambda a, p: a[:2] + _r2(a[2]) @ p,
    "angle_diff": lambda a, b: _wrap(_scalar(a) - _scalar(b)),
    "se3": lambda p, q: np.concatenate([p, q]),
    "compose_se3": lambda a, b: np.concatenate([a[:3] + rotation(a[3:7]) @ b[:3],
                                                hamilton(_unit(a[3:7]), _unit(b[3:7]))]),
    "inv_se3": lambda a: np.concatenate([-(rotation(a[3:7]).T @ a[:3]), _conj(_unit(a[3:7]))]),
    "pos_se3": lambda a: a[:3], "rot_se3": lambda a: a[3:7],
    "apply_se3": lambda a, p: a[:3] + rotation(a[3:7]) @ p,
    "quat_mul": hamilton,
    "quat_conj": _conj,
    "quat_rotate": lambda q, v: rotation(q) @ v,
    "quat_dist": lambda a, b: 1.0 - float(np.sum(a * b)) ** 2,
}


def _const(e: Any) -> float:
    if isinstance(e, Num):
        return float(e.value)
    if isinstance(e, Call) and e.fn in ("add", "sub", "mul", "div", "neg"):
        return float(KERNELS[e.fn](*(_const(a) for a in e.args)))
    raise ReferenceError_(f"expected a constant, got {e!r}")


class _Interp:
    def __init__(self, factor: FactorInstance, values: Mapping[VarInstance, Any],
                 geometry: Geometry | None):
        self.f, self.geometry = factor, geometry
        try:
            self.x = [np.asarray(values[v], float).reshape(-1) for v in factor.variables]
        except KeyError as err:
            raise ReferenceError_(f"no value for variable {err.args[0]}") from None

    def waypoint(self, e: Any, k: int) -> np.ndarray:
        if not isinstance(e, Slot) or not self.f.variables[e.index].waypoints:
            raise ReferenceError_("waypoint of a non-trajectory")
        v = self.f.variables[e.index]
        return self.x[e.index].reshape(v.waypoints, v.point_dim)[k]

    def body(self, e: Any) -> Body:
        b = Body.of(e)
        if b is None:
            raise ReferenceError_(f"not a body: {e!r}")
        return b

    def ev(self, e: Any) -> np.ndarray:
        if isinstance(e, Num):
            return np.array([float(e.value)])
        if isinstance(e, Slot):
            return self.x[e.index]
        if isinstance(e, Vec):
            return np.concatenate([self.ev(i) for i in e.items])
        if isinstance(e, Index):
            i = int(_const(e.index))
            if isinstance(e.base, Slot) and self.f.variables[e.base.index].waypoints and e.stop is None:
                return self.waypoint(e.base, i)
            b = self.ev(e.base)
            return b[[i]] if e.stop is None else b[i:int(_const(e.stop))]
        if isinstance(e, Call):
            return np.atleast_1d(np.asarray(self.call(e), float)).reshape(-1)
        raise ReferenceError_(f"cannot evaluate {e!r}")

    def call(self, e: Call):
        fn, A = e.fn, e.args
        if fn == "pow":
            return self.ev(A[0]) ** _const(A[1])
        if fn == "waypoint":
            return self.waypoint(A[0], int(_const(A[1])))
        if fn == "axis_se3":
            return rotation(self.ev(A[0])[3:7])[:, int(_const(A[1]))]
        if fn == "quat_axis":
            return rotation(self.ev(A[0]))[:, int(_const(A[1]))]
        g = self.geometry
        if fn == "fk":
            return g.fk_numeric(A[0].name, self.ev(A[1]), A[2].value, self.ev(A[3]))
        if fn == "sdist":
            return g.sdist_numeric(self.body(A[0]), self.ev(A[1]), self.body(A[2]), self.ev(A[3]))
        if fn == "sdist2":
            return g.sdist2_numeric(self.body(A[0]), self.ev(A[1]), self.body(A[2]), self.ev(A[3]))
        if fn not in KERNELS:
            raise ReferenceError_(f"unknown builtin {fn}")
        return KERNELS[fn](*[self.ev(a) for a in A])


def _reference_rows(factor: FactorInstance, values: Mapping[VarInstance, Any],
                    geometry: Geometry | None = None) -> list[tuple[str, float]]:
    """`constraint_rows` by walking the body tree for every row."""
    it = _Interp(factor, values, geometry)
    rows: list[tuple[str, float]] = []
    for c in factor.body:
        lhs, rhs = it.ev(c.lhs), it.ev(c.rhs)
        h = lhs - rhs if c.op != ">=" else rhs - lhs
        kind = "eq" if c.op == "==" else "ineq"
        rows += [(kind, float(v)) for v in np.atleast_1d(h)]
    return rows
