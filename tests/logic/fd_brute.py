"""Fast Downward on small tasks with conflicts, against the brute force (logic_brute.py): the
setup the FD tests of test_logic_fd_guidance.py and test_logic_transitions.py share."""
from __future__ import annotations

from typing import Callable, Iterable

import pytest

from logic_brute import all_plans

HORIZON = 6


def fd_agrees_with_brute_force(cases: Iterable, inspect: Callable | None = None, least: int = 5) -> None:
    """For each (task, conflicts, _) of cases: FastDownwardPlanner (max_horizon HORIZON) with the
    conflicts added, `inspect(task, planner)` before it plans, then its shortest plan (validated
    against task + conflicts inside: raises) is found exactly when the brute force finds a plan
    of at most HORIZON actions (lazy greedy with reopening: "no plan" is a proof); at least
    `least` of the cases have one. Skips without up-fast-downward."""
    pytest.importorskip("up_fast_downward", reason="up-fast-downward (optional external package) is not installed")
    from gnppdsl.logic.fd_planner import FastDownwardPlanner

    found = 0
    for task, conflicts, _ in cases:
        planner = FastDownwardPlanner(task, max_horizon=HORIZON)
        planner.add_conflicts(conflicts)
        if inspect is not None:
            inspect(task, planner)
        res = planner.shortest_plan()
        assert res.found == bool(all_plans(task, HORIZON, conflicts))
        found += res.found
    assert found >= least
