"""A conflict-to-be refuted from its initial guess (`Confirmation.cold_refutes`).

On a plan where a one-start verdict has been overturned already (`forget_unconfirmed`: the
plan's warm starts mislead), an infeasible verdict that is about to become a conflict is solved
once more from the graph's own initial guess; feasible there, it is no conflict (the checker
keeps the solution and Alg. 1 searches again). Before, such a verdict became the conflict: on
clutter_6 --seed 5 (examples/scalability/generate.py) a 17-fact, 102-factor conflict about the
last state of a 24-step plan, feasible from the initial guess in 0.1 s.

The misleading verdict here is a real solve of the plan's first keyframes from a start with the
block 3 m off and an iteration budget of 2, stored as the verdict the search ended with."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import Loop
from gnppdsl.solve.options import SolveOptions

P1 = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p1_one_block.pntc"


def _misled_checker():
    c = load_and_compile(str(P1))
    run = Loop(c, SolveOptions.from_settings(c.problem.settings, switches="trn"), None)
    plan = run.planner.shortest_plan(time_limit=30).plan
    graph = run.build_graph(plan.states)
    g = graph.time_slice(0, 0)
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    bad = {v: np.asarray(g.initial_guess.get(v, np.zeros(v.dim)), float) + 3.0 for v in g.variables}
    misled = FeasibilitySolver(c.geometry, SolverOptions(restarts=0, max_iter=2, polish=False))
    r = misled.solve(g, warm_start=bad)
    assert not r.feasible                      # the verdict the warm start gave
    checker.results[g.signature()] = r
    checker.values.update(bad)
    return c, run, checker, g


def test_a_verdict_feasible_from_its_initial_guess_is_no_conflict():
    c, run, checker, g = _misled_checker()
    checker.forget_unconfirmed()               # a one-start verdict of this plan proved wrong
    nlps = run.nlp_calls
    assert checker.confirm(g) is False         # refuted: no conflict
    r = checker.results[g.signature()]
    assert r.feasible and run.stats.cold_refutations == 1 and run.nlp_calls == nlps + 1
    assert max_violation(g.factor_instances, r.values, c.geometry)[0] <= run.options.tolerance
    assert all(np.array_equal(checker.values[v], r.values[v]) for v in g.variables)
    assert checker.confirm(g) is True          # decided once per plan: the search moves on
    assert run.nlp_calls == nlps + 1


def test_without_a_misleading_start_the_verdict_costs_no_extra_nlp():
    c, run, checker, g = _misled_checker()
    nlps = run.nlp_calls
    assert checker.confirm(g) is True          # the checker's own verdict stands as before
    assert run.nlp_calls == nlps and run.stats.cold_refutations == 0
