"""The optimisation NLP (`gnppdsl.nlp.optimisation`) on the feasibility NLPs' fast assembly:
its objective gradient, constraint Jacobian and Lagrangian Hessian (built from the per-template
derivatives, scattered by index arithmetic) equal casadi's own AD of the plain formulation
(every factor's Function stacked in an MX graph, the terms summed), and a solve from a feasible
point ends feasible (numpy re-check), cheaper, at the plain formulation's optimum; the
iteration monitor keeps the best feasible iterate and stops on a stall.

Oracles: casadi's AD of a graph written here without the module's layout code; the numpy
evaluator (`gnppdsl.nlp.evaluate`); ipopt on the plain formulation."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from dataclasses import replace

from gnppdsl.ir.expr import Num, Objective, Vec
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.monitor import ObjectiveMonitor
from gnppdsl.nlp.optimisation import _assemble, objective_value, optimise, term_rows
from tests.nlp.nlp_toys import ARM_GEOM, ARM_O, ARM_Q, C, _O_SLOT, _Q_SLOT, arm_reach_graph, factor


def _problem():
    """The arm reaching past a disc (FK and distance rows), a second instance of the distance
    template (another clearance: one compiled body, two parameter columns) after the reach
    factor, so the grouped layout reorders rows, and two terms: the joints' squared norm and
    the disc centre's distance to a point."""
    g = arm_reach_graph()
    reach, clear = g.factor_instances
    clear2 = replace(clear, body=(replace(clear.body[0], rhs=Num(0.15)),))
    graph = GraphNLP([clear, reach, clear2])
    terms = [factor("toy.effort", [ARM_Q], [Objective(C("sqnorm", _Q_SLOT))], 0, ("cost",)),
             factor("toy.centre", [ARM_O], [Objective(C("sqnorm", C("sub", _Q_SLOT, Vec((Num(0.9), Num(-0.3),
                                                                                             Num(0.1))))))],
                    0, ("cost",))]
    return graph, terms


def _plain(graph, terms, compiler, variables, offsets, index):
    """x -> (f, g) written directly: each factor's Function on its slice of x, rows in the
    grouped order (instances of one compiled body together, in order of first appearance)."""
    x = ca.MX.sym("x", int(offsets[-1]))

    def call(f):
        cb, p = compiler.compile(f)
        return cb.function(*[x[int(offsets[index[v]]):int(offsets[index[v]]) + v.dim] for v in f.variables],
                           ca.DM(p))

    order = []
    for f in graph.factor_instances:
        if id(compiler.compile(f)[0]) not in order:
            order.append(id(compiler.compile(f)[0]))
    assert len(order) < len(graph.factor_instances)      # some body has several instances
    g = ca.vertcat(*[call(f) for b in order for f in graph.factor_instances if id(compiler.compile(f)[0]) == b])
    fx = sum(ca.sum1(call(term_rows(t))) for t in terms)
    return x, fx, g


def test_derivatives_equal_casadis_ad_of_the_plain_formulation():
    graph, terms = _problem()
    compiler = BodyCompiler(ARM_GEOM, store=None)
    variables = list(graph.variables)
    index = {v: i for i, v in enumerate(variables)}
    offsets = np.cumsum([0] + [v.dim for v in variables])
    nlp, fns, params, lbg, _ = _assemble(graph, terms, compiler, variables, index, offsets, "exact", "exact")
    x, fx, g = _plain(graph, terms, compiler, variables, offsets, index)
    lam_f, lam_g = ca.MX.sym("lf"), ca.MX.sym("lg", g.numel())
    ref = ca.Function("ref", [x, lam_f, lam_g], [fx, ca.gradient(fx, x), g, ca.jacobian(g, x),
                                                 ca.hessian(lam_f * fx + ca.dot(lam_g, g), x)[0]])
    mine_g = ca.Function("g", [nlp["x"], nlp["p"]], [nlp["f"], nlp["g"]])
    rng = np.random.default_rng(3)
    for _ in range(4):
        xv = rng.normal(0.0, 0.8, x.numel())
        lf, lg = rng.uniform(0.5, 2.0), rng.normal(0.0, 1.0, g.numel())
        f0, gr0, g0, J0, H0 = (np.asarray(ca.DM(v).full()) for v in ref(xv, lf, lg))
        f1, g1 = (np.asarray(v.full()) for v in mine_g(xv, params))
        np.testing.assert_allclose(f1, f0, atol=1e-10)
        np.testing.assert_allclose(g1.ravel(), g0.ravel(), atol=1e-10)
        np.testing.assert_allclose(fns["grad_f"](xv, params)[1].full().ravel(), gr0.ravel(), atol=1e-9)
        np.testing.assert_allclose(fns["jac_g"](xv, params)[1].full(), J0, atol=1e-9)
        H1 = fns["hess_lag"](xv, params, lf, lg).full()
        np.testing.assert_allclose(H1, np.triu(H0), atol=1e-8)
    assert lbg.size == g.numel()


def _feasible_start(graph):
    r = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=1, assembly="MX")).solve(graph, seed=1)
    assert r.feasible
    return r.values


def test_a_solve_from_a_feasible_point_ends_feasible_cheaper_at_the_plain_optimum():
    graph, terms = _problem()
    start = _feasible_start(graph)
    compiler = BodyCompiler(ARM_GEOM, store=None)
    out = optimise(graph, terms, start, compiler, hessian="exact", max_iter=300, feasible_below=1e-7,
                   patience=10)
    assert out is not None
    assert max_violation(graph.factor_instances, out.values, ARM_GEOM)[0] <= 1e-6
    before = objective_value(terms, start, ARM_GEOM)
    after = objective_value(terms, out.values, ARM_GEOM)
    assert after < before - 1e-3
    # ipopt on the plain formulation from the same start reaches the same optimum
    variables = list(graph.variables)
    index = {v: i for i, v in enumerate(variables)}
    offsets = np.cumsum([0] + [v.dim for v in variables])
    x, fx, g = _plain(graph, terms, compiler, variables, offsets, index)
    _, _, _, lbg, ubg = _assemble(graph, terms, compiler, variables, index, offsets, "exact", "exact")
    s = ca.nlpsol("plain", "ipopt", {"x": x, "f": fx, "g": g},
                  {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes", "ipopt.tol": 1e-10})
    x0 = np.concatenate([np.asarray(start[v], float).reshape(-1) for v in variables])
    lbx = np.concatenate([np.asarray(v.lower, float) if v.lower is not None else np.full(v.dim, -np.inf)
                          for v in variables])
    ubx = np.concatenate([np.asarray(v.upper, float) if v.upper is not None else np.full(v.dim, np.inf)
                          for v in variables])
    ref = float(s(x0=x0, lbx=lbx, ubx=ubx, lbg=lbg, ubg=ubg)["f"])
    assert s.stats()["success"]
    assert after == pytest.approx(ref, abs=1e-5)


def test_the_monitor_keeps_the_best_feasible_iterate_and_stops_on_a_stall():
    m = ObjectiveMonitor("m_test", 2, np.array([-np.inf, 0.0]), np.array([0.0, 0.0]))
    m.reset(1e-7, 3)
    feas, infeas = np.array([-1.0, 0.0]), np.array([-1.0, 1e-3])
    assert m.decide(np.array([0.0, 0.0]), 5.0, feas) == 0            # the start
    assert m.decide(np.array([1.0, 0.0]), 1.0, infeas) == 0          # cheaper, infeasible: not kept
    assert m.decide(np.array([2.0, 0.0]), 3.0, feas) == 0            # cheaper and feasible: kept
    assert m.best == 3.0 and m.best_x[0] == 2.0
    assert [m.decide(np.array([3.0, 0.0]), 3.0, feas) for _ in range(3)] == [0, 0, 1]
    assert m.stalled and m.best_x[0] == 2.0
    # from the start alone no stall: the iterates may leave the feasible set for long
    m.reset(1e-7, 3)
    assert [m.decide(np.zeros(2), 5.0, feas)] + [m.decide(np.zeros(2), 6.0, infeas) for _ in range(6)] == [0] * 7
