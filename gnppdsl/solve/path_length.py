"""Path lengths of a solution, per robot: the base's travel on the floor and the end effector's.

Paper 002 (R-LGP) reports the base path length of its plans; an objective that shortens
motions should show there. Computed from the returned numbers alone: each robot's joint
configurations in time order (the keyframe of step i, then the waypoints of phase i), the base
position from the planar root joint's [x, y] (a mobile robot), the end-effector position from
pinocchio forward kinematics. Polylines through the waypoints: the length a controller that
interpolates linearly between waypoints drives.
"""
from __future__ import annotations

from typing import Mapping

import numpy as np

from gnppdsl.compile.factors import VarInstance


def robot_configurations(variables: list[VarInstance], values: Mapping[VarInstance, object]
                         ) -> dict[str, list[np.ndarray]]:
    """Robot -> its joint configurations in time order (variables of space `joints(robot)`)."""
    by_robot: dict[str, list[tuple[int, int, np.ndarray]]] = {}
    for v in variables:
        if v.space != "joints" or not v.args or v not in values:
            continue
        x = np.asarray(values[v], float).reshape(-1)
        if v.waypoints:
            pts = x.reshape(v.waypoints, v.point_dim)
            for k, p in enumerate(pts):
                by_robot.setdefault(v.args[0], []).append((v.step, 1 + k, p))
        else:
            by_robot.setdefault(v.args[0], []).append((v.step, 0, x))
    return {r: [p for _, _, p in sorted(seq, key=lambda t: (t[0], t[1]))] for r, seq in by_robot.items()}


def path_lengths(variables: list[VarInstance], values: Mapping[VarInstance, object], geometry
                 ) -> dict[str, dict[str, float | None]]:
    """Robot -> {"base": metres driven (None: a fixed base), "end_effector": metres}."""
    out: dict[str, dict[str, float | None]] = {}
    for robot, qs in robot_configurations(variables, values).items():
        try:
            model = geometry.robot(robot)
        except (KeyError, AttributeError, ValueError):
            continue
        if len(qs) < 2:
            out[robot] = {"base": 0.0 if _mobile(model) else None, "end_effector": 0.0}
            continue
        base = None
        if _mobile(model):
            xy = np.array([q[:2] for q in qs])
            base = float(np.sum(np.linalg.norm(np.diff(xy, axis=0), axis=1)))
        ee = None
        if model.ee:
            pos = np.array([geometry.fk_matrix(robot, q, model.ee)[:3, 3] for q in qs])
            ee = float(np.sum(np.linalg.norm(np.diff(pos, axis=0), axis=1)))
        out[robot] = {"base": base, "end_effector": ee}
    return out


def _mobile(model) -> bool:
    """A robot whose first coordinates are a planar root joint (x, y, theta on the floor)."""
    return bool(model.coords) and model.coords[0].kind == "planar"
