"""Infeasibility certificates: a subgraph decided at a graph's convergence point, without a solve.

Why: when the elastic NLP of a graph P ends infeasible at x*, its multipliers say which factors
take part in the contradiction (`FeasibilityResult.active`): the support, the convergence
heuristic's first candidate (Sec. VI-C). The candidate g is a subgraph of P, so its own
elastic NLP has the same rows, the same slacks and the same pull at x*; only the rows of P
outside g are gone. If their multipliers were zero there, (x*, the multipliers of g's rows) is
a KKT point of g's NLP, and if that NLP curves upwards in every direction its active rows
allow (second-order condition), x* is a strict local minimum of it with the same violation: the
verdict a solve of g from x* would return at once. Without this, each conflict cost its plan's
NLP plus one NLP on the support that only repeated what the plan's NLP had shown (planar p5:
both direct plans, 2 + 2 NLPs before the solution).

What is checked, for the elastic NLP of g at z* = (x*, s = the rows' violations) with g's
share of P's multipliers:
- stationarity in x: |grad f + J' lam_g + lam_x| <= RESIDUAL (P's multipliers of the rows
  outside g, which touch g's variables, must have been ~0: after the polish of an infeasible
  verdict, with the pull 1e-4 weaker, they are ~1e-8 on p5; before it, the pull's forces
  crossing g's boundary are ~4e-3 and nothing is certified);
- the slacks: a violated row has multiplier 1 (its weight), a satisfied one at most 1;
- second order: the Hessian of g's Lagrangian reduced to the null space of its strongly active
  rows and bounds is positive definite (weakly active rows are left out of the active set, a
  larger space: conservative). A saddle is refused: a factor pinned by a row of P with a zero
  multiplier (x = 0 from `x == 0`, and `x^2 >= 1` violated there) leaves g = {x^2 >= 1} at a
  stationary point that is a maximum of its violation, where g is feasible;
- the Newton step of the reduced quadratic model from the residual left is short (STEP) and
  changes the objective by less than DECREASE of the slack: a KKT point of g lies right there,
  with the same violation.
Local evidence, as every verdict of the local solver is: the loop confirms a certified
conflict with the random restarts it would give a solved one (`gnppdsl.solve.loop`).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from gnppdsl.nlp.feasibility import FeasibilityResult, FeasibilitySolver, elastic_point, g_rows_of
from gnppdsl.nlp.graph import GraphNLP

RESIDUAL = 1e-6        # max |stationarity residual| in x and on the slacks (measured ~5e-9 on p5)
ACTIVE = 1e-6          # |multiplier| above which a row or bound counts as strongly active
STEP = 5e-2            # max |Newton step| of the reduced model (its region of trust)
DECREASE = 1e-3        # max predicted change of the objective, as a share of the slacks' sum
PUSH = 1e-4            # a row outside the subgraph with a larger multiplier on its variables: refused
                       # before any evaluation (its push alone would leave a residual above RESIDUAL)
MAX_DIM = 1500         # dense reduced Hessian: larger NLPs are not certified (solved instead)


def certify_infeasible(solver: FeasibilitySolver, graph: GraphNLP, point: FeasibilityResult,
                       within: GraphNLP) -> FeasibilityResult | None:
    """The infeasible verdict on `graph` at the convergence point of `point`, the infeasible
    solve of `within` (a graph containing `graph`), or None when that point does not certify
    it (see the module docstring). Evaluated with `within`'s assembled NLP (cached by the
    solver): g's NLP is its restriction to g's coordinates (variables, slacks of g's rows)
    with the multipliers of the other rows set to zero, so g itself is never assembled. The
    verdict has `point`'s values, violations and multipliers restricted to `graph`, no
    iterations and no ipopt run."""
    duals = point.duals
    if point.feasible or duals is None or graph.n_factors == 0:
        return None
    refs = list(graph.factor_refs)
    mine = set(refs)
    if any(r not in duals.rows or r not in point.violations for r in refs) \
            or any(v not in point.values or v not in duals.bounds for v in within.variables):
        return None
    tol = solver.options.tolerance
    per = {r: point.violations[r] for r in refs}
    worst = max(per.values())
    if not worst > tol:
        return None                       # nothing of the contradiction is in graph
    for v in graph.variables:             # a row outside graph pushing on its variables: the
        for f in within.graph.neighbors(v):   # stationarity residual would be about that push
            if f not in mine and f in duals.rows and np.abs(duals.rows[f]).max(initial=0.0) > PUSH:
                return None
    # the exact Hessian: with the forward-kinematics rows linearised (kinematic_curvature false,
    # the first pass of auto) the second-order test below would be about another model, and a
    # certified verdict becomes a conflict
    a = solver.exact_assembly(within)
    n, n_in, n_eq = a.n_x, a.n_ineq, a.n_eq
    x, x0, lam_x = (_stacked(d, a.variables) for d in (point.values, duals.start, duals.bounds))
    z = elastic_point(a, x)
    # g's coordinates and rows inside within's NLP
    g_row = g_rows_of(a)
    lam_g = np.zeros(a.lbg.size)
    rows, slacks = [], []
    for r, i0, i1 in a.factor_rows:
        if r not in mine:
            continue
        if duals.rows[r].size != i1 - i0:
            return None
        lam_g[g_row[i0:i1]] = duals.rows[r]
        rows += g_row[i0:i1].tolist()
        for i in range(i0, i1):
            j = g_row[i]
            slacks += [n + j] if j < n_in else [n + j, n + j + n_eq]
    cols, q = [], n_in + n_eq
    own = set(graph.variables)
    for v, off in zip(a.variables, a.offsets):
        k = len(duals.quats.get(v, ()))
        if v in own:
            cols += range(off, off + v.dim)
            lam_g[q:q + k] = duals.quats[v]
            rows += range(q, q + k)
        q += k
    if q != a.lbg.size:
        return None
    coords = np.array(cols + sorted(slacks), dtype=np.int64)
    if coords.size > MAX_DIM:
        return None
    p = np.concatenate([x0, a.params, [duals.rho]])
    try:
        grad_f = np.asarray(a.solver.get_function("nlp_grad_f")(z, p)[1]).reshape(-1)
        jac = ca.DM(a.solver.get_function("nlp_jac_g")(z, p)[1]).full()
        hess = ca.DM(a.solver.get_function("nlp_hess_l")(z, p, 1.0, lam_g)).full()
    except Exception:                     # derivatives not available as functions: solve instead
        return None
    stat = grad_f + jac.T @ lam_g
    lam_z = np.concatenate([lam_x, np.zeros(z.size - n)])
    n_x = len(cols)
    r_x = stat[cols] + lam_z[cols]
    r_s = stat[coords[n_x:]]              # = -(the slacks' bound multipliers)
    s = z[coords[n_x:]]
    zero = s <= 1e-2 * tol
    if not (np.all(np.isfinite(stat[coords])) and np.abs(r_x).max(initial=0.0) <= RESIDUAL
            and np.abs(r_s[~zero]).max(initial=0.0) <= RESIDUAL and r_s[zero].min(initial=0.0) >= -RESIDUAL):
        return None
    # strongly active set (in g's coordinates): every equality row (elastic rows and unit
    # quaternions), the inequality rows with a multiplier, the bounds that hold a multiplier
    active_rows = [i for i in rows if i >= n_in or lam_g[i] > ACTIVE]
    lam_z[coords[n_x:]] = -r_s
    zc, lam_c = z[coords], lam_z[coords]
    at_bound = (zc <= a.lbx[coords] + 1e-9) | (zc >= a.ubx[coords] - 1e-9)
    fixed = np.flatnonzero(at_bound & (np.abs(lam_c) > ACTIVE))
    nz = coords.size
    active = np.vstack([jac[np.ix_(active_rows, coords)], np.eye(nz)[fixed]]) \
        if active_rows or fixed.size else np.zeros((0, nz))
    if active.shape[0]:
        _, sv, vt = np.linalg.svd(active)
        rank = int(np.sum(sv > 1e-9 * max(1.0, sv.max(initial=0.0))))
        null = vt[rank:].T
    else:
        null = np.eye(nz)
    hess = hess + hess.T - np.diag(np.diag(hess))          # ipopt's upper triangle
    residual = np.concatenate([r_x, np.zeros(nz - n_x)])
    if null.shape[1]:
        reduced = null.T @ hess[np.ix_(coords, coords)] @ null
        eig = np.linalg.eigvalsh(0.5 * (reduced + reduced.T))
        if not eig.min() > 1e-3 * duals.rho:
            return None                   # a saddle or a flat direction: no strict minimum
        gr = null.T @ residual
        step = np.linalg.solve(reduced, gr)
        if np.abs(null @ step).max(initial=0.0) > STEP or 0.5 * abs(gr @ step) > DECREASE * s.sum():
            return None
    activity = {r: float(np.abs(duals.rows[r]).max()) if duals.rows[r].size else 0.0 for r in refs}
    values = {v: point.values[v] for v in graph.variables}
    restricted = type(duals)({r: duals.rows[r] for r in refs},
                             {v: duals.quats[v] for v in graph.variables if v in duals.quats},
                             {v: duals.bounds[v] for v in graph.variables},
                             {v: duals.start[v] for v in graph.variables}, duals.rho)
    return FeasibilityResult(False, values, per, worst, float(s.sum()), 0.0, 0,
                             "certified at a convergence point of a graph containing it", 0,
                             activity, restricted)


def _stacked(per_variable: dict, variables: list) -> np.ndarray:
    """The values of `variables` in one vector, in the assembled NLP's order."""
    if not variables:
        return np.zeros(0)
    return np.concatenate([np.asarray(per_variable[v], float).reshape(-1) for v in variables])
