"""End to end on the Lab (two Panda arms): `solve` finds a plan whose every keyframe and
trajectory waypoint passes the independent pinocchio + coal verification; and the verification
itself rejects corrupted solutions (so a pass means something)."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.verify_solution import verify_solution
from rebuilt_check import check as rebuilt_check     # tests/rebuilt_check.py: no gnppdsl import

LAB = Path(__file__).resolve().parents[2] / "examples" / "lab"


def _solve(name: str, time_limit: float):
    c = load_and_compile(str(LAB / f"{name}.pntc"))
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=time_limit))
    return c, r


@pytest.fixture(scope="module")
def lab1():
    return _solve("lab1", 120)


def test_lab1_solved_and_verified(lab1):
    c, r = lab1
    assert r.status == "solved", r.message
    assert r.plan[-1].startswith("stack(b2")
    rep = verify_solution(c.geometry, r)
    assert rep.ok, str(rep)
    assert rep.keyframes == len(r.plan) + 1
    assert rep.waypoints == 18 * len(r.plan)          # interior waypoints of every motion


def _as_json(r) -> dict:
    return json.loads(json.dumps(r.to_json()))


def test_lab1_passes_the_rebuilt_constraint_check(lab1):
    """The second verifier (constraints rebuilt from the JSON, the scene YAML and the URDF,
    nothing from gnppdsl) agrees: every keyframe and the same waypoints as verify_solution."""
    c, r = lab1
    rep = rebuilt_check(_as_json(r), LAB / "lab1.pntc")
    assert rep.ok, str(rep)
    assert rep.keyframes == len(r.plan) + 1
    assert rep.waypoints == verify_solution(c.geometry, r).waypoints


def test_rebuilt_check_rejects_corrupted_solutions(lab1):
    """Each kind of failure the rebuilt check knows, triggered by one edit of the JSON."""
    _, r = lab1
    good = _as_json(r)
    last, held_at = len(good["steps"]) - 1, 1            # b2 held by left_arm at s1

    def failures(edit) -> list[str]:
        data = copy.deepcopy(good)
        edit(data)
        return rebuilt_check(data, LAB / "lab1.pntc").failures

    def sink(d):                                           # b2 3 cm into b1 at the end
        d["steps"][last]["values"]["pose(b2)"][2] -= 0.03
        d["steps"][last].pop("world", None)
    f = failures(sink)
    assert any("b1 and b2 overlap" in x or "b2 and b1 overlap" in x for x in f), f
    assert any("b2 does not rest on b1" in x for x in f), f

    def beyond(d):                                         # a waypoint past joint 4's upper limit
        d["steps"][0]["trajectories"]["path(left_arm)"][7][3] = 0.5
    assert any("waypoint 7" in x and "left_arm.panda_joint4" in x for x in failures(beyond))

    def slip(d):                                           # the held b2 20 cm off the fingers
        d["steps"][held_at]["values"]["pose(b2)"][0] += 0.2
    f = failures(slip)
    assert any(x.startswith(f"s{held_at}: left_arm's end effector is not inside b2") for x in f), f
    assert any(f"s{held_at}: the result's world pose of b2" in x for x in f), f

    def no_goal(d):
        d["steps"][last]["state"] = d["steps"][last]["state"].replace("parent(b2) = b1", "parent(b2) = table")
    assert any(x.startswith("goal parent(b2) = b1") for x in failures(no_goal))

    def dive(d):                                           # the hand through the table
        q = list(d["steps"][0]["values"]["q(left_arm)"])
        q[1], q[3] = 1.7, -0.2
        d["steps"][0]["trajectories"]["path(left_arm)"][10] = q
    assert any("waypoint 10: left_arm/" in x and "collides with table" in x for x in failures(dive))

    def fold(d):                                           # the hand folded back onto link 2, within the limits
        d["steps"][0]["trajectories"]["path(left_arm)"][5] = [0.0, -0.785, 0.0, -3.0, 0.0, 0.3, 0.785]
    f = failures(fold)
    assert "s0->s1 waypoint 5: left_arm/panda_link2_0 collides with left_arm/panda_hand_0 (self-collision)" in f, f
    assert not any("outside" in x for x in f), f          # no joint limit: the self-collision alone


def test_rebuilt_check_self_pairs_without_an_srdf():
    """Without an SRDF the rebuilt check keeps the link pairs at least two joints apart (adjacent
    links touch at their joint); the Panda's SRDF also removes pairs that never touch."""
    from rebuilt_check import _robot, _self_pairs

    rb = _robot("a", {"model": "panda", "ee": "panda_hand_tcp"}, [f"panda_joint{i}" for i in range(1, 8)])
    geom = rb.geom.copy()
    geom.removeAllCollisionPairs()
    name = lambda pairs: {(geom.geometryObjects[a].name, geom.geometryObjects[b].name) for a, b in pairs}  # noqa: E731
    plain, srdf = name(_self_pairs(rb.model, geom, None)), name(rb.self_pairs)
    for pairs in (plain, srdf):
        assert ("panda_link2_0", "panda_hand_0") in pairs and ("panda_link0_0", "panda_link5_0") in pairs
        assert ("panda_link1_0", "panda_link2_0") not in pairs and ("panda_link7_0", "panda_hand_0") not in pairs
        assert ("panda_leftfinger_0", "panda_leftfinger_1") not in pairs            # one link's meshes
    assert ("panda_link0_0", "panda_link2_0") in plain and ("panda_link0_0", "panda_link2_0") not in srdf  # "Never"
    assert ("panda_hand_0", "panda_leftfinger_0") not in plain                       # adjacent (finger joint)
    assert srdf < plain


def _corrupt(r, fn):
    bad = copy.deepcopy(r.steps)
    fn(bad)
    return type("R", (), {"steps": bad, "extras": r.extras})()


def test_verification_rejects_a_block_inside_another(lab1):
    c, r = lab1

    def move(steps):
        # b2 rests on b1 in the last state: sink it 3 cm into b1
        steps[-1].values["pose(b2)"][2] -= 0.03
    rep = verify_solution(c.geometry, _corrupt(r, move))
    assert not rep.ok
    assert any("collision" in f and "b2" in f for f in rep.failures)
    assert any("does not rest on b1" in f for f in rep.failures)


def test_verification_rejects_a_waypoint_beyond_joint_limits(lab1):
    c, r = lab1
    hi = c.geometry.robot("left_arm").upper

    def push(steps):
        steps[0].trajectories["path(left_arm)"][7][3] = float(hi[3]) + 0.2
    rep = verify_solution(c.geometry, _corrupt(r, push))
    assert any("waypoint 7: joint limit left_arm" in f for f in rep.failures), rep.failures


def test_verification_rejects_a_lost_grasp(lab1):
    c, r = lab1

    def slip(steps):
        # b2 is held at s1: shift its relative pose by 20 cm, out of the fingers
        steps[1].values["pose(b2)"][0] += 0.2
    rep = verify_solution(c.geometry, _corrupt(r, slip))
    assert any("grasp of b2 by left_arm" in f for f in rep.failures), rep.failures


def test_verification_rejects_a_trajectory_through_the_table(lab1):
    c, r = lab1
    q = np.asarray(r.steps[0].values["q(left_arm)"], float)

    def dive(steps):
        # shoulder pitched far forward: the hand goes through the table at an interior waypoint
        bad = q.copy()
        bad[1] = 1.7
        bad[3] = -0.2
        steps[0].trajectories["path(left_arm)"][10] = bad.tolist()
    rep = verify_solution(c.geometry, _corrupt(r, dive))
    assert any("waypoint 10: collision" in f for f in rep.failures), rep.failures


def test_verification_rejects_a_result_without_steps(lab1):
    c, r = lab1
    rep = verify_solution(c.geometry, _corrupt(r, lambda steps: steps.clear()))
    assert not rep.ok and rep.failures == ["no steps in the result"]


def test_verification_rejects_a_path_that_does_not_start_at_its_keyframe(lab1):
    c, r = lab1

    def shift(steps):
        steps[0].trajectories["path(left_arm)"][0][0] += 0.05     # 0.05 rad off q(left_arm) at s0
    rep = verify_solution(c.geometry, _corrupt(r, shift))
    assert "path s0->s1: left_arm waypoint 0 is not the keyframe configuration" in rep.failures, rep.failures


def test_verification_rejects_a_keyframe_beyond_joint_limits(lab1):
    c, r = lab1
    hi = c.geometry.robot("left_arm").upper

    def push(steps):
        steps[1].values["q(left_arm)"][5] = float(hi[5]) + 0.3
    rep = verify_solution(c.geometry, _corrupt(r, push))
    assert any(f.startswith("s1: joint limit left_arm") for f in rep.failures), rep.failures


def test_verification_rejects_an_invalid_plan_and_a_missing_one(lab1):
    c, r = lab1
    ops = tuple(r.extras["plan"].operators)
    assert len(ops) >= 2
    swapped = type("R", (), {"steps": r.steps, "extras": {**r.extras, "plan": ops[::-1]}})()
    rep = verify_solution(c.geometry, swapped)
    assert any(f.kind == "plan" and "is not applicable" in f.detail for f in rep.issues), rep.failures
    bare = type("R", (), {"steps": r.steps, "extras": {}})()
    rep = verify_solution(c.geometry, bare)
    assert "no task / plan in the result to validate the logic" in rep.failures
    assert verify_solution(c.geometry, bare, check_logic=False).ok


def test_verification_rejects_a_block_floating_above_its_support(lab1):
    c, r = lab1

    def lift(steps):
        steps[0].values["pose(b1)"][2] += 0.02       # b1 on the table at s0: 2 cm in the air
    rep = verify_solution(c.geometry, _corrupt(r, lift))
    assert any(f.kind == "placement" and f.step == 0 and f.detail.startswith("b1 does not rest on")
               for f in rep.issues), rep.failures


@pytest.mark.slow
@pytest.mark.parametrize("name", ["lab2", "lab3", "lab4", "lab5"])
def test_lab_problem_solved_and_verified(name):
    c, r = _solve(name, 600)
    assert r.status == "solved", r.message
    rep = verify_solution(c.geometry, r)
    assert rep.ok, str(rep)
    rebuilt = rebuilt_check(_as_json(r), LAB / f"{name}.pntc")
    assert rebuilt.ok, str(rebuilt)
