"""`gnppdsl.collector.solving`: during a solve the cyclic collector's young threshold is
raised and what was alive at the start is frozen; both are undone afterwards, also when the
solve raises."""
from __future__ import annotations

import gc
from pathlib import Path

import pytest

from gnppdsl import collector

PROBLEM = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p3_occupied.pntc"


def test_solving_raises_the_threshold_freezes_and_restores():
    before = gc.get_threshold()
    assert gc.get_freeze_count() == 0
    with collector.solving():
        assert gc.get_threshold()[0] >= collector.YOUNG_THRESHOLD
        assert gc.get_freeze_count() > 0
        with collector.solving():                  # nested: the outer one keeps the freezing
            assert gc.get_freeze_count() > 0
        assert gc.get_freeze_count() > 0
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0
    with pytest.raises(RuntimeError):
        with collector.solving():
            raise RuntimeError("a failed solve")
    assert gc.get_threshold() == before and gc.get_freeze_count() == 0


def test_the_solve_loop_runs_inside_it(monkeypatch):
    from gnppdsl.solve import loop as L
    from gnppdsl.solve.compiled import load_and_compile

    seen = []

    def solve(self):
        seen.append((gc.get_threshold()[0], gc.get_freeze_count()))
        raise RuntimeError("stop here")

    monkeypatch.setattr(L.Loop, "solve", solve)
    with pytest.raises(RuntimeError, match="stop here"):
        L.solve_compiled(load_and_compile(str(PROBLEM)))
    assert seen and seen[0][0] >= collector.YOUNG_THRESHOLD and seen[0][1] > 0
    assert gc.get_freeze_count() == 0
