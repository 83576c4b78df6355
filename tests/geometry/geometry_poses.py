"""Random body-pair inputs of the distance callback, shared by the geometry tests: each input
is x = [vec(RA) column-major, pA, vec(RB), pB] (24 numbers), as the callback receives it."""
from __future__ import annotations

import casadi as ca
import numpy as np

from gnppdsl.geometry.kinematics import quat_to_rotation


def rotation(q) -> np.ndarray:
    """3x3 rotation of a unit quaternion (x, y, z, w) through the casadi path."""
    return np.array(ca.Function("r", [], [quat_to_rotation(ca.DM(q))])()["o0"])


def pair_inputs(rng, n: int, spread: float, planar: bool = False, aligned_every: int = 0) -> list[np.ndarray]:
    """n inputs with positions in [-spread, spread]; `planar`: rotations about z in the plane
    z = 0; `aligned_every` k > 0: every k-th input has identity rotations and positions rounded
    to 1 cm (stacked boxes: parallel faces, edges and touching corners)."""
    xs = []
    for i in range(n):
        aligned = aligned_every > 0 and i % aligned_every == 0
        parts = []
        for _side in range(2):
            if planar:
                t = rng.uniform(-np.pi, np.pi)
                R = np.array([[np.cos(t), -np.sin(t), 0], [np.sin(t), np.cos(t), 0], [0, 0, 1.0]])
                p = np.r_[rng.uniform(-spread, spread, 2), 0.0]
            else:
                q = rng.normal(size=4)
                R = np.eye(3) if aligned else rotation(q / np.linalg.norm(q))
                p = rng.uniform(-spread, spread, 3)
                if aligned:
                    p = np.round(p, 2)
            parts += [R.reshape(-1, order="F"), p]
        xs.append(np.concatenate(parts))
    return xs
