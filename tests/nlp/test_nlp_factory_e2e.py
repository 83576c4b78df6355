"""Real factory output (GraphNLPFactory on the planar blocks IR) through GraphNLP and Alg. 1.

The IR is the hand-built planar domain of the compiler tests (tests/compile/planar_ir.py), so
this runs without the parser; test_nlp_planar_e2e.py does the same from the .pntc files.
"""
from __future__ import annotations

import sys
import time
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "compile"))
import planar_ir  # noqa: E402

from gnppdsl.compile.factory import GraphNLPFactory  # noqa: E402
from gnppdsl.compile.semantics import parse_plan, plan_states  # noqa: E402
from gnppdsl.compile.task import build_task  # noqa: E402
from gnppdsl.nlp.evaluate import max_violation  # noqa: E402
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions  # noqa: E402
from gnppdsl.nlp.graph import GraphNLP  # noqa: E402
from gnppdsl.nlp.subgraph import Relaxation, find_infeasible_subgraph  # noqa: E402

RELAXATIONS = [Relaxation.of("no_robot_col", ["robot", "collision"]),
               Relaxation.of("no_col", ["collision"]),
               Relaxation.of("no_robot_time", ["robot", "time"]),
               Relaxation.of("no_time", ["time"])]
TOL = 1e-6


def graph(name, plan, **kw):
    problem = planar_ir.problem(name, **kw)
    task = build_task(problem)
    states = plan_states(task, parse_plan(task, plan))
    fac = GraphNLPFactory(problem, task)
    vs = fac.variables(states)
    guess = {v: g for v in vs if (g := fac.initial_guess(v)) is not None}
    return GraphNLP.from_factors(fac.factors(states), vs, initial_guess=guess)


@pytest.mark.parametrize("name,plan,kw", [
    ("p1", "pick(b1, g, s1); place(b1, g, r1)", {}),
    ("p2", "pick(b1, g, s1); place(b1, g, rb); pick(b2, g, s2); place(b2, g, ra)", {}),
    ("p2", "pick(b1, g, s1); place(b1, g, rb); pick(b2, g, s2); place(b2, g, ra)",
     {"with_traj": True}),
    ("p5", "pick(b1, g1, s1); handover(b1, g1, g2); place(b1, g2, target)", {}),
])
def test_feasible_plans_solution_rechecked_on_full_graph(name, plan, kw):
    g = graph(name, plan, **kw)
    t = time.perf_counter()
    res = find_infeasible_subgraph(g, RELAXATIONS, "trn", solver=FeasibilitySolver())
    print(f"{name} {kw}: {g} feasible={res.feasible} {res.stats.solves} solves "
          f"{1e3 * (time.perf_counter() - t):.0f} ms")
    assert res.feasible and res.complete_values
    worst, f = max_violation(g.factor_instances, res.values)
    assert worst <= TOL, f.label


def test_unreachable_handover_free_plan_gives_confirmed_small_conflict():
    # in p5, g1 only reaches x <= 0.15 and the target is at x = 0.6: placing with g1 fails
    g = graph("p5", "pick(b1, g1, s1); place(b1, g1, target)")
    res = find_infeasible_subgraph(g, RELAXATIONS, "trn", solver=FeasibilitySolver())
    print(res.relaxation, res.stats.solves, "solves\n" + res.subgraph.describe())
    assert not res.feasible and res.subgraph.n_factors < g.n_factors
    rules = {f.rule for f in res.subgraph.factor_instances}
    assert {"reach", "placed"} <= rules
    assert all(a in ("b1", "g1", "target") for f in res.subgraph.factor_instances
               for _, a in f.bindings)
    s = FeasibilitySolver(options=SolverOptions(restarts=0, noise=1.0))
    assert all(not s.solve(res.subgraph, seed=10 + k).feasible for k in range(6))
