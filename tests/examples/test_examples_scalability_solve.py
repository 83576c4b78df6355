"""The smallest scalability member solved end to end with each planner that finds its plan fast,
the solution checked by the independent pinocchio + coal verification
(`gnppdsl.solve.verify_solution`, as benchmarks/bench_lab.py). About 5 s CPU per solve; the
larger members are in benchmarks/bench_scalability.py (`--solve`), not in the suite."""
from __future__ import annotations

from pathlib import Path

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
