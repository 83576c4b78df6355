"""The assembled-NLP cache is keyed by the factor instances, not by plan-local FactorRefs:
two graphs whose factor lists hold different factors at the same positions (two plans) must
never share an NLP; the same instances at different positions must (and report their own refs).
Also: the mapped MX assembly with hand-built derivatives agrees with the SX assembly."""
from __future__ import annotations

import numpy as np

from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import FactorRef, GraphNLP

from nlp_toys import in_box, no_overlap, pose


def test_same_positions_different_factors_are_different_nlps():
    v = pose("b0", 0)
    loose = GraphNLP([in_box(v, 5.0, 0)])          # feasible anywhere near 0
    s = FeasibilitySolver(options=SolverOptions(restarts=0))
    assert s.solve(loose, warm_start={v: np.array([3.0, 3.0, 0.0])}).feasible
    # a second "plan": same variable, same FactorRef(0), a different factor (|x| <= 1 and
    # x must reach 3 via a second, contradictory box)
    tight = GraphNLP([in_box(v, 1.0, 0)])
    r = s.solve(tight, warm_start={v: np.array([3.0, 3.0, 0.0])})
    assert r.feasible
    assert np.all(np.abs(r.values[v][:2]) <= 1.0 + 1e-6)     # the tight factor was solved
    assert len(s._nlps) == 2


def test_same_instances_at_other_positions_share_and_relabel():
    a, b = pose("a", 0), pose("b", 0)
    f1, f2 = in_box(a, 1.0, 0), no_overlap(a, b, 0.5, 0.5, 0)
    f3 = in_box(b, 1.0, 0)
    g1 = GraphNLP([f1, f2, f3])
    g2 = GraphNLP([f3, f1, f2])                   # a different plan's order
    s = FeasibilitySolver(options=SolverOptions(restarts=0))
    r1 = s.solve(g1)
    r2 = s.solve(g2)
    assert len(s._nlps) == 1
    assert r1.feasible and r2.feasible
    assert set(r2.violations) == {FactorRef(0), FactorRef(1), FactorRef(2)}
    # the no_overlap factor is FactorRef(1) in g1 and FactorRef(2) in g2
    assert r2.violations[FactorRef(2)] <= 1e-6


def _row_permutation(a, b, tol=1e-12):
    """perm with b[perm[i]] == a[i] entry by entry (rows of two Jacobians over the same columns);
    fails when a row of `a` has no equal row left in `b`."""
    free, perm = list(range(b.shape[0])), []
    for i, row in enumerate(a):
        k = next((k for k in free if np.allclose(b[k], row, atol=tol, rtol=0)), None)
        assert k is not None, f"row {i} of the SX Jacobian has no equal row in the MX one"
        free.remove(k)
        perm.append(k)
    return np.array(perm)


def test_mapped_mx_assembly_matches_sx():
    """The MX assembly (rows grouped per template) is the SX one up to a row order: every row of
    the constraint Jacobian (over the variables) equal entry by entry, the constraint values equal
    under the same row map, and the Lagrangian's Hessian over the variables equal entry by entry
    when the multipliers follow the rows. A derivative sent to the wrong variable fails here."""
    vs = [pose(f"b{i}", 0) for i in range(4)]
    fs = [in_box(v, 1.2, 0) for v in vs] + [no_overlap(vs[i], vs[j], 0.5, 0.5, 0)
                                           for i in range(4) for j in range(i + 1, 4)]
    g = GraphNLP(fs)
    start = {v: np.array([0.1 * i, -0.05 * i, 0.0]) for i, v in enumerate(vs)}
    asm = {}
    for mode in ("SX", "MX"):
        s = FeasibilitySolver(options=SolverOptions(restarts=0, assembly=mode, early_stop=False))
        a = s.assemble(g)
        x0 = s._start(a, g, start, None, 0, 0)
        z = np.concatenate([x0, np.linspace(0.1, 1.0, a.lbx.size - a.n_x)])
        p = np.concatenate([x0, a.params, [0.01]])
        asm[mode] = (s, a, x0, z, p)
    jac = {mode: np.asarray(a.solver.get_function("nlp_jac_g")(z, p)[1].full())
           for mode, (s, a, x0, z, p) in asm.items()}
    n_x = asm["SX"][1].n_x
    assert asm["MX"][1].n_x == n_x and asm["SX"][1].lbg.size == asm["MX"][1].lbg.size
    jx, jm = jac["SX"][:, :n_x], jac["MX"][:, :n_x]
    assert np.count_nonzero(jx) > 0
    perm = _row_permutation(jx, jm)
    np.testing.assert_array_equal(np.sort(perm), np.arange(jx.shape[0]))
    hx = np.asarray(asm["SX"][1].h_fun(asm["SX"][2], asm["SX"][1].params)).ravel()
    hm = np.asarray(asm["MX"][1].h_fun(asm["MX"][2], asm["MX"][1].params)).ravel()
    assert hx.size == hm.size == jx.shape[0], (hx.size, jx.shape)
    np.testing.assert_allclose(hm[perm], hx, atol=1e-12)
    lam = np.linspace(-1.0, 2.0, jx.shape[0])
    lam_m = np.empty_like(lam)
    lam_m[perm] = lam                       # the multiplier of SX row i sits on MX row perm[i]
    hess = {}
    for mode, mult in (("SX", lam), ("MX", lam_m)):
        s, a, x0, z, p = asm[mode]
        H = np.asarray(a.solver.get_function("nlp_hess_l")(z, p, 1.0, mult).full())
        hess[mode] = np.triu(H[:n_x, :n_x])
    assert np.count_nonzero(hess["SX"]) > 0
    np.testing.assert_allclose(hess["MX"], hess["SX"], atol=1e-12, rtol=1e-12)
    rsx = asm["SX"][0].solve(g, warm_start=start)
    rmx = asm["MX"][0].solve(g, warm_start=start)
    assert rsx.feasible and rmx.feasible


def test_instances_of_one_factory_body_share_their_compiled_body(monkeypatch):
    """Two plans of planar p3: their graphs hold distinct instances built on the factory's
    shared bodies (`_cached_instance`); the compiler lifts each body's constants once, and
    every instance gets what a fresh compiler computes for it (same Function, same parameters)."""
    from pathlib import Path

    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.nlp import body_compiler
    from gnppdsl.solve.compiled import load_and_compile

    c = load_and_compile(str(Path(__file__).resolve().parents[2] / "examples" / "planar" / "p3_occupied.pntc"))
    plans = ["pick(b1, g, s1); place(b1, g, target)",
             "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)"]
    graphs = [c.factory.factors(plan_states(c.task, parse_plan(c.task, p))) for p in plans]
    lifted = []
    real = body_compiler.lift_constants
    monkeypatch.setattr(body_compiler, "lift_constants", lambda body: lifted.append(id(body)) or real(body))
    shared = body_compiler.BodyCompiler(c.geometry)
    got = [[shared.compile(f) for f in fs] for fs in graphs]
    assert len(lifted) == len(set(lifted))                      # each body lifted once
    instances = [f for fs in graphs for f in fs]
    assert len({id(f.body) for f in instances}) < len({id(f) for f in instances})   # bodies are shared
    for fs, results in zip(graphs, got):
        for f, (cb, params) in zip(fs, results):
            fresh_cb, fresh_params = body_compiler.BodyCompiler(c.geometry).compile(f)
            assert cb.n_rows == fresh_cb.n_rows and cb.kinds == fresh_cb.kinds
            np.testing.assert_array_equal(params, fresh_params)
