"""End to end on examples/planar: real factory output -> GraphNLP -> Alg. 1.

Infeasible plans must yield conflicts that a multi-start re-solve confirms; feasible plans must
yield values that satisfy every factor of the full graph under the independent numpy checker.
"""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from gnppdsl.solve.compiled import load_and_compile

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.subgraph import find_infeasible_subgraph

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
TOL = 1e-6


def graph_of(compiled, plan_text):
    states = plan_states(compiled.task, parse_plan(compiled.task, plan_text))
    fac = compiled.factory
    variables = fac.variables(states)
    guess = {v: g for v in variables if (g := fac.initial_guess(v)) is not None}
    return GraphNLP.from_factors(fac.factors(states), variables, initial_guess=guess)


def confirmed_infeasible(graph, geometry, starts=6):
    s = FeasibilitySolver(geometry, SolverOptions(restarts=0, noise=1.0))
    return all(not s.solve(graph, seed=50 + k).feasible for k in range(starts))


@pytest.fixture(scope="module")
def p3():
    return load_and_compile(str(PLANAR / "p3_occupied.pntc"))


def test_p3_short_plan_conflict_is_real_and_small(p3):
    g = graph_of(p3, "pick(b1, g, s1); place(b1, g, target)")
    solver = FeasibilitySolver(p3.geometry)
    t = time.perf_counter()
    res = find_infeasible_subgraph(g, p3.relaxations, "trn", solver=solver)
    print(f"p3 short plan: {g}; conflict under {res.relaxation}: {res.subgraph} "
          f"({res.stats.solves} solves, {1e3 * (time.perf_counter() - t):.0f} ms)")
    print(res.subgraph.describe())
    assert not res.feasible
    assert res.subgraph.n_factors < g.n_factors
    assert confirmed_infeasible(res.subgraph, p3.geometry)
    # b2 rests on s2 in the middle of the target, which fits one block: b1 placed there
    # overlaps it. Exactly these three factors at the last step, nothing about the gripper.
    assert sorted((f.rule, f.step) for f in res.subgraph.factor_instances) == \
        [("apart", 2), ("on_spot", 2), ("placed", 2)]


def test_p3_long_plan_feasible_and_rechecked(p3):
    g = graph_of(p3, "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)")
    solver = FeasibilitySolver(p3.geometry)
    t = time.perf_counter()
    res = find_infeasible_subgraph(g, p3.relaxations, "trn", solver=solver)
    print(f"p3 long plan: {g}: feasible={res.feasible} ({res.stats.solves} solves, "
          f"{1e3 * (time.perf_counter() - t):.0f} ms)")
    assert res.feasible and res.complete_values
    worst, f = max_violation(g.factor_instances, res.values, p3.geometry)
    assert worst <= TOL, f.label


def test_t2_unreachable_conflict_is_real():
    c = load_and_compile(str(PLANAR / "t2_unreachable.pntc"))
    g = graph_of(c, "pick(b1, g, s1); place(b1, g, target)")
    res = find_infeasible_subgraph(g, c.relaxations, "trn", solver=FeasibilitySolver(c.geometry))
    print(f"t2: conflict under {res.relaxation}:\n{res.subgraph.describe()}")
    assert not res.feasible and confirmed_infeasible(res.subgraph, c.geometry)
    rules = {f.rule for f in res.subgraph.factor_instances}
    assert {"reach", "placed"} <= rules and "apart" not in rules
