"""A second opinion on "this subgraph is infeasible" that shares no assembly code with the solver.

The solver decides a conflict with `GraphNLP` + `casadi_expr` lowering + ipopt (and confirms it
with the same machinery from more starts), so a bug in the assembly would confirm itself. Here
the factors' rows are evaluated by the tests' own tree walk (tests/nlp/evaluate_reference.py:
its own numeric kernels, nothing from gnppdsl.nlp) and the feasibility problem
    find x in the variables' bounds with every `==` row = 0 and every `<=` row <= 0
is handed to scipy from several random starts: least squares on the violations (trust-region
reflective, inside the bounds), then SLSQP near a feasible point; Jacobians by central differences
of the walk. If any start ends with every row within `tol`, the "conflict" has a feasible point
and is not a conflict.

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
    """All rows of the factors at a packed point (remembered for the last point), and their
    Jacobian by central differences factor by factor (a factor moves only its own variables:
    2 x its dimension evaluations of it, not of the whole graph)."""

    def __init__(self, factors, geometry):
        self.factors, self.geometry = list(factors), geometry
        self.vars = list(dict.fromkeys(v for f in self.factors for v in f.variables))
        self.offsets = np.cumsum([0] + [v.dim for v in self.vars])
        index = {v: i for i, v in enumerate(self.vars)}
        # per factor: its coordinates in the packed vector, its row kinds
        self.coords = [np.concatenate([np.arange(self.offsets[index[v]], self.offsets[index[v] + 1])
                                       for v in dict.fromkeys(f.variables)]) for f in self.factors]
        self._key, self._val = None, None
        z0 = np.zeros(self.n)
        self.kinds = [[k for k, _ in _reference_rows(f, self._local(f, z0), geometry)] for f in self.factors]
        self.is_eq = np.array([k == "eq" for ks in self.kinds for k in ks], bool)

    @property
    def n(self) -> int:
        return int(self.offsets[-1])

    def _local(self, f, z):
        return {v: z[self.offsets[i]:self.offsets[i + 1]] for i, v in enumerate(self.vars) if v in f.variables}

    def _factor_rows(self, f, z) -> np.ndarray:
        return np.array([h for _, h in _reference_rows(f, self._local(f, z), self.geometry)], float)

    def _all(self, z) -> np.ndarray:
        key = z.tobytes()
        if key != self._key:
            self._key = key
            self._val = np.concatenate([self._factor_rows(f, z) for f in self.factors]) if self.factors \
                else np.zeros(0)
        return self._val

    def __call__(self, z) -> tuple[np.ndarray, np.ndarray]:
        r = self._all(z)
        return r[self.is_eq], r[~self.is_eq]

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

    def jacobian(self, z, h: float = 1e-7) -> np.ndarray:
        """d rows / d z (all rows, in `_all`'s order)."""
        J = np.zeros((self.is_eq.size, z.size))
        row = 0
        for f, cols, kinds in zip(self.factors, self.coords, self.kinds):
            m = len(kinds)
            for k in cols:
                zp, zm = z.copy(), z.copy()
                zp[k] += h
                zm[k] -= h
                J[row:row + m, k] = (self._factor_rows(f, zp) - self._factor_rows(f, zm)) / (2 * h)
            row += m
        return J

    def jacobians(self, z) -> tuple[np.ndarray, np.ndarray]:
        J = self.jacobian(z)
        return J[self.is_eq], J[~self.is_eq]


def scipy_feasible(factors, geometry, starts: int = 6, seed: int = 0, tol: float = 1e-6,
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

    n_eq, n_in = int(rows.is_eq.sum()), int((~rows.is_eq).sum())
    cons = []
    if n_eq:
        cons.append({"type": "eq", "fun": lambda z: rows(z)[0], "jac": lambda z: jacobians(z)[0]})
    if n_in:                                                   # scipy: fun(z) >= 0
        cons.append({"type": "ineq", "fun": lambda z: -rows(z)[1], "jac": lambda z: -jacobians(z)[1]})
    best = np.inf
    for k in range(starts):
        z0 = rng.uniform(np.where(np.isfinite(lo), lo, -UNBOUNDED), np.where(np.isfinite(hi), hi, UNBOUNDED))
        # phase 1: least squares on the violations; near a feasible point, SLSQP polishes it
        z = _phase1(rows, z0, lo, hi)
        v = rows.violation(z)
        if tol < v < 1e-3:
            with np.errstate(all="ignore"):
                res = minimize(lambda y: 0.5e-6 * float(np.dot(y - z, y - z)), z,
                               jac=lambda y: 1e-6 * (y - z), method="SLSQP", bounds=bounds,
                               constraints=cons, options={"maxiter": maxiter, "ftol": 1e-14})
            v = min(v, rows.violation(np.clip(res.x, lo, hi)))
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

    def jac(z):
        je, ji = rows.jacobians(z)
        active = rows(z)[1] > 0
        return np.vstack([je, ji * active[:, None]])
    z0 = np.clip(z0, np.where(np.isfinite(lo), lo + 1e-9, -np.inf), np.where(np.isfinite(hi), hi - 1e-9, np.inf))
    with np.errstate(all="ignore"):
        sol = least_squares(resid, z0, jac=jac, bounds=(lo, hi), method="trf", xtol=1e-15, ftol=1e-15,
                            gtol=1e-15, max_nfev=100)
    return sol.x
