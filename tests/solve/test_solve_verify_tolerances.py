"""The verification's contact tolerances, on a real result: sort4 by R-LGP (seed 0, main at
30ca9d1) was returned `solved` with mm's right finger 0.14 mm inside red2, which already stood
in the tray. The loop's verification then allowed every pair the 1 mm resting tolerance; the
independent `tests/rebuilt_check.py` (meshes, `coal.collide`) rejected it. Now both hold one
contract: a robot link may go at most 0.1 mm (the solver's tolerance) into anything, objects
touch each other or the scene by up to 1 mm (docs/reference.md)."""
from __future__ import annotations

import json
import types
from pathlib import Path

import pytest

from gnppdsl import load_and_compile
from gnppdsl.solve.verify_solution import verify_solution
from rebuilt_check import check as rebuilt_check     # tests/rebuilt_check.py: no gnppdsl import

ROOT = Path(__file__).resolve().parents[2]
SORT4 = ROOT / "examples" / "mobile" / "sort4.pntc"
DATA = Path(__file__).parent / "data" / "sort4_finger_contact.json"


@pytest.fixture(scope="module")
def sort4():
    data = json.loads(DATA.read_text())
    steps = [types.SimpleNamespace(state=s["state"], values=s["values"], trajectories=s.get("trajectories", {}))
             for s in data["steps"]]
    return load_and_compile(str(SORT4)), types.SimpleNamespace(steps=steps, extras={}), data


def test_a_finger_0_14_mm_inside_a_block_fails_the_verification(sort4):
    c, result, _ = sort4
    rep = verify_solution(c.geometry, result, check_logic=False)
    assert not rep.ok
    [f] = rep.issues
    assert (f.kind, f.step, f.waypoint) == ("collision", 8, None)
    assert set(f.bodies) == {"red2", "mm/panda_rightfinger"}
    assert f.distance == pytest.approx(-1.38e-4, abs=2e-6)


def test_the_old_1_mm_tolerance_for_robot_links_would_pass_it(sort4):
    """What changed is the robot links' floor and nothing else: with the resting tolerance
    applied to them as before, the same result is clean."""
    c, result, _ = sort4
    assert verify_solution(c.geometry, result, check_logic=False, robot_margin=-1e-3).ok


def test_objects_still_touch_the_scene_by_up_to_1_mm(sort4):
    """red2 sunk into its tray: 0.5 mm is a resting contact (allowed), 2 mm a collision. The
    robot links' floor is set to the old 1 mm here to leave the finger out of it."""
    c, result, _ = sort4

    def sunk(depth: float) -> list:
        steps = [types.SimpleNamespace(**vars(s)) for s in result.steps]
        pose = list(steps[-1].values["pose(red2)"])
        pose[2] -= depth
        steps[-1].values = {**steps[-1].values, "pose(red2)": pose}
        rep = verify_solution(c.geometry, types.SimpleNamespace(steps=steps, extras={}),
                              check_logic=False, robot_margin=-1e-3)
        return [(f.kind, set(f.bodies)) for f in rep.issues]

    assert sunk(0.0005) == []
    assert ("collision", {"red2", "red_tray"}) in sunk(0.002)


def test_the_rebuilt_check_rejects_it_too_and_passes_it_within_its_tolerance(sort4, monkeypatch):
    import rebuilt_check as module

    _, _, data = sort4
    rep = rebuilt_check(data, SORT4)
    assert rep.failures == ["s8: mm/panda_rightfinger_3 collides with red2"], rep.failures
    monkeypatch.setattr(module, "CONTACT_TOLERANCE", 2e-4)
    assert rebuilt_check(data, SORT4).ok
