"""The reference the compiled evaluator (`gnppdsl.nlp.evaluate`) must reproduce bit for bit:
a direct walk of the body tree for every row, no compilation, no sharing of nodes, calling the
same numeric kernels (`_NUMERIC`, `_rot`, the geometry's numeric methods). A test oracle only,
so the product module carries one implementation."""
from __future__ import annotations

from typing import Any, Mapping

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Call, Index, Num, Slot, Vec
from gnppdsl.nlp.evaluate import _NUMERIC, EvaluationError, _const, _rot
from gnppdsl.nlp.geometry_protocol import Body, Geometry


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
        b = Body.of(e)
        if b is None:
            raise EvaluationError(f"not a body: {e!r}")
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
