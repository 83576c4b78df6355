"""First starts of two variables of one kind and step with the same guess are moved apart by
SEPARATION (`FeasibilitySolver._separated`): coincident discs are a stationary point of the
distance between them, from which a one-start solve of a satisfiable `no_overlap` stalls and
reports 'infeasible'. Checked by the numpy evaluator at the returned point, and against the
solver with the separation switched off."""
from __future__ import annotations

import numpy as np

from gnppdsl.nlp import feasibility
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import in_box, no_overlap, pose


def _graph():
    a, b = pose("a", 0), pose("b", 0)
    return GraphNLP([in_box(a, 1.0, 0), in_box(b, 1.0, 0), no_overlap(a, b, 0.2, 0.2, 0)]), a, b


def test_equal_guesses_start_a_millimetre_apart_and_the_discs_separate(monkeypatch):
    g, a, b = _graph()
    same = {a: np.zeros(3), b: np.zeros(3)}           # e.g. two blocks at a region's centre
    solver = FeasibilitySolver(options=SolverOptions(restarts=0))
    x0 = solver._start(solver.assemble(g), g, None, same, 0, 0)
    xa, xb = x0[:3], x0[3:]
    assert 0 < np.linalg.norm(xa[:2] - xb[:2]) < 0.01   # apart, by about a millimetre
    assert np.array_equal(xa, same[a]) != np.array_equal(xb, same[b])   # only one was moved
    r = solver.solve(g, initial_guess=same)
    assert r.feasible and r.starts == 1
    assert max_violation(g.factor_instances, r.values)[0] <= 1e-6
    # counterfactual: without the separation, one start from the coincident guess stalls
    monkeypatch.setattr(feasibility, "SEPARATION", 0.0)
    stuck = FeasibilitySolver(options=SolverOptions(restarts=0)).solve(g, initial_guess=same)
    assert not stuck.feasible


def test_distinct_guesses_are_kept_as_they_are():
    g, a, b = _graph()
    guess = {a: np.array([0.3, 0.0, 0.0]), b: np.array([-0.3, 0.0, 0.0])}
    solver = FeasibilitySolver(options=SolverOptions(restarts=0))
    x0 = solver._start(solver.assemble(g), g, None, guess, 0, 0)
    np.testing.assert_array_equal(x0, np.concatenate([guess[a], guess[b]]))
