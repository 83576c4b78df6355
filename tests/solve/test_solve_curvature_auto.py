"""kinematic_curvature "auto" in the loop: no verdict, hence no conflict, rests on linearised
runs alone. Every feasibility check of the loop (full graph, relaxations, conflict search,
time search, confirmations) goes through `FeasibilitySolver.solve`, whose fallback re-runs a
failed linearised start with the exact Hessian.

The planar problem has no forward kinematics, so a stub plays the Gauss-Newton model that
stalls: each first-pass assembly counts as linearised and its runs end where they started.
With "auto" the loop must learn exactly the conflicts and find the plan it finds with the
exact Hessian; with the linearised model alone (false) the same stub breaks it."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest

from gnppdsl.nlp.feasibility import FeasibilitySolver
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions

PROBLEM = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p3_occupied.pntc"


def _stall_linearised(monkeypatch) -> list:
    assemble, run = FeasibilitySolver.assemble, FeasibilitySolver._run
    stalls: list = []

    def assemble_(self, graph):
        a = assemble(self, graph)
        return a if self.kinematic_exact else replace(a, linearised=True)

    def run_(self, a, x0, rho, warm=None, limit=0):
        if a.linearised:
            stalls.append(a.n_x)
            return x0.copy(), 1.0, 0, "stub: linearised run stalled", None
        return run(self, a, x0, rho, warm, limit)

    monkeypatch.setattr(FeasibilitySolver, "assemble", assemble_)
    monkeypatch.setattr(FeasibilitySolver, "_run", run_)
    return stalls


def _solve(c, mode):
    return solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=60, max_horizon=5,
                                                        kinematic_curvature=mode))


@pytest.mark.parametrize("patience", [0, 2])
def test_auto_learns_no_conflict_from_a_linearised_failure(monkeypatch, patience):
    """patience 0: every NLP tries the linearised runs first; 2 (the default): the loop stops
    trying them after two solves in a row that needed the fallback (`trial_patience`)."""
    c = load_and_compile([str(PROBLEM)])
    exact = _solve(c, True)
    assert exact.solved and exact.conflicts        # N > N0: conflicts are learned on the way
    stalls = _stall_linearised(monkeypatch)
    init = FeasibilitySolver.__init__

    def init_(self, *a, **kw):
        init(self, *a, **kw)
        self.options.trial_patience = patience

    monkeypatch.setattr(FeasibilitySolver, "__init__", init_)
    auto = _solve(c, "auto")
    assert stalls                                  # the stub was hit ...
    assert auto.solved and auto.stats.N == exact.stats.N
    assert 0 < auto.stats.curvature_fallbacks <= len(stalls)
    if patience:
        assert auto.stats.curvature_fallbacks == patience
    if patience == 0:
        assert auto.stats.curvature_rescues > 0    # ... feasible verdicts came from the exact runs
    assert sorted(k.text for k in auto.conflicts) == sorted(k.text for k in exact.conflicts)
    assert auto.stats.nlp_solves == exact.stats.nlp_solves
    # ... and it matters: the linearised model alone learns conflicts that are not there
    broken = _solve(c, False)
    assert not broken.solved or sorted(k.text for k in broken.conflicts) != sorted(k.text for k in exact.conflicts)
