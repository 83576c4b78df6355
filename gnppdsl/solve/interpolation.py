"""Trajectory warm starts by interpolation between keyframes (Appendix C): the keyframe variable a
trajectory moves between, and the straight line from its value at step i to its value at i+1.
"""
from __future__ import annotations

from typing import Callable, Iterable

import numpy as np

from gnppdsl.compile.factors import VarInstance


def keyframe_of(traj: VarInstance, candidates: Iterable[VarInstance],
                neighbours: Iterable[VarInstance] = ()) -> str | None:
    """The variable key whose values at steps i and i+1 a trajectory at step i moves between:
    a non-trajectory variable with the same objects and the trajectory's point dimension,
    preferring one a factor connects to the trajectory (its boundary constraints)."""
    near = {v.key for v in neighbours if not v.waypoints}
    same = sorted({v.key for v in candidates
                   if not v.waypoints and v.args == traj.args and v.dim == traj.point_dim})
    for key in same:
        if key in near:
            return key
    return same[0] if same else None


def interpolate_trajectories(trajs: Iterable[VarInstance], values: dict[VarInstance, np.ndarray],
                             neighbours: Callable[[VarInstance], Iterable[VarInstance]] = lambda v: ()
                             ) -> dict[VarInstance, np.ndarray]:
    """Warm start of each trajectory: linear interpolation from its keyframe at step i to the
    one at i+1 (quaternions of SE3 points renormalised)."""
    by_key_step = {(v.key, v.step): v for v in values}
    out: dict[VarInstance, np.ndarray] = {}
    for tr in trajs:
        key = keyframe_of(tr, values.keys(), neighbours(tr))
        if key is None:
            continue
        a = by_key_step.get((key, tr.step))
        b = by_key_step.get((key, tr.step + 1), a)
        if a is None:
            a = b
        if a is None:
            continue
        out[tr] = straight_line(np.asarray(values[a], float).reshape(-1),
                                np.asarray(values[b], float).reshape(-1), tr.waypoints, a.space)
    return out


def straight_line(xa: np.ndarray, xb: np.ndarray, waypoints: int, space: str) -> np.ndarray:
    """`waypoints` points from xa to xb, evenly spaced (quaternions of SE3 points renormalised),
    stacked into one vector."""
    s = np.linspace(0.0, 1.0, waypoints)[:, None]
    pts = (1 - s) * xa[None, :] + s * xb[None, :]
    if space == "SE3" and pts.shape[1] == 7:
        pts[:, 3:7] /= np.maximum(np.linalg.norm(pts[:, 3:7], axis=1, keepdims=True), 1e-12)
    return pts.reshape(-1)


def via_line(xa: np.ndarray, xv: np.ndarray, xb: np.ndarray, waypoints: int, space: str) -> np.ndarray:
    """`waypoints` points from xa through xv to xb, evenly spaced along the two straight
    segments (quaternions of SE3 points renormalised), stacked into one vector: a detour start
    through another keyframe of the same variable (`TrajectoryPhase.detour_start`)."""
    d1, d2 = float(np.linalg.norm(xv - xa)), float(np.linalg.norm(xb - xv))
    if d1 + d2 <= 0.0:
        return straight_line(xa, xb, waypoints, space)
    t = np.linspace(0.0, d1 + d2, waypoints)[:, None]
    first = xa[None, :] + (t / max(d1, 1e-12)) * (xv - xa)[None, :]
    second = xv[None, :] + ((t - d1) / max(d2, 1e-12)) * (xb - xv)[None, :]
    pts = np.where(t <= d1, first, second)
    pts[0], pts[-1] = xa, xb
    if space == "SE3" and pts.shape[1] == 7:
        pts[:, 3:7] /= np.maximum(np.linalg.norm(pts[:, 3:7], axis=1, keepdims=True), 1e-12)
    return pts.reshape(-1)
