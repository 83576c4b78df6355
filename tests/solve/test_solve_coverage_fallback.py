"""`Coverage.unoptimised`: when the optimised solution still fails the independent verification
after the active set's rounds, the plan's feasible solution (no optimisation phase) is verified
and returned when it is clean; else the optimised result stays, its figures restored.

How the branch is reached (sort2, R-LGP, seed 0, whose optimised solution is clean): the
verification of an optimised solution is answered by the test, every other call by the real
verification (pinocchio + coal), whose report on what is returned is the oracle."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.solve import coverage
from gnppdsl.solve.active_set import verify
from gnppdsl.solve.verify_solution import Failure, SolutionReport

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"
FAKE = Failure("grasp", 1, None, ("blue1",), None, "injected by the test")


def _solve(monkeypatch, answer):
    """sort2 with R-LGP, seed 0; `answer(k, optimised, real report)` gives the report of the
    verification's k-th call (from 1), None: the real one. Returns (compiled, result, calls:
    (optimised, real report) per call)."""
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions

    calls = []

    def answered(compiled, result, settings=None, **kw):
        real = verify(compiled, result, settings, **kw)
        calls.append((bool(result.stats.optimised), real))
        out = answer(len(calls), calls[-1][0], real)
        return real if out is None else out

    monkeypatch.setattr(coverage, "verify", answered)
    c = load_and_compile([str(MOBILE / "sort2.pntc")])
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, algorithm="rlgp", seed=0,
                                                     time_limit=120))
    return c, r, calls


def test_the_optimised_result_stays_when_the_feasible_one_fails_too(monkeypatch):
    """A failure the active set cannot repair (not a collision) on the optimised solution and on
    the feasible one: the optimised result is returned, failed, with its own figures."""
    c, r, calls = _solve(monkeypatch, lambda k, optimised, real: SolutionReport(False, [FAKE]))
    assert [o for o, _ in calls] == [True, False]      # the optimised result, then the feasible one
    assert r.status == "verification_failed"
    assert r.verification["failures"][0]["message"].endswith("injected by the test")
    assert r.stats.optimised and r.stats.cost < r.stats.cost_feasible


def test_the_feasible_solution_is_returned_when_the_optimised_one_fails_the_verification(monkeypatch):
    """The optimised solution is made to collide where the plain feasible solution does (its real
    collisions, one active-set round: their pairs along the motions), then to fail without a
    collision: the rounds end, and the feasible solution, which satisfies the round's pair
    factors, is verified clean and returned (its cost the feasible one's)."""
    _, first, calls = _solve(monkeypatch, lambda k, optimised, real: SolutionReport(False, [FAKE]))
    feasible = calls[1][1]                   # the real report of the plan's feasible solution
    optimised_cost = first.stats.cost

    def answer(k, optimised, real):
        if not optimised:
            return None
        if k == 1 and not feasible.ok:
            return SolutionReport(False, list(feasible.issues), near=list(feasible.near),
                                  riding=dict(feasible.riding))
        return SolutionReport(False, [FAKE])

    c, r, calls = _solve(monkeypatch, answer)
    assert not calls[-1][0]                  # the last verification: the feasible solution's
    assert r.status == "solved", r.message
    assert "feasible solution is returned" in r.message and "injected by the test" in r.message
    assert r.verification["ok"] and verify(c, r).ok
    assert not r.stats.optimised
    assert r.stats.cost == pytest.approx(r.stats.cost_feasible) and r.stats.cost > optimised_cost
