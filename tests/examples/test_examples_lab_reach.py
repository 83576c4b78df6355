"""The Lab scene's reach claims, checked with pinocchio directly (not gnppdsl.geometry).

lab3's N > N0 rests on b5 being out of the left arm's reach and pad_l out of the right arm's;
lab1/lab2 rest on the left arm reaching b1, b2, b3 with top grasps. These tests solve inverse
kinematics for the scene's robots (bases, Panda model, locked fingers) with a damped
least-squares iteration and random restarts.
"""
from __future__ import annotations

import glob
import os
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_reference import EXAMPLES, raw_scene  # noqa: E402

import pinocchio as pin  # noqa: E402  (a dependency of the package: never a skip)

SCENE = raw_scene(EXAMPLES / "lab" / "lab.yaml")


def _model():
    shares = glob.glob(os.path.join(os.path.dirname(pin.__file__), "..", "..", "..", "..", "share"))
    shares += glob.glob(os.path.join(sys.prefix, "lib", "python3*", "site-packages", "cmeel.prefix", "share"))
    urdf = next(os.path.join(s, "example-robot-data/robots/panda_description/urdf/panda.urdf")
                for s in shares if os.path.isfile(os.path.join(s, "example-robot-data/robots/panda_description/urdf/panda.urdf")))
    full = pin.buildModelFromUrdf(urdf)
    lock = [full.getJointId("panda_finger_joint1"), full.getJointId("panda_finger_joint2")]
    q = pin.neutral(full)
    model = pin.buildReducedModel(full, lock, q)
    return model, model.createData(), model.getFrameId("panda_hand_tcp")


MODEL, DATA, TCP = _model()


def _base(arm: str) -> pin.SE3:
    b = SCENE["robots"][arm]["base"]
    return pin.SE3(pin.rpy.rpyToMatrix(*b["rpy"]), np.array(b["xyz"], float))


def _ik(arm: str, target, rotation=None, restarts: int = 8, seed: int = 0, scene: dict | None = None) -> float:
    """Smallest position (and orientation) error reached from home and random starts (the
    robot `arm` of `scene`, default the Lab's)."""
    rng = np.random.default_rng(seed)
    spec = (scene or SCENE)["robots"][arm]
    base = pin.SE3(pin.rpy.rpyToMatrix(*spec["base"]["rpy"]), np.array(spec["base"]["xyz"], float))
    lo, hi = MODEL.lowerPositionLimit, MODEL.upperPositionLimit
    home = np.array(spec["home"], float)
    best = np.inf
    for k in range(restarts):
        q = home.copy() if k == 0 else rng.uniform(lo, hi)
        for _ in range(200):
            pin.framesForwardKinematics(MODEL, DATA, q)
            T = base * DATA.oMf[TCP]
            if rotation is None:
                err = np.asarray(target) - T.translation
                J = base.rotation @ pin.computeFrameJacobian(MODEL, DATA, q, TCP, pin.LOCAL_WORLD_ALIGNED)[:3]
            else:
                err = pin.log6(T.inverse() * pin.SE3(rotation, np.asarray(target, float))).vector
                J = pin.computeFrameJacobian(MODEL, DATA, q, TCP, pin.LOCAL)
            q = np.clip(q + np.linalg.solve(J.T @ J + 1e-3 * np.eye(7), J.T @ err), lo, hi)
        best = min(best, float(np.linalg.norm(err)))
        if best < 1e-5:
            break
    return best


def _top(obj: str):
    """A top grasp of a block at its scene pose: tcp z down, fingers (tcp y) along world x."""
    p = SCENE["objects"][obj]["pose"]["xyz"]
    R = np.column_stack([[0, 1, 0], [1, 0, 0], [0, 0, -1]]).astype(float)
    return p, R


def test_ik_helper_can_fail():
    assert _ik("left_arm", [0.0, 0.2, 0.645]) < 1e-5
    assert _ik("left_arm", [3.0, 0.0, 0.645], restarts=2) > 1.0


@pytest.mark.parametrize("arm,obj", [("left_arm", "b5"), ("right_arm", "pad_l")])
def test_out_of_reach(arm, obj):
    """No configuration brings the tcp within 25 cm of the object (any orientation)."""
    p = SCENE["objects"][obj]["pose"]["xyz"]
    assert _ik(arm, p) > 0.25


@pytest.mark.parametrize("arm,obj", [("left_arm", "b1"), ("left_arm", "b2"), ("left_arm", "b3"),
                                     ("right_arm", "b3"), ("right_arm", "b4"), ("right_arm", "b5"),
                                     ("left_arm", "pad_l")])
def test_top_grasp_reachable(arm, obj):
    p, R = _top(obj)
    if obj.startswith("pad"):
        p = [p[0], p[1], p[2] + 0.045]
    assert _ik(arm, p, R) < 1e-4
