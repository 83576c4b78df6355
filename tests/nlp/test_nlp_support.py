"""The support of an infeasible verdict (`FeasibilityResult.active`: the violated factors and
those whose multipliers at the convergence point hold them off) and its use as the first
candidate of the convergence heuristic.

Checked independently on planar p5's two direct plans (a gripper that cannot reach the block,
one that cannot reach the target): the support is an irreducible infeasible subgraph, i.e. it
is infeasible from several starts and dropping any one of its factors makes it feasible (each
verdict re-evaluated with the numpy evaluator), and it is what the heuristic returns."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.subgraph import convergence_heuristic
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.plan_graph import plan_graph

P5 = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p5_handover.pntc"
PLANS = {"g2 cannot reach the block": ("pick(b1, g2, s1); place(b1, g2, target)", (0, 1)),
         "g1 cannot reach the target": ("pick(b1, g1, s1); place(b1, g1, target)", (1, 2))}


@pytest.fixture(scope="module")
def p5():
    return load_and_compile(str(P5))


def _solver(c, restarts=0):
    return FeasibilitySolver(c.geometry, SolverOptions(restarts=restarts), compiler=c.body_compiler("off"))


@pytest.mark.parametrize("why", sorted(PLANS))
def test_the_support_of_a_failed_plan_is_an_irreducible_infeasible_subgraph(p5, why):
    plan, steps = PLANS[why]
    g = plan_graph(p5.factory, plan_states(p5.task, parse_plan(p5.task, plan)))
    r = _solver(p5).solve(g)
    assert not r.feasible and r.activity
    tol = 1e-6
    support = r.active(tol)
    assert set(r.violated(tol)) < set(support) and len(support) < g.n_factors / 2
    m = g.subgraph(factors=support)
    assert m.steps == steps                              # the contradiction's time window
    proof = _solver(p5, restarts=4).solve(m)
    assert not proof.feasible and proof.starts == 5      # infeasible from every start
    for ref in support:
        rest = m.subgraph(factors=[x for x in support if x != ref])
        sol = _solver(p5, restarts=4).solve(rest)
        assert sol.feasible, (why, g.factor(ref).label)
        assert max_violation(rest.factor_instances, sol.values, p5.geometry)[0] <= 1e-6


def test_the_heuristic_tries_the_support_first(p5):
    plan, _ = PLANS["g1 cannot reach the target"]
    g = plan_graph(p5.factory, plan_states(p5.task, parse_plan(p5.task, plan)))
    solver = _solver(p5)
    r = solver.solve(g)
    checked = []

    def check(m):
        checked.append(m.name)
        return solver.solve(m)

    found = convergence_heuristic(g, r, check, 1e-6, rounds=1)
    assert checked[0].endswith("{a}")
    assert set(found.factor_refs) == set(r.active(1e-6))
    # without multipliers (e.g. a verdict read from the database) the heuristic starts at M'_v
    checked.clear()
    from dataclasses import replace
    convergence_heuristic(g, replace(r, activity={}), check, 1e-6, rounds=1)
    assert checked and not checked[0].endswith("{a}")
