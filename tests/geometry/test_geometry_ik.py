"""Panda IK: reachable targets (from random configurations) are reached, checked with pinocchio."""
from __future__ import annotations

import numpy as np
import pinocchio as pin

from gnppdsl.geometry.ik import solve_ik
from gnppdsl.geometry.robots import load_robot
from gnppdsl.ir.scene_model import SceneRobot


def test_panda_ik_reaches_reachable_targets():
    robot = load_robot(SceneRobot("ikpanda", "urdf", model="panda", ee="panda_hand_tcp",
                                  base=(0.1, 0.2, 0.0, 0.0, 0.0, 0.0, 1.0)))
    rng = np.random.default_rng(0)
    data = robot.model.createData()
    fid = robot.model.getFrameId("panda_hand_tcp")
    solved = 0
    n = 20
    for i in range(n):
        qt = robot.random_coords(rng)
        pin.framesForwardKinematics(robot.model, data, robot.to_pin_q(qt))
        T = robot.base @ np.array(data.oMf[fid].homogeneous)
        res = solve_ik(robot, T, restarts=5, seed=i)
        if res is None:
            continue
        solved += 1
        # independent check of the returned configuration
        pin.framesForwardKinematics(robot.model, data, robot.to_pin_q(res.q))
        T2 = robot.base @ np.array(data.oMf[fid].homogeneous)
        assert np.linalg.norm(T2[:3, 3] - T[:3, 3]) < 1e-3
        assert np.abs(T2[:3, :3] - T[:3, :3]).max() < 2e-2
        assert np.all(res.q >= robot.lower - 1e-9) and np.all(res.q <= robot.upper + 1e-9)
    assert solved >= 18, solved          # timings: benchmarks/bench_geometry.py


def test_unreachable_target_returns_none():
    robot = load_robot(SceneRobot("ikpanda2", "urdf", model="panda", ee="panda_hand_tcp"))
    far = np.r_[3.0, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0]
    assert solve_ik(robot, far, restarts=2, seed=0) is None
