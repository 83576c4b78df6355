"""The elastic NLP's constraint rows as one mapped call per template Function, and ipopt's
`jac_g` and `hess_lag` assembled from the per-template derivatives (`BodyCompiler.jacobian`,
`BodyCompiler.hessian`) of those calls, scattered into place by one sparse product each.
Used by `gnppdsl.nlp.feasibility.FeasibilitySolver.assemble` for MX assemblies with ipopt's
exact-Hessian interface."""
from __future__ import annotations

from collections import OrderedDict

import casadi as ca
import numpy as np

from gnppdsl.nlp import shape_cache
from gnppdsl.nlp.body_compiler import BodyCompiler, mapped_inputs as _mapped_inputs, \
    scatter_parts as _scatter_parts
from gnppdsl.nlp.geometry_protocol import DISTANCE_PRIMITIVES
from gnppdsl.nlp.graph import GraphNLP


def mapped_rows(graph: GraphNLP, compiled: list, index: dict, offsets: list[int], n: int,
                fast: bool = False):
    """MX rows with one `Function.map` call per template Function: the k instances of a
    template become the k columns of one call, so casadi builds and evaluates derivatives
    per template, not per instance. Measured on the lab1 full graph (75 factors, 34
    Functions, 20-waypoint trajectories): nlpsol construction 17.8 s with one call node per
    factor; see `gnppdsl.nlp.feasibility`'s docstring for the mapped figure."""
    x = ca.MX.sym("x", n)
    groups: OrderedDict[int, list] = OrderedDict()
    for r, cb, p in compiled:
        groups.setdefault(id(cb), []).append((r, cb, p))
    params_arr, factor_rows = shape_cache.instance_numbers(compiled, grouped=True)
    P = ca.MX.sym("P", params_arr.size)
    rows, kinds, r0, p0 = [], [], 0, 0
    layout = []      # per group: (cb, k, stacked-slot variable indices per instance, p0, r0)
    for members in groups.values():
        cb = members[0][1]
        k = len(members)
        slots = []
        stacked = [[] for _ in members]
        for j, d in enumerate(cb.slot_dims):
            idx = []
            for t, (r, _, _) in enumerate(members):
                v = graph.factor(r).variables[j]
                o = offsets[index[v]]
                idx.extend(range(o, o + v.dim))
                stacked[t].extend(range(o, o + v.dim))
            slots.append(ca.reshape(x[idx], d, k))
        layout.append((cb, k, stacked, p0, r0))
        npar = cb.n_params
        if npar:
            Pg = ca.reshape(P[p0:p0 + npar * k], npar, k)       # columns: the instances
            p0 += npar * k
        else:
            Pg = ca.MX(0, k)
        body = cb.evaluate if fast and cb.evaluate is not None else cb.function
        fn = body if k == 1 else body.map(k, "serial")
        out = fn(*slots, Pg)
        rows.append(ca.vec(out))
        kinds += [kd == "eq" for kd in cb.kinds] * k
        r0 += k * cb.n_rows
    return x, P, params_arr, rows, kinds, factor_rows, layout


def jacobian_function(compiler: BodyCompiler, layout: list, n: int, n_z: int, n_par: int,
                      h_rows: np.ndarray, quat_idx: list[int], n_in: int, n_eq: int) -> ca.Function:
    """ipopt's `jac_g` ((z, p) -> (g, dg/dz)) from the per-template SX Jacobians, one mapped
    call per template, scattered by one sparse product (as `hessian_function`); the slack
    columns are the constants -1 / +1 of the elastic rows.

    The "g" output is a zero placeholder: casadi's ipopt interface asks `nlp_jac_g` for the
    Jacobian only (g comes from `nlp_g`), but an MX Function computes every output, and the
    real g here re-ran every distance callback (a quarter of all callback calls on lab1).
    Measured with casadi 3.8.2: identical iterates and solutions on lab1-lab3;
    `tests/nlp/test_nlp_jac_g_outputs.py` checks the solver still solves."""
    z = ca.MX.sym("x", n_z)
    pp = ca.MX.sym("p", n + n_par + 1)
    x, P = z[:n], pp[n:n + n_par]
    parts, entries, base = [], [], 0       # (g row, z column, index into parts)
    for cb, k, stacked, p0, r0 in layout:
        jf = compiler.jacobian(cb)
        sp = jf.sparsity_out(0)
        if sp.nnz() == 0:
            continue
        slots, Pg = _mapped_inputs(x, P, cb, k, stacked, p0)
        fn = jf if k == 1 else jf.map(k, "serial")
        parts.append(fn(*slots, Pg).nz[:])
        rr, cc = (np.asarray(v, dtype=np.int64) for v in sp.get_triplet())
        nnz = sp.nnz()
        t = np.arange(k, dtype=np.int64)[:, None]       # instances x entries, in that order
        entries.append(np.stack([h_rows[r0 + t * cb.n_rows + rr[None, :]],
                                 np.asarray(stacked, dtype=np.int64)[:, cc],
                                 base + t * nnz + np.arange(nnz)[None, :]], axis=-1).reshape(-1, 3))
        base += k * nnz
    chunks, entries = entries, []
    consts = []
    for i in range(n_in):
        entries.append((i, n + i, base + len(consts)))
        consts.append(-1.0)
    for e in range(n_eq):
        entries.append((n_in + e, n + n_in + e, base + len(consts)))
        consts.append(-1.0)
        entries.append((n_in + e, n + n_in + n_eq + e, base + len(consts)))
        consts.append(1.0)
    if consts:
        parts.append(ca.DM(consts))
        base += len(consts)
    if quat_idx:
        parts.append(2 * x[quat_idx])
        entries += [(n_in + n_eq + m // 4, a, base + m) for m, a in enumerate(quat_idx)]
        base += len(quat_idx)
    n_g = n_in + n_eq + len(quat_idx) // 4
    J = _scatter_parts(n_g, n_z, np.concatenate(
        [*chunks, np.array(entries, dtype=np.int64).reshape(-1, 3)]), parts)
    return ca.Function("nlp_jac_g", [z, pp], [ca.MX.zeros(n_g, 1), J], ["x", "p"], ["g", "jac_g_x"])


def hessian_function(compiler: BodyCompiler, layout: list, n: int, n_z: int, n_par: int,
                     h_rows: np.ndarray, quat_idx: list[int], n_g: int, distance_curvature: bool,
                     kinematic_exact: bool) -> ca.Function:
    """ipopt's `hess_lag` (upper triangle of the Lagrangian's Hessian in z = [x, slacks])
    assembled from the per-template SX Hessians (`BodyCompiler.hessian`), one mapped call
    per template, scattered into place by one sparse matrix product. `h_rows[i]` is the
    elastic row of g holding real row i; `quat_idx` the x indices of quaternion entries,
    in the order of the unit-norm rows that follow the elastic rows.

    With `distance_curvature` off, templates that query signed distances (`sdist`,
    `sdist2`) are left out: their rows enter ipopt's model linearised, as collision
    constraints do in SQP trajectory optimisers (TrajOpt). Why: on robot domains those
    Hessians are a large part of an iteration's cost (Lab 5 mode-switch graph, 2554 rows:
    26 of 64 ms per iteration) and the least informative part of the model, the second
    derivative of a piecewise-smooth distance through a local contact model. The verdict
    is untouched: only ipopt's steps change, feasibility is decided on the real rows.
    Measured with `benchmarks/bench_lab.py` (examples/README.md).

    With `kinematic_curvature` off, templates that use forward kinematics (`fk`) are left
    out as well (KOMO's Gauss-Newton model; measurements and why it is not the Lab's
    setting in docs/design.md, "Linearised kinematics").

    In that linearised model the unit-quaternion rows (|q|^2 - 1 = 0) keep their curvature
    only where it is convex: 2 max(lam, 0) on the quaternion's diagonal instead of 2 lam.
    Why: a negative multiplier made the Hessian indefinite, and ipopt corrected the inertia
    (extra factorisations, a damped step) in a third of the iterations; measured on
    `bench_komo.py`'s keyframe NLP (12 seeds, the block's SE3 poses): 370 -> 306 ipopt
    iterations in all, median 43.8 -> 38.1 ms CPU per solve, same verdicts (dropping the term
    altogether: 313 iterations, keeping |lam|: 331). The exact Hessian keeps 2 lam."""
    z = ca.MX.sym("x", n_z)
    pp = ca.MX.sym("p", n + n_par + 1)
    lam_f = ca.MX.sym("lam_f")
    lam_g = ca.MX.sym("lam_g", n_g)
    x, x0, P, rho = z[:n], pp[:n], pp[n:n + n_par], pp[n + n_par]
    lam_h = lam_g[h_rows.tolist()] if h_rows.size else ca.MX(0, 1)
    parts, entries, base = [], [], 0       # entries: (row a, col b, index into parts)
    for cb, k, stacked, p0, r0 in layout:
        if not distance_curvature and DISTANCE_PRIMITIVES & cb.primitives:
            continue
        if not kinematic_exact and "fk" in cb.primitives:
            continue
        hf = compiler.hessian(cb)
        sp = hf.sparsity_out(0)
        if sp.nnz() == 0:
            continue
        slots, Pg = _mapped_inputs(x, P, cb, k, stacked, p0)
        Lg = ca.reshape(lam_h[r0:r0 + cb.n_rows * k], cb.n_rows, k)
        fn = hf if k == 1 else hf.map(k, "serial")
        Hk = fn(*slots, Pg, Lg)
        parts.append(Hk.nz[:])
        rr, cc = (np.asarray(v, dtype=np.int64) for v in sp.get_triplet())
        nnz = sp.nnz()
        st = np.asarray(stacked, dtype=np.int64)
        t = np.arange(k, dtype=np.int64)[:, None]       # instances x entries, in that order
        ab = np.stack([st[:, rr], st[:, cc], base + t * nnz + np.arange(nnz)[None, :]],
                      axis=-1).reshape(-1, 3)
        entries.append(ab[ab[:, 0] <= ab[:, 1]])       # the upper triangle
        base += k * nnz
    # pull towards the start (pseudo-Huber) and unit quaternions: diagonal terms
    parts.append(lam_f * rho * (1 + (x - x0) ** 2) ** (-1.5))
    chunks, entries = entries, [(i, i, base + i) for i in range(n)]
    base += n
    if quat_idx:
        lam_q = lam_g[n_g - len(quat_idx) // 4:]
        if not kinematic_exact:
            # the model's convex part only (see the docstring)
            lam_q = ca.fmax(lam_q, 0)
        parts.append(2 * ca.repmat(lam_q.T, 4, 1)[:])
        entries += [(a, a, base + m) for m, a in enumerate(quat_idx)]
        base += len(quat_idx)
    H = _scatter_parts(n_z, n_z, np.concatenate(
        [*chunks, np.array(entries, dtype=np.int64).reshape(-1, 3)]), parts)
    return ca.Function("nlp_hess_l", [z, pp, lam_f, lam_g], [H],
                       ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])
