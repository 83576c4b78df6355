"""Forward kinematics as casadi expressions vs pinocchio's own forward kinematics."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pinocchio as pin
import pytest

from gnppdsl.errors import UserError
from gnppdsl.geometry.kinematics import (fk_function, fk_rp_function, quat_to_rotation, rotation_to_quat,
                                         rotation_to_quat_numeric)
from gnppdsl.geometry.robots import load_robot, matrix_to_se3, se3_to_matrix
from gnppdsl.ir.scene_model import SceneRobot

BASE = (0.3, -0.2, 0.1, 0.0, 0.0, np.sin(0.35), np.cos(0.35))

ROBOTS = {
    # name: (SceneRobot, frames to check or None = every frame)
    "panda": (SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp", base=BASE), None),
    "ur5": (SceneRobot("ur", "urdf", model="ur5", ee="ee_link"), None),
    # continuous joints (RUBZ: pinocchio stores cos/sin, planner coordinates are angles)
    "kinova": (SceneRobot("kin", "urdf", model="kinova"), None),
    # revolute joints about unaligned axes, prismatic torso, continuous joints
    "pr2": (SceneRobot("pr2", "urdf", model="pr2"), ["r_gripper_palm_link", "l_gripper_palm_link", "head_tilt_link",
                                                      "r_forearm_link", "l_wrist_roll_link", "torso_lift_link"]),
    # mobile manipulator: planar root joint (x, y, theta) + Panda arm
    "mobile_panda": (SceneRobot("mob", "urdf", model="panda", ee="panda_hand_tcp",
                                attributes={"base_joint": "planar"}), None),
}


def _pin_frames(robot, c, base):
    data = robot.model.createData()
    q = robot.to_pin_q(c)
    pin.framesForwardKinematics(robot.model, data, q)
    B = se3_to_matrix(base)
    return {i: B @ np.array(data.oMf[i].homogeneous) for i in range(robot.model.nframes)}


@pytest.mark.parametrize("key", list(ROBOTS))
def test_fk_matches_pinocchio(key):
    spec, frames = ROBOTS[key]
    robot = load_robot(spec)
    names = frames or [f.name for f in robot.model.frames if f.name != "universe"]
    # duplicate frame names are possible in URDFs: check by id of the first match, as fk does
    rng = np.random.default_rng(7)
    funcs = {n: (fk_rp_function(robot, n), fk_function(robot, n)) for n in names}
    worst = 0.0
    base = np.array(spec.base, dtype=float)
    for _ in range(100):
        c = robot.random_coords(rng)
        ref = _pin_frames(robot, c, base)
        for n, (f_rp, f_vec) in funcs.items():
            T = ref[robot.model.getFrameId(n)]
            R, p = f_rp(c, base)
            v = np.array(f_vec(c, base)).ravel()
            worst = max(worst, np.abs(np.array(R) - T[:3, :3]).max(), np.abs(np.array(p).ravel() - T[:3, 3]).max(),
                        np.abs(se3_to_matrix(v) - T).max())
    assert worst < 1e-9, worst


def test_coordinates_roundtrip_and_limits():
    robot = load_robot(ROBOTS["mobile_panda"][0])
    assert robot.nc == 10 and robot.model.nq == 11       # planar root: 3 coords, 4 pinocchio q
    assert robot.coords[0].kind == "planar"
    assert np.isinf(robot.lower[2]) and np.isinf(robot.upper[2]) and np.isinf(robot.lower[0])
    bounded = load_robot(SceneRobot("mob2", "urdf", model="panda", ee="panda_hand_tcp",
                                    attributes={"base_joint": "planar", "base_min": [-2, -1], "base_max": [2, 1.5]}))
    np.testing.assert_allclose(bounded.lower[:3], [-2, -1, -np.inf])
    np.testing.assert_allclose(bounded.upper[:3], [2, 1.5, np.inf])
    assert "panda_link0" not in bounded.fixed_links and "panda_link0" in load_robot(ROBOTS["panda"][0]).fixed_links
    rng = np.random.default_rng(1)
    c = robot.random_coords(rng)
    np.testing.assert_allclose(robot.from_pin_q(robot.to_pin_q(c)), c, atol=1e-12)
    panda = load_robot(ROBOTS["panda"][0])
    assert panda.nc == 7        # fingers locked
    np.testing.assert_allclose(panda.lower, panda.model.lowerPositionLimit)


def test_quaternion_roundtrip_has_exact_derivative():
    """rotation -> quaternion -> rotation is the identity on SO(3), and so is its derivative along
    rotations, in every branch of Shepperd's method (random rotations hit all four)."""
    w = ca.SX.sym("w", 3)
    R0 = ca.SX.sym("R0", 3, 3)
    rng = np.random.default_rng(3)
    # rotation by angle vector w applied to R0, via Rodrigues
    th = ca.sqrt(ca.sumsqr(w) + 1e-30)
    K = ca.skew(w) / th
    Rw = ca.mtimes(R0, ca.DM.eye(3) + ca.sin(th) * K + (1 - ca.cos(th)) * ca.mtimes(K, K))
    back = quat_to_rotation(rotation_to_quat(Rw))
    f = ca.Function("f", [w, R0], [ca.reshape(back, 9, 1), ca.jacobian(ca.reshape(back, 9, 1), w),
                                   ca.jacobian(ca.reshape(Rw, 9, 1), w)])
    for _ in range(200):
        q = rng.normal(size=4)
        R0v = se3_to_matrix(np.r_[0, 0, 0, q])[:3, :3]
        wv = rng.normal(size=3) * 1e-3
        val, J1, J2 = f(wv, R0v)
        np.testing.assert_allclose(np.array(J1), np.array(J2), atol=1e-8)
    # the numeric converters agree with each other
    q = rng.normal(size=4)
    v = np.r_[1, 2, 3, q / np.linalg.norm(q)]
    np.testing.assert_allclose(se3_to_matrix(matrix_to_se3(se3_to_matrix(v))), se3_to_matrix(v), atol=1e-12)


def test_bad_inputs_raise_user_errors():
    with pytest.raises(UserError, match="unknown robot model"):
        load_robot(SceneRobot("x", "urdf", model="pandaa"))
    with pytest.raises(UserError, match="did you mean 'panda_hand_tcp'"):
        load_robot(SceneRobot("y", "urdf", model="panda", ee="panda_hand_tpc"))
    with pytest.raises(UserError, match="not found"):
        load_robot(SceneRobot("z", "urdf", urdf="/nonexistent/robot.urdf"))
    robot = load_robot(ROBOTS["panda"][0])
    with pytest.raises(UserError, match="no frame"):
        fk_function(robot, "panda_link99")


def test_numeric_quaternion_twin_matches_casadi():
    """Same rotation -> the same quaternion (sign included) from casadi and from numpy, in every
    branch, including 180-degree rotations (a Panda top grasp)."""
    R = ca.SX.sym("R", 3, 3)
    f = ca.Function("f", [R], [rotation_to_quat(R)])
    rng = np.random.default_rng(4)
    mats = [se3_to_matrix(np.r_[0, 0, 0, q])[:3, :3] for q in rng.normal(size=(300, 4))]
    mats += [np.diag([1.0, -1.0, -1.0]), np.diag([-1.0, 1.0, -1.0]), np.diag([-1.0, -1.0, 1.0]), np.eye(3)]
    for M in mats:
        q = rotation_to_quat_numeric(M)
        np.testing.assert_allclose(np.array(f(M)).ravel(), q, atol=1e-12)
        np.testing.assert_allclose(se3_to_matrix(np.r_[0, 0, 0, q])[:3, :3], M, atol=1e-12)
