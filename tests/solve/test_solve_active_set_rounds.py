"""The active set's rounds on a solution the optimisation phase did not move: it has no feasible
solution to fall back on (`Coverage.unoptimised` serves optimised ones), so it gets
`ActiveSet.max_feasible_rounds` rounds before the run ends verification_failed, not the 4 of an
optimised one. The case: field5 seed 3 (Table I on a523e21) needed a fifth round (99, 6, 5, 3,
then 1 pair) and ended verification_failed after the fourth.

How it is reached cheaply: lab1 (not optimised, clean at its first solution) with the
verification's first five answers replaced by one near, colliding pair each, a different real
pair every time (so each round adds a factor, which the real solution already satisfies); every
later call is the real verification (pinocchio + coal), whose verdict on what is returned is the
oracle."""
from __future__ import annotations

from pathlib import Path

from gnppdsl.solve import coverage
from gnppdsl.solve.active_set import ActiveSet, verify
from gnppdsl.solve.verify_solution import Failure, SolutionReport

LAB1 = Path(__file__).resolve().parents[2] / "examples" / "lab" / "lab1.pntc"
# links of the two arms at the start, 1 m apart: pairs of links 1-4, which the Lab domain lists
# at no keyframe (its arm-arm pairs involve the hands, fingers and links 5-7), so each one joins
PAIRS = [("left_arm/panda_link1", "right_arm/panda_link1"), ("left_arm/panda_link2", "right_arm/panda_link2"),
         ("left_arm/panda_link3", "right_arm/panda_link3"), ("left_arm/panda_link4", "right_arm/panda_link4"),
         ("left_arm/panda_link1", "right_arm/panda_link2"), ("left_arm/panda_link2", "right_arm/panda_link1")]


def _solve(monkeypatch, fake_calls: int):
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions

    calls: list[bool] = []

    def answered(compiled, result, settings=None, **kw):
        calls.append(bool(result.stats.optimised))
        k = len(calls)
        if k <= fake_calls:
            a, b = PAIRS[k - 1]
            hit = Failure("collision", 0, None, (a, b), -0.01)
            return SolutionReport(False, [hit], keyframes=len(result.steps), near=[(0, None, a, b, -0.01)])
        return verify(compiled, result, settings, **kw)

    monkeypatch.setattr(coverage, "verify", answered)
    c = load_and_compile([str(LAB1)])
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, seed=0, time_limit=120))
    return c, r, calls


def test_a_feasible_solution_gets_more_rounds_than_an_optimised_one():
    s = ActiveSet()
    assert s.max_feasible_rounds > s.max_rounds


def test_a_fifth_round_cleans_what_four_left(monkeypatch):
    c, r, calls = _solve(monkeypatch, fake_calls=5)
    assert not any(calls)                      # lab1's solutions are not optimised
    assert len(calls) == 6, r.message          # five answered rounds, then the real verification
    assert r.status == "solved", r.message
    assert "in 5 rounds" in r.message, r.message
    assert r.verification["ok"] and verify(c, r).ok


def test_the_rounds_run_out(monkeypatch):
    limit = ActiveSet().max_feasible_rounds
    monkeypatch.setattr(coverage, "active_set_of",
                        lambda problem: ActiveSet(max_feasible_rounds=3))
    c, r, calls = _solve(monkeypatch, fake_calls=5)
    assert limit > 3 and len(calls) == 4       # three rounds, the fourth answer ends the run
    assert r.status == "verification_failed", r.status
