"""The time limit counts loading and grounding (`SolveOptions.started`): `solve_problem` on a
path from before loading; `solve_compiled` on a problem compiled earlier from the loop's start
(`gnpp solve` hands the loop what is left of its limit after loading: gnppdsl/cli/solve_cmd.py). No timing is asserted: the tests check where the clock
starts (the order of events) and that a limit already spent ends the solve before any plan."""
from __future__ import annotations

import time
from pathlib import Path

import gnppdsl.solve.loop as loop
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.result import TIME_LIMIT

P1 = str(Path(__file__).resolve().parents[2] / "examples/planar/p1_one_block.pntc")


def test_a_limit_spent_before_the_loop_ends_the_solve_without_a_plan():
    compiled = load_and_compile(P1)
    long_ago = time.perf_counter() - 1000.0
    res = loop.solve_compiled(compiled, SolveOptions(time_limit=30, started=long_ago))
    assert res.status == TIME_LIMIT and res.stats.plans == 0 and res.stats.nlp_solves == 0
    assert res.stats.total_time >= 1000.0          # the clock started at `started`
    fresh = loop.solve_compiled(compiled, SolveOptions(time_limit=30))
    assert fresh.solved and fresh.stats.total_time < 1000.0


def spy(monkeypatch, load_owner) -> dict:
    """Record when loading starts (`load_owner.load_and_compile`) and the options the solve
    gets (`loop.solve_compiled`), calling the real functions."""
    seen: dict = {}
    real_load, real_solve = load_and_compile, loop.solve_compiled

    def load(paths):
        seen["load"] = time.perf_counter()
        return real_load(paths)

    def solve(compiled, options, progress=None):
        seen["options"] = options
        return real_solve(compiled, options, progress)

    monkeypatch.setattr(load_owner, "load_and_compile", load)
    monkeypatch.setattr(loop, "solve_compiled", solve)
    return seen


def test_solve_problem_on_a_path_starts_the_clock_before_loading(monkeypatch):
    seen = spy(monkeypatch, loop)
    assert loop.solve_problem(P1).solved
    assert seen["options"].started is not None and seen["options"].started <= seen["load"]
    compiled = load_and_compile(P1)
    loop.solve_problem(compiled)
    assert seen["options"].started is None           # compiled earlier: the loop's own start
