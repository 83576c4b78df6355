"""Infeasibility certificates (`gnppdsl.nlp.certificate.certify_infeasible`): a subgraph decided
infeasible at the convergence point of a graph containing it, without a solve.

Checked independently: on planar p5's two direct plans the certified support is infeasible from
several starts of its own solve, while every subgraph the certificate refuses there that is
feasible (the support without any one factor, each found feasible by a solve and re-evaluated
with numpy) stays refused; without the polish (the pull's forces crossing the support's
boundary) nothing is certified; and a stationary point that is a saddle of the subgraph's NLP
(a factor pinned by a row with a zero multiplier) is refused by the second-order condition,
where the first-order one alone would certify a feasible subgraph."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.ir.expr import Constraint, Index, Num, Slot, Vec
from gnppdsl.nlp import certificate
from gnppdsl.nlp.certificate import certify_infeasible
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.plan_graph import plan_graph

from nlp_toys import C, factor, pose

P5 = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p5_handover.pntc"
PLANS = ("pick(b1, g2, s1); place(b1, g2, target)", "pick(b1, g1, s1); place(b1, g1, target)")
TOL = 1e-6


@pytest.fixture(scope="module")
def p5():
    return load_and_compile(str(P5))


def _solver(c=None, restarts=0, **kw):
    if c is None:
        return FeasibilitySolver(options=SolverOptions(restarts=restarts, **kw))
    return FeasibilitySolver(c.geometry, SolverOptions(restarts=restarts, **kw), compiler=c.body_compiler("off"))


@pytest.mark.parametrize("plan", PLANS)
def test_the_support_is_certified_and_every_feasible_part_of_it_refused(p5, plan):
    g = plan_graph(p5.factory, plan_states(p5.task, parse_plan(p5.task, plan)))
    solver = _solver(p5)
    r = solver.solve(g)                                   # one start, polished (default)
    assert not r.feasible and r.duals is not None
    support = r.active(TOL)
    m = g.subgraph(factors=support)
    cert = certify_infeasible(solver, m, r, g)
    assert cert is not None and not cert.feasible and cert.iterations == 0
    assert set(cert.violated(TOL)) == set(r.violated(TOL))
    assert cert.max_violation == pytest.approx(r.max_violation)
    proof = _solver(p5, restarts=4).solve(m)              # its own solve, 5 starts
    assert not proof.feasible and proof.starts == 5
    assert proof.max_violation == pytest.approx(cert.max_violation, rel=1e-3)
    for ref in support:
        rest = m.subgraph(factors=[x for x in support if x != ref])
        sol = _solver(p5, restarts=4).solve(rest)
        assert sol.feasible
        assert max_violation(rest.factor_instances, sol.values, p5.geometry)[0] <= TOL
        assert certify_infeasible(solver, rest, r, g) is None, g.factor(ref).label


@pytest.mark.parametrize("plan", PLANS)
def test_without_the_polish_the_pull_crossing_the_support_certifies_nothing(p5, plan):
    g = plan_graph(p5.factory, plan_states(p5.task, parse_plan(p5.task, plan)))
    solver = _solver(p5, final_polish_below=1e-2)         # 0.16-0.2 violated: not polished
    r = solver.solve(g)
    assert not r.feasible and r.duals is not None and r.duals.rho == solver.options.regularisation
    outside = [ref for ref in g.factor_refs if ref not in r.active(TOL)]
    assert max(np.abs(r.duals.rows[ref]).max() for ref in outside) > 1e-3
    assert certify_infeasible(solver, g.subgraph(factors=r.active(TOL)), r, g) is None
    polished = _solver(p5).solve(g)
    assert polished.duals.rho == pytest.approx(1e-4 * solver.options.regularisation)
    assert max(np.abs(polished.duals.rows[ref]).max() for ref in outside) < 1e-6


def _saddle() -> tuple[GraphNLP, GraphNLP]:
    """x pinned at 0 (`pin`), and |x| >= 0.5 (`away`, as x^2 >= 0.25): the elastic optimum is
    x = 0 (violation 0.25 on `away`, cheaper than 0.5 on `pin`), where `pin` carries no
    multiplier (the gradient of `away` vanishes there). So the support is `away` alone, and x = 0
    is a stationary point of its NLP: the maximum of its violation, while it is feasible."""
    v = pose("b", 0)
    x = Index(Slot(0), Num(0))
    pin = factor("toy.pin", [v], [Constraint(x, "==", Num(0.0))], 0)
    away = factor("toy.away", [v], [Constraint(C("sqnorm", Vec((x,))), ">=", Num(0.25))], 0)
    g = GraphNLP.from_factors([pin, away], name="saddle")
    return g, g.subgraph(factors=[ref for ref in g.factor_refs if g.factor(ref).template == "toy.away"])


def test_a_saddle_of_the_subgraph_is_refused_by_the_second_order_condition(monkeypatch):
    g, away = _saddle()
    solver = _solver(restarts=0)
    r = solver.solve(g)
    assert not r.feasible and abs(r.values[g.variables[0]][0]) < 1e-3
    assert set(r.active(TOL)) == set(away.factor_refs)    # the heuristic's candidate
    sol = _solver(restarts=2).solve(away)                  # ... which is feasible
    assert sol.feasible and abs(sol.values[away.variables[0]][0]) >= 0.5 - 1e-6
    assert certify_infeasible(solver, away, r, g) is None
    # the first-order conditions hold there: only the curvature (-2 on `away`) refuses it
    real = np.linalg.eigvalsh
    monkeypatch.setattr(certificate.np.linalg, "eigvalsh", lambda a: np.abs(real(a)))
    assert certify_infeasible(solver, away, r, g) is not None


def test_nothing_is_certified_from_a_feasible_point_or_without_multipliers():
    g, away = _saddle()
    solver = _solver(restarts=0)
    r = solver.solve(g)
    assert certify_infeasible(solver, away, type(r)(**{**r.__dict__, "duals": None}), g) is None
    ok = _solver(restarts=0).solve(away)
    assert ok.feasible and certify_infeasible(solver, away, ok, away) is None
