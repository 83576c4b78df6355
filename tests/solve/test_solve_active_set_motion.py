"""The active set on a motion whose optimised path keeps colliding somewhere else
(`gnppdsl.solve.active_set.along_motion`, `gnppdsl.solve.coverage.Coverage.unoptimised`).

Oracle: the independent verification (pinocchio + coal, `gnppdsl.solve.verify_solution`); a
solved result must be clean by it, run afresh."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace

import pytest

from gnppdsl.solve.active_set import along_motion, verify
from gnppdsl.solve.verify_solution import Failure, SolutionReport

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"


def _result(n: int):
    step = lambda state, traj: SimpleNamespace(state=state, trajectories=traj)      # noqa: E731
    return SimpleNamespace(steps=[
        step("{parent(b) = table, parent(c) = mm}", {"path(mm)": [[0.0]] * n}),
        step("{parent(b) = mm, parent(c) = table}", {}),
    ])


def test_a_pair_colliding_at_one_midpoint_joins_at_every_point_of_its_motion():
    n = 6
    report = SolutionReport(False, [
        Failure("collision", 0, 3.5, ("table", "mm/base_link"), -0.02),
        Failure("collision", 0, 2.0, ("c", "mm/finger"), -0.01),      # held by mm: exempt
        Failure("collision", 1, None, ("b", "table"), -0.01),         # a keyframe: not spread
    ])
    out = along_motion(_result(n), report)
    points = sorted(wp for step, wp, a, b, d in out)
    assert points == sorted([1.0, 2.0, 3.0, 4.0] + [k + 0.5 for k in range(n - 1)])
    assert {(step, a, b) for step, wp, a, b, d in out} == {(0, "table", "mm/base_link")}


def test_no_collision_along_a_motion_spreads_nothing():
    report = SolutionReport(False, [Failure("joint_limit", 0, 2.0, ("mm",))],
                            near=[(0, 2.0, "table", "mm/base_link", 0.003)])
    assert along_motion(_result(5), report) == []


@pytest.mark.slow
def test_rlgp_sort_random_pr2_instance_8_is_solved_and_verified():
    """sort_random_pr2 instance 8 with R-LGP: the optimisation phase moved the base's and the
    arm's collision with the centre table to other midpoints of the base drive in each of the
    four active-set rounds, and the run ended verification_failed."""
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile([str(MOBILE / "sort_random_pr2.pntc")], instance=8)
    opts = SolveOptions.from_settings(c.problem.settings, algorithm="rlgp", time_limit=240)
    r = solve_compiled(c, opts)
    assert r.status == "solved", r.message
    assert r.verification["ok"], r.verification["failures"]
    assert verify(c, r).ok
