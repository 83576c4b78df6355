"""The Workshop scenario (paper 000, Table I): four Pandas and a stick that pushes blocks.

Oracles independent of the code under test:
- reach (the claims N > N0 rests on): pinocchio IK on the scene's robots, written here (the Lab's
  damped least-squares helper), not gnppdsl.geometry;
- the tool templates of stdlib/tools.pntc: their rows, evaluated by the project's numpy
  re-check interpreter on the compiled factors, equal the numbers computed here by hand with
  pinocchio forward kinematics and numpy transforms (block-frame displacement, height change,
  rotation between the two keyframes; the tip's offset on the block's face);
- end to end (GNPP_SLOW): Work_1 solved, verified by the independent pinocchio + coal
  verification, and the push re-checked from the returned numbers alone.
N0 of every problem is checked against Fast Downward by tests/compile/test_compile_examples.py.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_reference import EXAMPLES, raw_scene  # noqa: E402
from test_examples_lab_reach import DATA, MODEL, TCP, _ik  # noqa: E402

WORK = EXAMPLES / "workshop"
SCENE = raw_scene(WORK / "work4.yaml")
SCENE5 = raw_scene(WORK / "work5.yaml")
ARMS = ("arm_s", "arm_n", "arm_w", "arm_e")
PLAN1 = "pick(stick, arm_s, table); push(b1, stick, arm_s); take(b1, arm_n, stick); put(b1, arm_n, pad_n)"


def _base(arm: str) -> pin.SE3:
    b = SCENE["robots"][arm]["base"]
    return pin.SE3(pin.rpy.rpyToMatrix(*b["rpy"]), np.array(b["xyz"], float))


def _tcp(arm: str, q) -> np.ndarray:
    pin.framesForwardKinematics(MODEL, DATA, np.asarray(q, float))
    return (_base(arm) * DATA.oMf[TCP]).homogeneous


TOP = np.column_stack([[0, 1, 0], [1, 0, 0], [0, 0, -1]]).astype(float)
"""A top grasp of a block (or the stick pointing along y) whose x axis is world x: tcp z down,
fingers (tcp y) along world x."""


def _ik_error(arm: str, target, top: bool) -> float:
    """The Lab's IK helper on the Workshop's robots (position only, or a top grasp)."""
    return _ik(arm, target, TOP if top else None, restarts=10, scene=SCENE)


def _xyz(scene, name):
    return scene["objects"][name]["pose"]["xyz"]


# ---- reach: why N > N0 ---------------------------------------------------------------------------
def test_blocks_in_the_middle_are_out_of_every_hand_reach():
    for scene, names in ((SCENE, ("b1",)), (SCENE5, ("b1", "b2"))):
        for b in names:
            for arm in ARMS:
                assert _ik_error(arm, _xyz(scene, b), top=False) > 0.05, (b, arm)


def test_the_other_blocks_and_the_pads_are_reached_by_their_arm():
    for arm, target in (("arm_w", "b2"), ("arm_e", "b3"), ("arm_s", "b4"), ("arm_n", "pad_n"),
                        ("arm_n", "pad_n2"), ("arm_w", "pad_w"), ("arm_e", "pad_e"), ("arm_s", "pad_s")):
        p = np.array(_xyz(SCENE, target), float)
        p[2] = 0.64
        assert _ik_error(arm, p, top=True) < 1e-4, (arm, target)


def test_a_pushed_block_comes_into_arm_n_reach_and_the_stick_reaches_the_middle():
    """b1 pushed 0.3 m towards arm_n is reached by arm_n (top grasp); the hand of arm_s holding
    the 0.8 m stick 0.7 m behind its end reaches both ends of that push (the stick's end on b1's
    face before, 0.3 m further after)."""
    assert _ik_error("arm_n", [0.0, 0.3, 0.64], top=True) < 1e-4
    face = -0.025                                   # b1's -y face, b1 at the table's centre
    for y in (face - 0.7, face + 0.3 - 0.7):
        assert _ik_error("arm_s", [0.0, y, 0.655], top=True) < 1e-4


# ---- the tool templates, against a hand computation ------------------------------------------------
@pytest.fixture(scope="module")
def work1_factors():
    import gnppdsl.ir as ir
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.solve.compiled import compile_problem

    c = compile_problem(ir.load_problem(WORK / "work1.pntc"))
    states = plan_states(c.task, parse_plan(c.task, PLAN1))
    return c, {f.template: f for f in c.factory.factors(states) if f.template.startswith("tools.")}


def _se3(T: np.ndarray) -> list[float]:
    q = pin.Quaternion(T[:3, :3]).coeffs()          # x, y, z, w
    return [*T[:3, 3], *q]


def _mat(v) -> np.ndarray:
    return pin.XYZQUATToSE3(np.asarray(v, float)).homogeneous


def _values(f, by_key: dict):
    return {v: np.asarray(by_key[(v.kind, v.args[0], v.step)], float) for v in f.variables}


def _rows(c, f, by_key):
    from gnppdsl.nlp.evaluate import constraint_rows
    return np.array([h for _, h in constraint_rows(f, _values(f, by_key), c.geometry)])


def _yaw(a: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = pin.rpy.rpyToMatrix(0, 0, a)
    return T


def test_tip_contact_rows_are_the_offsets_from_the_face(work1_factors):
    """b1's pose relative to the stick (its parent while pushed): on the face at 0.425 m (half
    the stick's 0.8 plus half the block's 0.05) satisfies every row; 2 mm further, or turned by
    3 degrees, violates exactly the face row / the rotation rows by that much."""
    from gnppdsl.nlp.evaluate import factor_violation
    c, fs = work1_factors
    f = fs["tools.tip_contact"]
    ok = [0.004, 0.425, -0.01, 0, 0, 0, 1]
    assert factor_violation(f, _values(f, {("pose", "b1", 2): ok}), c.geometry) < 1e-12
    far = list(ok)
    far[1] += 0.002
    assert factor_violation(f, _values(f, {("pose", "b1", 2): far}), c.geometry) == pytest.approx(0.002, abs=1e-12)
    turned = _se3(_mat(ok) @ _yaw(np.radians(3)))
    assert factor_violation(f, _values(f, {("pose", "b1", 2): turned}), c.geometry) == \
        pytest.approx(np.sin(np.radians(1.5)), rel=1e-9)
    low = list(ok)
    low[2] = 0.021                                   # the stick 1 mm lower than tip_lift allows
    assert factor_violation(f, _values(f, {("pose", "b1", 2): low}), c.geometry) == pytest.approx(0.001, abs=1e-12)


def test_push_motion_rows_match_the_hand_computed_displacement(work1_factors):
    """Keyframes 2 (b1 on the stick's end, arm_s holds the stick) and 3 (arm_n holds b1): b1's
    world poses from pinocchio FK and numpy; the rows are b1's displacement in its own frame
    (sideways: 0 wanted; forward: >= 0), its height change and the vector part of its rotation
    change, whatever the joint values."""
    c, fs = work1_factors
    f = fs["tools.push_motion"]
    rng = np.random.default_rng(3)
    home = np.array(SCENE["robots"]["arm_s"]["home"], float)
    q_s = home + rng.normal(0, 0.2, 7)
    q_n = home + rng.normal(0, 0.2, 7)
    stick = _se3(_yaw(0.3) @ np.array([[1, 0, 0, 0], [0, 1, 0, -0.3], [0, 0, 1, 0], [0, 0, 0, 1.0]]))
    W2 = _yaw(0.7)
    W2[:3, 3] = [0.0, 0.0, 0.64]                     # b1 upright at the centre, yaw 0.7 rad
    b1_2 = _se3(np.linalg.inv(_tcp("arm_s", q_s) @ _mat(stick)) @ W2)
    step = np.eye(4)
    step[:3, 3] = [0.003, 0.2, 0.001]                # in b1's frame: 3 mm sideways, 0.2 m ahead, 1 mm up
    W3 = W2 @ step @ _yaw(np.radians(2))
    b1_3 = _se3(np.linalg.inv(_tcp("arm_n", q_n)) @ W3)
    by_key = {("q", "arm_s", 2): q_s, ("pose", "stick", 2): stick, ("pose", "b1", 2): b1_2,
              ("q", "arm_n", 3): q_n, ("pose", "b1", 3): b1_3}
    rows = _rows(c, f, by_key)
    assert rows[:3] == pytest.approx([0.003, -0.2, 0.001], abs=1e-9)       # >= row as 0 - 0.2
    s = np.sin(np.radians(1.0))
    assert np.allclose(rows[3:], [0, 0, s], atol=1e-9) or np.allclose(rows[3:], [0, 0, -s], atol=1e-9)
    # a pure push (straight ahead, no turn, same height) satisfies every row
    W3 = W2 @ np.array([[1, 0, 0, 0], [0, 1, 0, 0.25], [0, 0, 1, 0], [0, 0, 0, 1.0]])
    by_key[("pose", "b1", 3)] = _se3(np.linalg.inv(_tcp("arm_n", q_n)) @ W3)
    rows = _rows(c, f, by_key)
    assert np.abs(rows[[0, 2, 3, 4, 5]]).max() < 1e-9 and rows[1] == pytest.approx(-0.25, abs=1e-9)


def test_push_path_rows_are_the_block_heights_along_the_motion(work1_factors):
    """Along arm_s's motion (waypoints 1..18 of a path between two configurations) b1 rides at
    a fixed pose on the stick; the rows are its height at each waypoint minus at keyframe 2
    (pinocchio FK here) and the tilt of its z axis against 1 - upright_tol."""
    c, fs = work1_factors
    f = fs["tools.push_path"]
    home = np.array(SCENE["robots"]["arm_s"]["home"], float)
    qa, qb = home, home + np.array([0.3, 0.2, -0.1, 0.2, 0.1, -0.2, 0.3])
    path = np.array([qa + t * (qb - qa) for t in np.linspace(0, 1, 20)])
    stick = [0, -0.3, 0, 0, 0, 0, 1]
    b1 = [0, 0.425, 0, 0, 0, 0, 1]
    chain = lambda q: _tcp("arm_s", q) @ _mat(stick) @ _mat(b1)      # noqa: E731
    rows = _rows(c, f, {("path", "arm_s", 2): path.ravel(), ("pose", "stick", 2): stick,
                        ("pose", "b1", 2): b1, ("q", "arm_s", 2): qa})
    z0 = chain(qa)[2, 3]
    heights = [chain(q)[2, 3] - z0 for q in path[1:-1]]
    tilts = [1 - 5e-5 - chain(q)[2, 2] for q in path[1:-1]]
    assert rows[0::2] == pytest.approx(heights, abs=1e-9)
    assert rows[1::2] == pytest.approx(tilts, abs=1e-9)


# ---- end to end ---------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def work1_solved():
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile(str(WORK / "work1.pntc"))
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=600, seed=0))
    return c, r


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("GNPP_SLOW"), reason="slow end-to-end test (GNPP_SLOW=1)")
def test_work1_pushes_and_is_verified(work1_solved):
    from gnppdsl.solve.verify_solution import verify_solution
    c, r = work1_solved
    assert r.status == "solved", r.message
    assert (r.stats.N0, r.stats.N) == (2, 4)
    assert r.plan[0].startswith("pick(stick, arm_s") and r.plan[1] == "push(b1, stick, arm_s)"
    rep = verify_solution(c.geometry, r)
    assert rep.ok, str(rep)
    # the second verifier (no gnppdsl import): b1 rides on the stick and follows it along the push
    import copy
    import json

    sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
    from rebuilt_check import check as rebuilt_check
    data = json.loads(json.dumps(r.to_json()))
    rebuilt = rebuilt_check(data, WORK / "work1.pntc")
    assert rebuilt.ok and rebuilt.keyframes == rep.keyframes, str(rebuilt)
    # ... and finds b1 off the stick's end when its pose on the stick is moved 1 cm ahead
    moved = copy.deepcopy(data)
    pushed = next(st for st in moved["steps"] if "parent(b1) = stick" in st["state"])
    pushed["values"]["pose(b1)"][1] += 0.01
    pushed.pop("world", None)
    assert any("b1 rides on stick 10.0 mm away" in f for f in rebuilt_check(moved, WORK / "work1.pntc").failures)


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("GNPP_SLOW"), reason="slow end-to-end test (GNPP_SLOW=1)")
def test_work1_push_from_the_returned_numbers(work1_solved):
    """From the returned joint values and relative poses alone (pinocchio FK, numpy): b1 rides
    on the stick's end between the push and the take, moves straight ahead along its own +y
    axis by enough to come into arm_n's reach, keeps its height and yaw, and stays at its height
    along arm_s's pushing motion."""
    _, r = work1_solved
    i = r.plan.index("push(b1, stick, arm_s)") + 1           # keyframe of the push
    st, nx = r.steps[i], r.steps[i + 1]
    v = lambda s, k: np.asarray(s.values[k], float)          # noqa: E731
    stick_w = _tcp("arm_s", v(st, "q(arm_s)")) @ _mat(v(st, "pose(stick)"))
    W2 = stick_w @ _mat(v(st, "pose(b1)"))
    holder = nx.state.split("parent(b1) = ")[1].split()[0].strip(",")
    W3 = _tcp(holder, v(nx, f"q({holder})")) @ _mat(v(nx, "pose(b1)"))
    rel = np.linalg.inv(stick_w) @ W2
    assert rel[1, 3] == pytest.approx(0.425, abs=1e-5) and abs(rel[0, 3]) <= 0.01 + 1e-5
    d = np.linalg.inv(W2) @ W3
    assert abs(d[0, 3]) < 1e-5 and d[1, 3] > 0.2 and abs(W3[2, 3] - W2[2, 3]) < 1e-5
    assert np.allclose(d[:3, :3], np.eye(3), atol=1e-4)
    assert np.linalg.norm(W3[:2, 3] - np.array(SCENE["robots"]["arm_n"]["base"]["xyz"][:2])) < 0.9
    path = np.asarray(st.trajectories["path(arm_s)"], float)
    for q in path[1:-1]:
        z = (_tcp("arm_s", q) @ _mat(v(st, "pose(stick)")) @ _mat(v(st, "pose(b1)")))[2, 3]
        assert z == pytest.approx(W2[2, 3], abs=1e-5)


# ---- the verification of a pushed block ------------------------------------------------------------
def _riding_failures(c, rel, lift=0.0):
    """The verification's placement failures of one keyframe where arm_s (at home) holds the
    stick and b1 rides on its end at `rel` (b1's pose relative to the stick), b1's world pose
    upright at the table's centre `lift` above the table."""
    return [str(f) for f in _riding_report(c, rel, lift).issues if f.kind == "placement"]


def _riding_report(c, rel, lift=0.0):
    """The verification's report of that keyframe (`_riding_failures`)."""
    from types import SimpleNamespace

    from gnppdsl.solve.result import Step
    from gnppdsl.solve.verify_solution import verify_solution

    q_s = np.array(SCENE["robots"]["arm_s"]["home"], float)
    W = np.eye(4)
    W[:3, 3] = [0, 0, 0.64 + lift]
    stick = np.linalg.inv(_tcp("arm_s", q_s)) @ W @ np.linalg.inv(_mat(rel))
    state = "parent(b1) = stick, parent(stick) = arm_s, holding(arm_s) = stick"
    step = Step(0, None, state, values={"q(arm_s)": list(q_s), "pose(stick)": _se3(stick), "pose(b1)": list(rel)})
    return verify_solution(c.geometry, SimpleNamespace(steps=[step]), check_logic=False)


def test_the_verification_checks_a_pushed_block_touches_the_stick_and_the_table(work1_factors):
    c, _ = work1_factors
    assert _riding_failures(c, [0.004, 0.425, -0.01, 0, 0, 0, 1]) == []
    far = _riding_failures(c, [0.004, 0.431, -0.01, 0, 0, 0, 1])
    assert len(far) == 1 and "rides on stick 0.0060 away" in far[0]
    lifted = _riding_failures(c, [0.004, 0.425, -0.01, 0, 0, 0, 1], lift=0.01)
    assert len(lifted) == 1 and "rests on no static body" in lifted[0]


def test_the_active_set_leaves_a_pushed_blocks_sliding_contact_with_the_table_to_the_push_rows(work1_factors):
    """The verification names the static body a riding block rests on (`SolutionReport.riding`),
    and the active set adds no row for that pair on the keyframe or the motion that starts there
    (a signed distance at 0 along the push: it stalled the repair of Work_1's push at 1e-4), but
    keeps the block's other near pairs, and the pair where the block does not ride."""
    from types import SimpleNamespace

    from gnppdsl.solve.active_set import near_pairs
    from gnppdsl.solve.verify_solution import SolutionReport

    c, _ = work1_factors
    assert _riding_report(c, [0.004, 0.425, -0.01, 0, 0, 0, 1]).riding == {(0, "b1"): ("table",)}
    assert _riding_report(c, [0.004, 0.425, -0.01, 0, 0, 0, 1], lift=0.01).riding == {(0, "b1"): ()}
    riding = SimpleNamespace(state="parent(b1) = stick, parent(stick) = arm_s")
    resting = SimpleNamespace(state="parent(b1) = table, parent(stick) = arm_s")
    result = SimpleNamespace(steps=[riding, riding, resting])
    near = [(0, None, "b1", "table", -1e-4), (0, 8.0, "table", "b1", -1e-4),
            (0, 8.0, "b1", "arm_n/panda_hand", 0.002), (1, 3.0, "table", "b1", -1e-4),
            (2, 3.0, "b1", "pad_n", 0.001)]
    rep = SolutionReport(ok=False, near=list(near), riding={(0, "b1"): ("table",), (1, "b1"): ()})
    assert near_pairs(result, rep.near, rep.riding) == [near[2], near[3], near[4]]
    assert near_pairs(result, list(near)) == near


@pytest.mark.slow
@pytest.mark.skipif(not os.environ.get("GNPP_SLOW"), reason="slow end-to-end test (GNPP_SLOW=1)")
def test_work1_learns_the_reach_of_every_arm_from_one_plan(work1_solved):
    """b1 lies out of every hand's reach (the IK oracle above). The first conflict about picking
    it from the table (a 2-action plan's graph: 136 factors, below `batch_min_factors` but above
    `batch_min_keyframe_factors` per keyframe) brings the other three arms with it as
    batch-learned instances, instead of one arm per plan; the stick, which arm_s reaches, is
    never forbidden to arm_s. (Lazy batch, the default: the renamings are decided when the
    second plan picks b1 with another arm, a conflict without that plan's graph-NLP, and then
    all at once.)"""
    _, r = work1_solved
    assert r.status == "solved", r.message
    for arm in ARMS:
        assert _ik_error(arm, _xyz(SCENE, "b1"), top=False) > 0.05, arm
    reach = [c for c in r.conflicts if c.text.startswith("{parent(b1) = table, not moved(b1)} -> {parent(b1) = arm_")]
    assert len(reach) <= 2 and (len(reach) == 1 or reach[1].source == "batch"), [c.text for c in reach]
    named = {a for c in reach for t in (c.text, *c.instances, *c.batched) for a in ARMS if f"= {a}}}" in t}
    assert named == set(ARMS), [(c.text, c.batched) for c in reach]
    learned = [t for c in r.conflicts for t in (c.text, *c.instances, *c.batched)]
    assert "{parent(stick) = table, not moved(stick)} -> {parent(stick) = arm_s}" not in learned
    assert r.plan[0] == "pick(stick, arm_s, table)"
