"""The Field scenario (paper 000, Table I): a fixed Panda and a mobile Panda with start_move /
end_move. Field_1 solved end to end, its solution checked by the independent pinocchio + coal
verification, and the base semantics checked from the returned numbers alone: the base
([x, y, theta], the first three joints of the mobile) is the same at both ends of, and all
along, every phase that starts in a state where the robot is not driving, and it does move
during the drive (else the drive would be a pointless pair of actions the planner was forced
into by a wrong model)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.verify_solution import verify_solution

FIELD = Path(__file__).resolve().parents[2] / "examples" / "field"


@pytest.fixture(scope="module")
def field1():
    c = load_and_compile(str(FIELD / "field1.pntc"))
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=120, seed=0))
    return c, r


def test_field1_needs_the_drive_and_is_verified(field1):
    c, r = field1
    assert r.status == "solved", r.message
    assert (r.stats.N0, r.stats.N) == (2, 4)
    assert r.plan[:2] == ["start_move(mm)", "end_move(mm)"]
    rep = verify_solution(c.geometry, r)
    assert rep.ok, str(rep)
    assert rep.keyframes == len(r.plan) + 1


def test_the_base_moves_only_out_of_a_driving_state(field1):
    _, r = field1
    moved = []
    for i in range(len(r.steps) - 1):
        a, b = np.asarray(r.steps[i].values["q(mm)"]), np.asarray(r.steps[i + 1].values["q(mm)"])
        path = np.asarray(r.steps[i].trajectories["path(mm)"])
        driving = "not driving(mm)" not in str(r.steps[i].state)
        if not driving:
            assert np.allclose(a[:3], b[:3], atol=1e-5), f"base moved in phase {i}"
            assert np.allclose(path[:, :3], a[:3], atol=1e-5), f"base moved along phase {i}"
        moved.append(float(np.linalg.norm(b[:2] - a[:2])))
    drive = r.plan.index("end_move(mm)")          # the phase that ends with end_move
    assert moved[drive] > 0.5, moved


def test_the_reported_base_path_is_the_drive(field1):
    """`path_length` of the mobile base: the polyline through its [x, y] at every keyframe and
    waypoint in time order, recomputed here from the returned steps."""
    _, r = field1
    pts = []
    for st in r.steps:
        pts.append(st.values["q(mm)"][:2])
        pts.extend(w[:2] for w in st.trajectories.get("path(mm)", []))
    xy = np.array(pts)
    length = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
    assert r.path_length["mm"]["base"] == pytest.approx(length, rel=1e-9)
    assert r.path_length["arm1"]["base"] is None and r.path_length["mm"]["base"] > 0.5
