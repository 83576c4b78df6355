"""The Lab domain keeps the Panda fingers off objects and the table at every keyframe
(`panda.clear_gripper`), the pairs the independent verification checks there.

Why: the verification (`verify_solution`) checks every link pair at keyframes, while the domain
used to constrain only links 5, 6 and the hand there; Lab 5 seed 0 then produced a solution with
a finger 5.4 mm inside a resting obstacle. These tests check the domain's factors against the
verification on a solved Lab 1 plan: coverage of every (keyframe, arm, object) pair, and a
finger pushed into a resting block (hand and wrist still clear) is a violation of the domain's
factor AND a verification failure, while the rows of the old `clear_object` (links 5, 6, hand)
do not see it."""
from __future__ import annotations

import copy
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.geometry.robots import matrix_to_se3, se3_to_matrix
from gnppdsl.nlp.evaluate import constraint_rows, factor_violation
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.verify_solution import verify_solution

LAB = Path(__file__).resolve().parents[2] / "examples" / "lab"


@pytest.fixture(scope="module")
def lab1():
    c = load_and_compile(str(LAB / "lab1.pntc"))
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=120))
    assert r.status == "solved", r.message
    return c, r


def _gripper_factors(graph):
    """(step, arm, object) -> the clear_gripper factor (rule arm_table names the table constant
    in its template call, not in a pattern variable)."""
    out = {}
    for f in graph.factor_instances:
        if f.template == "panda.clear_gripper":
            b = dict(f.bindings)
            out[(f.step, b["r"], b.get("o", "table" if f.rule == "arm_table" else None))] = f
    return out


def test_every_keyframe_keeps_the_gripper_off_every_object(lab1):
    c, r = lab1
    graph = r.extras["graph"]
    have = set(_gripper_factors(graph))
    arms = ["left_arm", "right_arm"]
    objects = ["b1", "b2", "table"]            # the blocks lab1 declares, and the table
    want = {(i, a, o) for i in range(len(r.steps)) for a in arms for o in objects}
    assert want <= have, sorted(want - have)
    # the solution keeps every finger off every object at every keyframe (independent check)
    rep = verify_solution(c.geometry, r)
    assert rep.ok, str(rep)


def test_a_finger_in_a_resting_block_violates_the_domain_and_the_verification(lab1):
    c, r = lab1
    graph, values = r.extras["graph"], dict(r.extras["values"])
    ctx = c.geometry
    step = 1                                   # left_arm holds b2, b1 rests on the table
    assert "parent(b1) = table" in r.steps[step].state
    q = np.asarray(r.steps[step].values["q(left_arm)"], float)
    T_tcp = ctx.fk_matrix("left_arm", q, "panda_hand_tcp")
    # b1 aligned with the tcp frame (Panda collision model, tcp frame: left finger at
    # y 0.040..0.066, z -0.045..0.0095; the hand at z <= -0.0374): b1's face 3 mm inside the
    # left finger along y, its near face 1.2 cm beyond the hand's lowest face along z.
    local = np.eye(4)
    local[:3, 3] = [0.0, 0.063 + 0.075, -0.025 + 0.045]
    T_b1 = T_tcp @ local
    T_table = se3_to_matrix(np.asarray(ctx.scene.objects["table"].pose, float))
    rel = matrix_to_se3(np.linalg.inv(T_table) @ T_b1)

    pose_b1 = next(v for v in graph.variables if v.key == "pose(b1)" and v.step == step)
    values[pose_b1] = np.asarray(rel, float)
    f = _gripper_factors(graph)[(step, "left_arm", "b1")]
    rows = [h for _, h in constraint_rows(f, values, ctx)]
    assert len(rows) == 6                      # links 5, 6, hand, left finger, right finger, 7
    assert max(rows[:3]) <= 0.0, rows          # clear_object's rows hold: they miss the finger
    assert 0.002 < factor_violation(f, values, ctx) < 0.004, rows

    steps = copy.deepcopy(r.steps)
    steps[step].values["pose(b1)"] = list(map(float, rel))
    bad = type("R", (), {"steps": steps, "extras": r.extras})()
    rep = verify_solution(ctx, bad)
    assert not rep.ok
    assert any(f"s{step}: collision" in x and "b1" in x and "left_arm/panda_leftfinger" in x
               for x in rep.failures), rep.failures


def test_link7_inside_a_block_violates_the_keyframe_factor_and_the_verification(lab1):
    """Link 7 is a keyframe collision body of `clear_gripper` (the verification found it 3.6 mm
    inside o1 at a Lab 5 keyframe when only links 5, 6 and the hand were): a block moved onto
    link 7 violates the factor's link-7 row, and the independent verification reports the
    same contact."""
    c, r = lab1
    graph, values = r.extras["graph"], dict(r.extras["values"])
    ctx = c.geometry
    step = 1
    assert "parent(b1) = table" in r.steps[step].state
    q = np.asarray(r.steps[step].values["q(left_arm)"], float)
    T_link7 = ctx.fk_matrix("left_arm", q, "panda_link7")
    T_table = se3_to_matrix(np.asarray(ctx.scene.objects["table"].pose, float))
    centre, _ = ctx.body(("link", "left_arm", "panda_link7")).bounding_sphere()
    local = np.eye(4)
    local[:3, 3] = centre                      # b1 centred on link 7's collision hull
    rel = matrix_to_se3(np.linalg.inv(T_table) @ T_link7 @ local)
    pose_b1 = next(v for v in graph.variables if v.key == "pose(b1)" and v.step == step)
    values[pose_b1] = np.asarray(rel, float)
    f = _gripper_factors(graph)[(step, "left_arm", "b1")]
    rows = [h for _, h in constraint_rows(f, values, ctx)]
    assert rows[5] > 0.0, rows                 # the link-7 row: b1 overlaps link 7
    steps = copy.deepcopy(r.steps)
    steps[step].values["pose(b1)"] = list(map(float, rel))
    bad = type("R", (), {"steps": steps, "extras": r.extras})()
    rep = verify_solution(ctx, bad)
    assert any(f"s{step}: collision" in x and "b1" in x and "left_arm/panda_link7" in x
               for x in rep.failures), rep.failures
