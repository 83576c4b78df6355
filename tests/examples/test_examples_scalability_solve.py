"""The smallest scalability member solved end to end with each planner that finds its plan fast,
the solution checked by the independent pinocchio + coal verification
(`gnppdsl.solve.verify_solution`, as benchmarks/bench_lab.py). About 5 s CPU per solve; the
larger members are in benchmarks/bench_scalability.py (`--solve`), not in the suite."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.verify_solution import verify_solution

FAMILY = Path(__file__).resolve().parents[2] / "examples" / "scalability"


@pytest.mark.parametrize("mode", ["fd", pytest.param("sequential", marks=pytest.mark.slow)])
def test_stack_4_solved_and_verified(mode):
    if mode == "fd":
        pytest.importorskip("up_fast_downward")
    comp = load_and_compile(str(FAMILY / "stack_4.pntc"))
    r = solve_compiled(comp, SolveOptions.from_settings(comp.problem.settings, planner=mode, jit=False))
    assert r.solved, r.message
    assert r.stats.N == 4                     # N0 = N = number of blocks (expected.yaml)
    # sequential proves N0 shortest; Fast Downward only when its bounded searches below the
    # plan answered "no plan" (`FastDownwardPlanner._tighten`), and then it is N0 = 4 too
    if mode == "sequential":
        assert r.stats.N0_shortest is True
    else:
        assert r.stats.N0_shortest is False or r.stats.N0 == 4
    rep = verify_solution(comp.geometry, r)
    assert rep.ok, rep.failures[:3]


def _stack_4(options=None, **kw):
    comp = load_and_compile(str(FAMILY / "stack_4.pntc"))
    opts = SolveOptions.from_settings(comp.problem.settings, planner="sequential", jit=False, **kw)
    return comp, solve_compiled(comp, opts)


def _spy_screened_motions(monkeypatch) -> list:
    from gnppdsl.solve.feasibility_check import FeasibilityCheck

    out = []
    real = FeasibilityCheck.screened_motion

    def spy(self, m, start, solve, margins=None):
        r = real(self, m, start, solve, margins)
        out.append((self, m, r))
        return r

    monkeypatch.setattr(FeasibilityCheck, "screened_motion", spy)
    return out


def test_motions_with_many_collision_factors_are_screened_and_verified(monkeypatch):
    """A motion between fixed keyframes with at least MOTION_SCREEN_MIN collision factors (here
    lowered so that stack_4's motions qualify) is solved with the factors near its start; what
    it returns satisfies every factor of the motion's NLP (numpy), and the solution passes the
    independent verification. Without screening (the counterfactual) none is screened."""
    from gnppdsl.nlp.evaluate import max_violation
    from gnppdsl.solve import screening

    monkeypatch.setattr(screening, "MOTION_SCREEN_MIN", 1)
    seen = _spy_screened_motions(monkeypatch)
    comp, r = _stack_4()
    assert r.solved, r.message
    answers = [(check, m, res) for check, m, res in seen if res is not None]
    assert answers, "no motion was screened"
    assert r.stats.screened_dropped > 0
    for check, m, res in answers:
        assert res.feasible
        point = {v: res.values[v] for v in m.variables}
        assert max_violation(m.factor_instances, point, comp.geometry)[0] <= 1e-6
    assert verify_solution(comp.geometry, r).ok
    seen.clear()
    _, r = _stack_4(screen_collisions=False)
    assert r.solved and not [x for x in seen if x[2] is not None]


def test_a_screened_motion_that_breaks_the_whole_nlp_is_not_accepted(monkeypatch):
    """Every screened motion NLP 'solves' with its waypoints moved far outside the joint
    limits (a lie the screened NLP cannot see): numpy rejects each, the motions are solved
    whole, and the solve still ends verified."""
    from gnppdsl.solve import screening
    from gnppdsl.solve.feasibility_check import FeasibilityCheck

    monkeypatch.setattr(screening, "MOTION_SCREEN_MIN", 1)
    real = FeasibilityCheck.screen_rounds
    lies = []

    def lying_rounds(self, g, point, collision, solve, margins=None):
        def liar(sub, at):
            res = solve(sub, at)
            if res.feasible and "{motion" in g.name:
                res.values.update({v: np.full_like(np.asarray(x, float), 50.0)
                                   for v, x in res.values.items() if v.waypoints and v.lower != v.upper})
                lies.append(g.name)
            return res
        return real(self, g, point, collision, liar, margins)

    monkeypatch.setattr(FeasibilityCheck, "screen_rounds", lying_rounds)
    seen = _spy_screened_motions(monkeypatch)
    comp, r = _stack_4()
    assert lies
    assert not [x for x in seen if x[2] is not None]
    assert r.solved, r.message
    assert verify_solution(comp.geometry, r).ok
