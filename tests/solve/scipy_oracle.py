"""A second opinion on "this subgraph is infeasible" that shares no assembly code with the solver.

The solver decides a conflict with `GraphNLP` + `casadi_expr` lowering + ipopt (and confirms it
with the same machinery from more starts), so a bug in the assembly would confirm itself. Here
the factors' rows are evaluated by the tests' own tree walk (tests/nlp/evaluate_reference.py:
its own numeric kernels, nothing from gnppdsl.nlp) and the feasibility problem
    find x in the variables' bounds with every `==` row = 0 and every `<=` row <= 0
is handed to scipy's SLSQP (finite-difference Jacobians) from many random starts. If any start
ends with every row within `tol`, the "conflict" has a feasible point and is not a conflict.

This cannot prove infeasibility (no local method can); it is an independent search for a
counterexample, from starts that share nothing with the solver's (its own random generator,
uniform in the variables' boxes).
"""
from __future__ import annotations

import sys
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import least_squares, minimize

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "nlp"))
from evaluate_reference import _reference_rows  # noqa: E402

UNBOUNDED = 2.0       # half-width of the start box of an unbounded coordinate (scenes are ~1 m)


@dataclass
class ScipyVerdict:
    feasible: bool
    best_violation: float        # smallest max-row violation reached over the starts
    starts: int


class _Rows:
    """All rows of the factors at a packed point, remembered for the last point."""

    def __init__(self, factors, geometry):
        self.factors, self.geometry = list(factors), geometry
        self.vars = list(dict.fromkeys(v for f in self.factors for v in f.variables))
        self.offsets = np.cumsum([0] + [v.dim for v in self.vars])
        self._key, self._val = None, None

    @property
    def n(self) -> int:
        return int(self.offsets[-1])

    def values(self, z):
        return {v: z[self.offsets[i]:self.offsets[i + 1]] for i, v in enumerate(self.vars)}

    def __call__(self, z) -> tuple[np.ndarray, np.ndarray]:
        key = z.tobytes()
        if key != self._key:
            vals = self.values(z)
            eq, ineq = [], []
            for f in self.factors:
                for kind, h in _reference_rows(f, vals, self.geometry):
                    (eq if kind == "eq" else ineq).append(h)
            self._key, self._val = key, (np.array(eq, float), np.array(ineq, float))
        return self._val

    def violation(self, z) -> float:
        eq, ineq = self(z)
        parts = [np.abs(eq), np.maximum(ineq, 0.0)]
        v = max((float(p.max()) for p in parts if p.size), default=0.0)
        return v if np.isfinite(v) else np.inf

    def bounds(self) -> list[tuple[float | None, float | None]]:
        out = []
        for v in self.vars:
            lo = np.resize(np.asarray(v.lower, float), v.dim) if v.lower is not None else [None] * v.dim
            hi = np.resize(np.asarray(v.upper, float), v.dim) if v.upper is not None else [None] * v.dim
            out += [(None if a is None or not np.isfinite(a) else float(a),
                     None if b is None or not np.isfinite(b) else float(b)) for a, b in zip(lo, hi)]
        return out


    def jacobians(self, z, h: float = 1e-7) -> tuple[np.ndarray, np.ndarray]:
        """Central differences of every row, both kinds from one pass over the coordinates."""
        eq0, in0 = self(z)
        je, ji = np.zeros((eq0.size, z.size)), np.zeros((in0.size, z.size))
        for k in range(z.size):
            zp, zm = z.copy(), z.copy()
            zp[k] += h
            zm[k] -= h
            (ep, ip), (em, im) = self(zp), self(zm)
            je[:, k], ji[:, k] = (ep - em) / (2 * h), (ip - im) / (2 * h)
        self(z)
        return je, ji


def scipy_feasible(factors, geometry, starts: int = 8, seed: int = 0, tol: float = 1e-6,
                   maxiter: int = 60) -> ScipyVerdict:
    """Search for a point satisfying every row of `factors` with SLSQP from `starts` starts."""
    rows = _Rows(factors, geometry)
    bounds = rows.bounds()
    lo = np.array([b[0] if b[0] is not None else -np.inf for b in bounds])
    hi = np.array([b[1] if b[1] is not None else np.inf for b in bounds])
    rng = np.random.default_rng(seed)
    jac = {}

    def jacobians(z):
        key = z.tobytes()
        if key not in jac:
            jac.clear()
            jac[key] = rows.jacobians(z)
        return jac[key]

    n_eq, n_in = (len(r) for r in rows(np.zeros(rows.n)))
    cons = []
    if n_eq:
        cons.append({"type": "eq", "fun": lambda z: rows(z)[0], "jac": lambda z: jacobians(z)[0]})
    if n_in:                                                   # scipy: fun(z) >= 0
        cons.append({"type": "ineq", "fun": lambda z: -rows(z)[1], "jac": lambda z: -jacobians(z)[1]})
    best = np.inf
    for k in range(starts):
        z0 = rng.uniform(np.where(np.isfinite(lo), lo, -UNBOUNDED), np.where(np.isfinite(hi), hi, UNBOUNDED))
        with np.errstate(all="ignore"):
            res = minimize(lambda z: 0.5e-6 * float(np.dot(z - z0, z - z0)), z0,
                           jac=lambda z: 1e-6 * (z - z0), method="SLSQP", bounds=bounds,
                           constraints=cons, options={"maxiter": maxiter, "ftol": 1e-14})
        z = np.clip(res.x, lo, hi)
        v = rows.violation(z)
        if v > tol:     # SLSQP stalled: phase 1 (least squares on the violations), then SLSQP again
            z = _phase1(rows, z0 if not np.isfinite(v) else z, lo, hi)
            with np.errstate(all="ignore"):
                res = minimize(lambda y: 0.5e-6 * float(np.dot(y - z, y - z)), z,
                               jac=lambda y: 1e-6 * (y - z), method="SLSQP", bounds=bounds,
                               constraints=cons, options={"maxiter": maxiter, "ftol": 1e-14})
            z2 = np.clip(res.x, lo, hi)
            v = min(rows.violation(z), rows.violation(z2))
        best = min(best, v)
        if v <= tol:
            return ScipyVerdict(True, v, k + 1)
    return ScipyVerdict(False, best, starts)


def _phase1(rows: _Rows, z0, lo, hi):
    """Least squares on the violations (eq rows, and the positive part of the `<=` rows):
    scipy's trust-region reflective method, its own finite differences."""
    def resid(z):
        eq, ineq = rows(z)
        r = np.concatenate([eq, np.maximum(ineq, 0.0)])
        return np.where(np.isfinite(r), r, 1e3)
    z0 = np.clip(z0, np.where(np.isfinite(lo), lo + 1e-9, -np.inf), np.where(np.isfinite(hi), hi - 1e-9, np.inf))
    with np.errstate(all="ignore"):
        sol = least_squares(resid, z0, bounds=(lo, hi), method="trf", xtol=1e-15, ftol=1e-15, gtol=1e-15,
                            max_nfev=200 * max(1, z0.size))
    return sol.x
