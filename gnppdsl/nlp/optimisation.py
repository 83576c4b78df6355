"""The optimisation phase of optimal TAMP: a feasible plan's graph-NLP with its objective.

Paper 000 decides feasibility; paper 002 (R-LGP) asks for the cheapest motion of the plan it
commits to. Once the loop holds a feasible solution x* of the plan's graph-NLP G, this phase
solves

    min_x  sum_k c_k(x)   s.t.  every row of G's factors, the variables' bounds and unit
                                quaternions,

from x*, where the c_k are the `minimize` terms of the plan's rule instances
(`GraphNLPFactory.objectives`). The caller keeps the result only when an evaluation that shares
no code with this NLP (the numpy evaluator) finds it feasible within the solve's tolerance and
cheaper than x*; otherwise x* stands, so optimising never costs feasibility.

Why a second NLP and not the objective inside the elastic one of `feasibility`: there the
slacks are the objective, and a cost beside them trades violation for cost.

How it is evaluated: like the feasibility NLPs (`_assemble`): g from the bodies' evaluation
twins (one batched native distance call per template and evaluation), ipopt's `grad_f`, `jac_g`
and `hess_lag` from `BodyCompiler`'s per-template SX derivatives, the terms compiled as bodies
whose rows are summed. Why not casadi's AD of an MX graph of the template Functions (what this
module did first): every distance was then a Python callback per pair and waypoint, ~0.1 s per
limited-memory iteration on sort2 and 0.23 s per exact one, against ~14 and ~20 ms now, so the
exact Hessian, which needs far fewer iterations, is the first choice (`solve/optimal.py`).
When to stop: `ObjectiveMonitor` (docs/design.md, "Objectives and the optimisation phase").
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Mapping, NamedTuple, Sequence

import casadi as ca
import numpy as np

from gnppdsl import interrupt
from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Constraint, Num, Objective
from gnppdsl.nlp import shape_cache
from gnppdsl.nlp.body_compiler import BodyCompiler, CompiledBody, mapped_inputs, scatter_parts
from gnppdsl.nlp.geometry_protocol import DISTANCE_PRIMITIVES
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.monitor import ObjectiveMonitor


def term_rows(term: FactorInstance) -> FactorInstance:
    """An objective instance as a factor whose rows are its terms (h_k = c_k, "eq" kind), so
    the body compiler and the numpy evaluator read it like any factor. Never a constraint: only
    this module and `objective_value` use it."""
    rows = tuple(Constraint(st.expr, "==", Num(0.0), span=st.span) for st in term.body
                 if isinstance(st, Objective))
    return replace(term, body=rows)


def objective_value(terms: Sequence[FactorInstance], values: Mapping[VarInstance, object],
                    geometry=None) -> float:
    """The sum of the terms at `values`, by the numpy evaluator (independent of casadi)."""
    from gnppdsl.nlp.evaluate import constraint_rows

    total = 0.0
    for t in terms:
        for _, h in constraint_rows(term_rows(t), values, geometry):
            total += float(np.sum(h))
    return total


@dataclass
class Optimised:
    values: dict[VarInstance, np.ndarray]     # the optimiser's point (not yet accepted)
    status: str                               # ipopt's return status
    iterations: int
    seconds: float


def _bounds(v: VarInstance, bound, default: float) -> np.ndarray:
    if bound is None:
        return np.full(v.dim, default)
    b = np.asarray(bound, float).reshape(-1)
    if b.size == v.point_dim and v.waypoints:
        b = np.tile(b, v.waypoints)
    return b if b.size == v.dim else np.full(v.dim, default)


class _Group(NamedTuple):
    """The k instances of one compiled body in the assembly: one mapped call per group."""

    cb: CompiledBody
    k: int
    stacked: list          # per instance, the x indices of its stacked slots
    p0: int                # its parameters' first entry in P (column-major, n_params x k)
    r0: int                # its first row in g (constraints) or in the stacked terms


def _groups(items: Sequence[tuple[FactorInstance, CompiledBody, np.ndarray]], index: dict,
            offsets: np.ndarray) -> tuple[list[_Group], np.ndarray]:
    """The mapped-call layout of `items` (instances of a template grouped in order of first
    appearance, as `elastic_derivatives.mapped_rows`) and their parameter vector."""
    members: dict[int, list] = {}
    for item in items:
        members.setdefault(id(item[1]), []).append(item)
    params, _ = shape_cache.instance_numbers([(None, cb, p) for _, cb, p in items], grouped=True)
    layout, p0, r0 = [], 0, 0
    for ms in members.values():
        cb, k = ms[0][1], len(ms)
        stacked = [[i for v in f.variables for i in range(int(offsets[index[v]]), int(offsets[index[v]]) + v.dim)]
                   for f, _, _ in ms]
        layout.append(_Group(cb, k, stacked, p0, r0))
        p0 += cb.n_params * k
        r0 += cb.n_rows * k
    return layout, params


def _mapped(fn: ca.Function, k: int) -> ca.Function:
    return fn if k == 1 else fn.map(k, "serial")


def _values(layout: list[_Group], x: ca.MX, P: ca.MX) -> ca.MX:
    """The stacked rows of every group at x: the bodies' evaluation twins (native distance
    queries, `CompiledBody.evaluate`) where they have one; never differentiated by casadi."""
    out = []
    for gr in layout:
        slots, Pg = mapped_inputs(x, P, gr.cb, gr.k, gr.stacked, gr.p0)
        body = gr.cb.evaluate if gr.cb.evaluate is not None else gr.cb.function
        out.append(ca.vec(_mapped(body, gr.k)(*slots, Pg)))
    return ca.vertcat(*out) if out else ca.MX(0, 1)


def _jacobian_entries(compiler: BodyCompiler, layout: list[_Group], x: ca.MX, P: ca.MX, row_of
                      ) -> tuple[list, list]:
    """(parts, entries) of the groups' Jacobians (per-template SX Jacobians, one mapped call
    per group): entry (row, x column, index into the stacked parts), `row_of(r0, t, rr)` the
    row of row rr of instance t of the group starting at r0."""
    parts, entries, base = [], [], 0
    for gr in layout:
        jf = compiler.jacobian(gr.cb)
        sp = jf.sparsity_out(0)
        if sp.nnz() == 0:
            continue
        slots, Pg = mapped_inputs(x, P, gr.cb, gr.k, gr.stacked, gr.p0)
        parts.append(_mapped(jf, gr.k)(*slots, Pg).nz[:])
        rr, cc = (np.asarray(v, dtype=np.int64) for v in sp.get_triplet())
        nnz = sp.nnz()
        t = np.arange(gr.k, dtype=np.int64)[:, None]
        entries.append(np.stack([np.broadcast_to(row_of(gr, t, rr[None, :]), (gr.k, nnz)),
                                 np.asarray(gr.stacked, dtype=np.int64)[:, cc],
                                 base + t * nnz + np.arange(nnz)[None, :]], axis=-1).reshape(-1, 3))
        base += gr.k * nnz
    return parts, entries


def _hessian_entries(compiler: BodyCompiler, layout: list[_Group], x: ca.MX, P: ca.MX, lam: ca.MX,
                     skip=lambda cb: False, base: int = 0) -> tuple[list, list]:
    """(parts, entries) of the upper triangle of sum_rows lam_row * d^2 row / dx^2 over the
    groups (per-template SX Hessians, `BodyCompiler.hessian`); `lam` holds the groups' rows in
    layout order; groups with `skip(cb)` are left out (linearised)."""
    parts, entries = [], []
    for gr in layout:
        if skip(gr.cb):
            continue
        hf = compiler.hessian(gr.cb)
        sp = hf.sparsity_out(0)
        if sp.nnz() == 0:
            continue
        slots, Pg = mapped_inputs(x, P, gr.cb, gr.k, gr.stacked, gr.p0)
        Lg = ca.reshape(lam[gr.r0:gr.r0 + gr.cb.n_rows * gr.k], gr.cb.n_rows, gr.k)
        parts.append(_mapped(hf, gr.k)(*slots, Pg, Lg).nz[:])
        rr, cc = (np.asarray(v, dtype=np.int64) for v in sp.get_triplet())
        nnz = sp.nnz()
        st = np.asarray(gr.stacked, dtype=np.int64)
        t = np.arange(gr.k, dtype=np.int64)[:, None]
        ab = np.stack([st[:, rr], st[:, cc], base + t * nnz + np.arange(nnz)[None, :]], axis=-1).reshape(-1, 3)
        entries.append(ab[ab[:, 0] <= ab[:, 1]])
        base += gr.k * nnz
    return parts, entries


def _scatter(n_rows: int, n_cols: int, entries: list, parts: list) -> ca.MX:
    if not parts:
        return ca.MX(n_rows, n_cols)
    return scatter_parts(n_rows, n_cols, np.concatenate([e.reshape(-1, 3) for e in entries]), parts)


def _assemble(graph: GraphNLP, terms: Sequence[FactorInstance], compiler: BodyCompiler,
              variables: list[VarInstance], index: dict, offsets: np.ndarray, hessian: str,
              curvature: str):
    """The optimisation NLP on the feasibility NLPs' fast path: g from the bodies' evaluation
    twins (one batched native distance call per template, no Python per query), and ipopt's
    `grad_f`, `jac_g`, `hess_lag` from the per-template SX derivatives of `BodyCompiler`, one
    mapped call per template, scattered by one sparse product each. Returns
    (nlp, options, P's value, lbg, ubg)."""
    n = int(offsets[-1])
    rows = [(f, *compiler.compile(f)) for _, f in graph.iter_factors()]
    cost = [(t, *compiler.compile(term_rows(t))) for t in terms]
    g_layout, g_par = _groups(rows, index, offsets)
    c_layout, c_par = _groups(cost, index, offsets)
    x = ca.MX.sym("x", n)
    P = ca.MX.sym("p", g_par.size + c_par.size)
    Pg, Pc = P[:g_par.size], P[g_par.size:]
    n_h = sum(gr.k * gr.cb.n_rows for gr in g_layout)
    kinds = np.array([kd == "eq" for gr in g_layout for _ in range(gr.k) for kd in gr.cb.kinds], dtype=bool)
    quat_idx = [int(offsets[index[v]]) + k * v.point_dim + 3 + m for v in variables if v.space == "SE3"
                for k in range(v.waypoints or 1) for m in range(4)]
    n_q = len(quat_idx) // 4
    n_g = n_h + n_q
    xq = ca.reshape(x[quat_idx], 4, n_q) if n_q else ca.MX(4, 0)
    g = ca.vertcat(_values(g_layout, x, Pg), ca.sum1(xq ** 2).T - 1 if n_q else ca.MX(0, 1))
    f = ca.sum1(_values(c_layout, x, Pc))
    # derivatives: graphs of their own, so casadi never differentiates g or f
    xs, ps = ca.MX.sym("x", n), ca.MX.sym("p", P.numel())
    Pgs, Pcs = ps[:g_par.size], ps[g_par.size:]
    parts, entries = _jacobian_entries(compiler, c_layout, xs, Pcs, lambda gr, t, rr: 0 * t + 0 * rr)
    grad = _scatter(1, n, entries, parts).T
    grad_f = ca.Function("nlp_grad_f", [xs, ps], [ca.sum1(_values(c_layout, xs, Pcs)), ca.densify(grad)],
                         ["x", "p"], ["f", "grad_f_x"])
    parts, entries = _jacobian_entries(compiler, g_layout, xs, Pgs,
                                       lambda gr, t, rr: gr.r0 + t * gr.cb.n_rows + rr)
    base = sum(int(p.numel()) for p in parts)
    if quat_idx:
        parts.append(2 * xs[quat_idx])
        entries.append(np.array([(n_h + m // 4, a, base + m) for m, a in enumerate(quat_idx)], dtype=np.int64))
    jac_g = ca.Function("nlp_jac_g", [xs, ps], [ca.MX.zeros(n_g, 1), _scatter(n_g, n, entries, parts)],
                        ["x", "p"], ["g", "jac_g_x"])
    opts = {"grad_f": grad_f, "jac_g": jac_g}
    if hessian == "exact":
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", n_g)
        linear = curvature != "exact"
        dropped = {"exact": set(), "distance": set(DISTANCE_PRIMITIVES)}.get(curvature, DISTANCE_PRIMITIVES | {"fk"})
        skip = (lambda cb: bool(cb.primitives & dropped))
        parts, entries = _hessian_entries(compiler, g_layout, xs, Pgs, lam_g[:n_h], skip)
        base = sum(int(p.numel()) for p in parts)
        n_c = sum(gr.k * gr.cb.n_rows for gr in c_layout)
        cp, ce = _hessian_entries(compiler, c_layout, xs, Pcs, ca.repmat(lam_f, n_c, 1), base=base)
        parts += cp
        entries += ce
        base += sum(int(p.numel()) for p in cp)
        if quat_idx:
            lam_q = lam_g[n_h:]
            lam_q = ca.fmax(lam_q, 0) if linear else lam_q
            parts.append(2 * ca.repmat(lam_q.T, 4, 1)[:])
            entries.append(np.array([(a, a, base + m) for m, a in enumerate(quat_idx)], dtype=np.int64))
        opts["hess_lag"] = ca.Function("nlp_hess_l", [xs, ps, lam_f, lam_g], [_scatter(n, n, entries, parts)],
                                       ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
    lbg = np.concatenate([np.where(kinds, 0.0, -np.inf), np.zeros(n_q)])
    return {"x": x, "p": P, "f": f, "g": g}, opts, np.concatenate([g_par, c_par]), lbg, np.zeros(n_g)


# The stall test's least relative gain of the best feasible objective within `patience`
# iterations (`ObjectiveMonitor`). Why 1e-3 and not 1e-4: ipopt's exact-Hessian runs on the
# mobile domain reach within ~0.5 % of their final cost in 50-110 iterations, then creep by
# 1e-4..5e-4 per 10 iterations (18-30 ms each, the Lagrangian Hessian ~10 ms of it) up to the
# 300-iteration cap: sort_random instance 1 (R-LGP), the run before the active set's round,
# 0.16768 at iteration 101, 0.16678 at 300 (5.5 s CPU); with 1e-3 it stops at 110.
STALL_PROGRESS = 1e-3


def optimise(graph: GraphNLP, terms: Sequence[FactorInstance], start: Mapping[VarInstance, object],
             compiler: BodyCompiler, *, time_limit: float = 30.0, max_iter: int = 100,
             tolerance: float = 1e-8, hessian: str = "limited-memory",
             curvature: str = "exact", feasible_below: float = 0.0, patience: int = 0,
             progress: float = STALL_PROGRESS,
             ipopt: Mapping | None = None) -> Optimised | None:
    """Minimise the terms over G's feasible set from `start` (G's feasible solution, or a point
    near the set: the caller re-checks what is returned).
    `hessian="exact"`: ipopt's exact Hessian of the Lagrangian (the caller's second try when the
    quasi-Newton run stops at its iteration limit: a two-gripper planar problem, 13 factors, took
    100 limited-memory iterations to 0.340 and 19 exact ones to 0.319); `curvature`: "exact",
    "distance" (the rows querying signed distances enter that Hessian linearised, as with the
    feasibility NLPs' `distance_curvature` off) or "linear" (those and the forward-kinematics
    rows; sort4 seed 0 from its feasible point: "distance" 121 iterations, 4.6 s, to 0.170,
    "exact" 143, 6.5 s, to 0.148; "linear" made no progress in 300). `feasible_below` > 0: an
    `ObjectiveMonitor` keeps the best iterate whose rows hold within it (returned instead of
    ipopt's last one) and stops the run after `patience` iterations without a `progress`
    relative gain, or at `time_limit` CPU seconds.

    Returns None when there is nothing to optimise (no term whose variables are all in G)."""
    variables = list(graph.variables)
    index = {v: i for i, v in enumerate(variables)}
    terms = [t for t in terms if all(v in index for v in t.variables)]
    if not terms:
        return None
    t0 = time.process_time()
    offsets = np.cumsum([0] + [v.dim for v in variables])
    nlp, extra, params, lbg, ubg = _assemble(graph, terms, compiler, variables, index, offsets, hessian,
                                             curvature)
    lbx = np.concatenate([_bounds(v, v.lower, -np.inf) for v in variables])
    ubx = np.concatenate([_bounds(v, v.upper, np.inf) for v in variables])
    x0 = np.concatenate([np.asarray(start[v], float).reshape(-1) for v in variables])
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "error_on_fail": False,
            "ipopt.hessian_approximation": hessian, "ipopt.max_iter": int(max_iter),
            "ipopt.tol": float(tolerance), "ipopt.max_cpu_time": max(0.1, float(time_limit)),
            "ipopt.mu_init": 1e-4, "ipopt.warm_start_init_point": "yes",
            "calc_lam_p": False, "no_nlp_grad": True, **extra, **(ipopt or {})}
    monitor = None
    if feasible_below > 0:
        monitor = ObjectiveMonitor("optimise_monitor", int(offsets[-1]), lbg, ubg)
        monitor.reset(feasible_below, patience, progress, deadline=t0 + max(0.1, float(time_limit)))
        opts["iteration_callback"] = monitor
    solver = ca.nlpsol("optimise", "ipopt", nlp, opts)
    with interrupt.native():         # a signal stops the run (the monitor), raised after it
        sol = solver(x0=np.clip(x0, lbx, ubx), p=params, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)
    stats = solver.stats()
    xs = np.asarray(sol["x"]).reshape(-1)
    status = str(stats.get("return_status", ""))
    if monitor is not None and monitor.best_x is not None:
        g = np.asarray(sol["g"]).reshape(-1)
        worst = max(np.max(g - ubg, initial=0.0), np.max(lbg - g, initial=0.0))
        if not (worst <= feasible_below and float(sol["f"]) <= monitor.best):
            xs = monitor.best_x          # the best feasible iterate, not where ipopt stopped
        if monitor.stalled:
            status = "Objective_Stalled"
        elif monitor.timed_out:
            status = "Maximum_CpuTime_Exceeded"
    values = {v: xs[int(offsets[i]):int(offsets[i + 1])].copy() for i, v in enumerate(variables)}
    return Optimised(values, status, int(stats.get("iter_count", 0)), time.process_time() - t0)
