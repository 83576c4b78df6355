"""Panda IK: reachable targets (from random configurations) are reached, checked with pinocchio."""
from __future__ import annotations

import time

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
    solved, times, attempts = 0, [], []
    n = 20
    for i in range(n):
        qt = robot.random_coords(rng)
        pin.framesForwardKinematics(robot.model, data, robot.to_pin_q(qt))
        T = robot.base @ np.array(data.oMf[fid].homogeneous)
        t0 = time.perf_counter()
        res = solve_ik(robot, T, restarts=5, seed=i)
        times.append(time.perf_counter() - t0)
        if res is None:
            continue
        solved += 1
        attempts.append(res.attempts)
        # independent check of the returned configuration
        pin.framesForwardKinematics(robot.model, data, robot.to_pin_q(res.q))
        T2 = robot.base @ np.array(data.oMf[fid].homogeneous)
        assert np.linalg.norm(T2[:3, 3] - T[:3, 3]) < 1e-3
        assert np.abs(T2[:3, :3] - T[:3, :3]).max() < 2e-2
        assert np.all(res.q >= robot.lower - 1e-9) and np.all(res.q <= robot.upper + 1e-9)
    print(f"\n[ik panda] solved {solved}/{n}, median {np.median(times) * 1e3:.1f} ms, "
          f"max {max(times) * 1e3:.1f} ms, mean attempts {np.mean(attempts):.2f}")
    assert solved >= 18


def test_unreachable_target_returns_none():
    robot = load_robot(SceneRobot("ikpanda2", "urdf", model="panda", ee="panda_hand_tcp"))
    far = np.r_[3.0, 0.0, 0.5, 0.0, 0.0, 0.0, 1.0]
    assert solve_ik(robot, far, restarts=2, seed=0) is None
