"""ipopt runs with `fast_step_computation` (no residual check of each KKT solve, no iterative
refinement unless the solve fails): the feasibility NLPs' steps, iterates and verdicts are those
of ipopt's default within round-off, at less CPU per iteration (`SolverOptions.nlpsol_options`).

Checked here: the option reaches the assembled solver, and on two NLPs (coal boxes with signed
distances, a planar chain with an infeasible subgraph) the run with it ends where the run
without it ends (same verdict, same iteration count, values within 1e-8), the verdict checked
against the numpy/coal checker, not the NLP."""
from __future__ import annotations

import numpy as np

import coal  # noqa: F401  (a dependency of the package: never a skip)
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import chain, coal_boxes

FAST = "ipopt.fast_step_computation"


def test_the_default_options_skip_the_step_residual():
    assert SolverOptions().nlpsol_options()[FAST] == "yes"
    # an explicit option still wins (the ipopt dict is applied last)
    assert SolverOptions(ipopt={FAST: "no"}).nlpsol_options()[FAST] == "no"


def test_the_assembled_solver_has_it():
    geo, fs = coal_boxes(3, 0.4)
    a = FeasibilitySolver(geo, SolverOptions(restarts=0)).assemble(GraphNLP(fs))
    assert a.spec[3][FAST] == "yes"


def _pair(graph, geo=None):
    fast = FeasibilitySolver(geo, SolverOptions(restarts=0)).solve(graph, seed=0)
    slow = FeasibilitySolver(geo, SolverOptions(restarts=0, ipopt={FAST: "no"})).solve(graph, seed=0)
    return fast, slow


def test_same_run_as_with_the_step_residual_on_distances():
    geo, fs = coal_boxes(3, 0.4)
    fast, slow = _pair(GraphNLP(fs), geo)
    assert fast.feasible and slow.feasible
    assert fast.iterations == slow.iterations
    for v in slow.values:
        assert np.allclose(fast.values[v], slow.values[v], atol=1e-8)
    assert max_violation(fs, fast.values, geo)[0] <= 1e-6      # coal directly, not the NLP


def test_same_verdict_on_an_infeasible_chain():
    _, fs = chain(5, conflict_at=3)
    g = GraphNLP(fs)
    fast, slow = _pair(g)
    assert not fast.feasible and not slow.feasible
    assert fast.iterations == slow.iterations
    assert abs(fast.max_violation - slow.max_violation) <= 1e-8
