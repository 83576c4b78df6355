"""Idle motions in the phase-by-phase motion solve
(`FeasibilityCheck.motions_between_keyframes`): a trajectory whose keyframes do not change is first held on its straight line, the factors that
then only read fixed values are checked once with numpy and left out of the phase NLP, and a
phase where that fails is solved again with the trajectory free. Checked on the toy with two
blocks (one moves while the other waits) against the independent re-check of the solution."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.motions import IDLE_MOTION
from gnppdsl.solve.options import SolveOptions
from solve_checks import check_solution


def _toy():
    from solve_toy import occupied_problem

    return occupied_problem(waypoints=8)


def _solve(compiled):
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=6, order="staged"))
    assert res.solved and res.stats.N == 4, res.message
    check_solution(compiled, res)
    return res


def test_waiting_trajectories_are_held_on_the_straight_line_and_left_out_of_the_phase_nlp(monkeypatch, zigzag_starts):
    from gnppdsl.nlp.feasibility import FeasibilitySolver

    seen_idle, phase_graphs = [], []
    real_idle = FeasibilityCheck.idle_motions
    real_solve = FeasibilitySolver.solve

    def spy_idle(self, s, i):
        idle = real_idle(self, s, i)
        seen_idle.append((s, idle))
        return idle

    def spy_solve(self, g, warm_start=None, initial_guess=None, seed=0, **kw):
        if "{moving}" in g.name:
            phase_graphs.append(g)
        return real_solve(self, g, warm_start=warm_start, initial_guess=initial_guess, seed=seed, **kw)

    monkeypatch.setattr(FeasibilityCheck, "idle_motions", spy_idle)
    monkeypatch.setattr(FeasibilitySolver, "solve", spy_solve)
    compiled = _toy()
    _solve(compiled)
    assert any(idle for _, idle in seen_idle), "the toy has a block that waits in some phase"
    for s, idle in seen_idle:
        for v, x in idle.items():
            pts = x.reshape(v.waypoints, v.point_dim)
            # a straight line between keyframes that differ by at most IDLE_MOTION
            assert np.allclose(np.diff(pts, 2, axis=0), 0.0, atol=1e-12)
            assert np.max(np.abs(pts[-1] - pts[0])) <= IDLE_MOTION
    # the phase NLPs never carry a factor whose variables are all fixed
    assert phase_graphs
    for g in phase_graphs:
        for ref in g.factor_refs:
            assert any(u.lower is None or u.lower != u.upper for u in g.graph.neighbors(ref))


def test_a_held_trajectory_that_breaks_a_factor_is_solved_again_free(monkeypatch, zigzag_starts):
    """idle_motions is forced to propose a wrong line (shifted off its keyframes): the constant
    factors are violated, so every such phase is solved again with the trajectory free, and the
    answer is the same valid solution."""
    real_idle = FeasibilityCheck.idle_motions
    retried = []
    real_motion = FeasibilityCheck.solve_motion

    def shifted(self, s, i):
        return {v: x + 0.5 for v, x in real_idle(self, s, i).items()}

    def spy_motion(self, s, frozen, idle, warm, fixed_values):
        r = real_motion(self, s, frozen, idle, warm, fixed_values)
        retried.append((bool(idle), r is None))
        return r

    monkeypatch.setattr(FeasibilityCheck, "idle_motions", shifted)
    monkeypatch.setattr(FeasibilityCheck, "solve_motion", spy_motion)
    _solve(_toy())
    assert (True, True) in retried                    # the held try was refused by numpy
    assert (False, False) in retried                  # and the phase solved free


def test_a_phase_whose_straight_line_start_satisfies_it_needs_no_nlp(monkeypatch):
    """The toy's straight-line paths already keep the step bound: every phase is accepted by
    the numpy check of its start, no phase NLP is built, and the solution (made of those
    starts) passes the independent re-check."""
    from gnppdsl.nlp.feasibility import FeasibilitySolver

    real_solve = FeasibilitySolver.solve
    real_motion = FeasibilityCheck.solve_motion
    phase_nlps, answers = [], []

    def spy_solve(self, g, warm_start=None, initial_guess=None, seed=0, **kw):
        if "{motion" in g.name:
            phase_nlps.append(g.name)
        return real_solve(self, g, warm_start=warm_start, initial_guess=initial_guess, seed=seed, **kw)

    def spy_motion(self, *args):
        r = real_motion(self, *args)
        answers.append(None if r is None else r.status)
        return r

    monkeypatch.setattr(FeasibilitySolver, "solve", spy_solve)
    monkeypatch.setattr(FeasibilityCheck, "solve_motion", spy_motion)
    _solve(_toy())
    assert answers and all(a == "its start satisfies it" for a in answers), answers
    assert not phase_nlps


def test_phase_nlps_between_fixed_keyframes_run_at_most_motion_max_iter_iterations(monkeypatch, zigzag_starts):
    """A phase between fixed keyframes is never a verdict (a failing one is joined with its
    keyframes), so its ipopt runs are capped at MOTION_MAX_ITER iterations; the other NLPs of
    the loop keep the loop's own limit."""
    from gnppdsl.nlp.feasibility import FeasibilitySolver
    from gnppdsl.solve.motions import MOTION_MAX_ITER

    limits = {"phase": set(), "other": set()}
    real_solve = FeasibilitySolver.solve

    def spy_solve(self, g, warm_start=None, initial_guess=None, seed=0, **kw):
        limits["phase" if "{motion" in g.name else "other"].add(self.options.max_iter)
        return real_solve(self, g, warm_start=warm_start, initial_guess=initial_guess, seed=seed, **kw)

    monkeypatch.setattr(FeasibilitySolver, "solve", spy_solve)
    _solve(_toy())
    assert MOTION_MAX_ITER < SolveOptions().max_iter
    assert limits["phase"] == {MOTION_MAX_ITER}
    assert limits["other"] == {SolveOptions().max_iter}
