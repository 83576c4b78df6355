"""`SolverOptions.iteration_budget` (all runs of one solve together, enforced between runs and,
through the iteration monitor, inside a run) and the final polish that is not run again from
a point whose polish already ran (`FeasibilitySolver.solve`)."""
from __future__ import annotations

import numpy as np

from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import discs


def test_iteration_budget_bounds_all_runs_of_a_solve():
    vs, fs = discs(3)                    # infeasible: every start runs until its stall
    g = GraphNLP(fs)
    free = FeasibilitySolver(options=SolverOptions(restarts=2, early_stop=True, stall_iterations=400))
    r = free.solve(g)
    assert not r.feasible and r.iterations > 25 and free.solves >= 3
    s = FeasibilitySolver(options=SolverOptions(restarts=2, early_stop=True, stall_iterations=400,
                                                iteration_budget=25))
    b = s.solve(g)
    assert b is not None and not b.feasible
    assert b.iterations <= 25 and s.solves < free.solves
    assert b.status == "Maximum_Iterations_Exceeded"
    # what was reached is still judged: the point's violation is a real one
    assert b.max_violation > 1e-3 and np.isfinite(b.max_violation)


def test_iteration_budget_does_not_change_a_feasible_verdict():
    vs, fs = discs(2)
    r = FeasibilitySolver(options=SolverOptions(early_stop=True, iteration_budget=200)).solve(GraphNLP(fs))
    assert r.feasible


class _WorsePolish(FeasibilitySolver):
    """A solver whose polish runs end farther from feasible than their start (so the start
    stays the best point), recording every run's start."""

    def __init__(self, *a, **k):
        super().__init__(*a, **k)
        self.calls = []

    def _run(self, a, x0, rho, warm=None, **kw):
        self.calls.append((x0.tobytes(), rho, warm is not None))
        x, slack, it, status, lam = super()._run(a, x0, rho, warm, **kw)
        if warm is not None:
            x = x + 0.5
        return x, slack, it, status, lam


def test_a_polish_that_ended_no_better_is_not_run_again_from_the_same_point():
    vs, fs = discs(3)
    s = _WorsePolish(options=SolverOptions(restarts=0, polish_below=float("inf"), early_stop=True))
    r = s.solve(GraphNLP(fs))
    assert not r.feasible
    polishes = [c for c in s.calls if c[2]]
    assert len(polishes) == 1 and len(set(s.calls)) == len(s.calls)
