"""Node validation of the reachability graph: Eq. 2 of paper 002.

    min_q  M * max(0, g_prec(x0)) + |x - x0|^2   s.t.  g_prec(x0) <= 0,  x = f_kin(q),  g(q) <= 0

How it is solved here, and why:
- g_prec (the target point itself inside an obstacle) is tested first with coal: such targets
  are rejected without any optimisation, which is what the big-M term is for in the paper.
- The position IK (orientation free, joint limits as bounds) is `gnppdsl.geometry.ik.solve_ik`
  (ipopt, exact Hessian; result checked with pinocchio). It is called once per start, so that
  each candidate can be collision-checked: the collision part of g(q) <= 0 is enforced by
  rejecting colliding solutions and trying the next start, not inside the NLP (a coal signed
  distance per link and obstacle in every ipopt iteration costs more than a few restarts).
- Starts: the configurations of the nearest existing nodes (so neighbouring nodes get nearby
  joint configurations and Eq. 3's joint distance stays meaningful, which matters for mobile
  bases with their large null space), then the home configuration, then `restarts` uniform
  random configurations from the seeded generator.
- The node cost c is the optimal value of Eq. 2 for an accepted node, i.e. |x - x0|^2.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Iterable

import numpy as np

from gnppdsl.geometry.ik import solve_ik
from gnppdsl.geometry.robots import RobotModel
from gnppdsl.reach.collision import CollisionChecker


@dataclass
class NodeValidation:
    """An accepted node n(x, q, c): target x0, configuration q, Eq. 2 cost c."""

    x: np.ndarray
    q: np.ndarray
    cost: float
    attempts: int


@dataclass
class ValidationStats:
    targets: int = 0
    in_obstacle: int = 0       # rejected by g_prec
    ik_failed: int = 0         # no start converged within tolerance
    in_collision: int = 0      # every converged start collided
    accepted: int = 0
    ik_solves: int = 0

    @property
    def success_rate(self) -> float:
        return self.accepted / self.targets if self.targets else 0.0


def validate_position(robot: RobotModel, checker: CollisionChecker, frame: str, x0, rng: np.random.Generator,
                      seeds: Iterable[np.ndarray] = (), restarts: int = 5, tol: float = 1e-3,
                      stats: ValidationStats | None = None) -> NodeValidation | None:
    """Solve Eq. 2 for target x0; None if x0 is inside an obstacle, unreachable or only reachable
    in collision (within the given starts)."""
    stats = stats if stats is not None else ValidationStats()
    stats.targets += 1
    x0 = np.asarray(x0, dtype=float).ravel()
    if not checker.point_free(x0):
        stats.in_obstacle += 1
        return None
    T = np.eye(4)
    T[:3, 3] = x0
    starts = [np.asarray(s, dtype=float) for s in seeds]
    converged = False
    attempts = 0
    for k in range(len(starts) + restarts):
        q0 = starts[k] if k < len(starts) else robot.random_coords(rng)
        attempts += 1
        stats.ik_solves += 1
        res = solve_ik(robot, T, q0=q0, restarts=0, frame=frame, tol=tol, position_only=True)
        if res is None:
            continue
        converged = True
        if checker.config_free(res.q):
            stats.accepted += 1
            return NodeValidation(x0, res.q, float(res.position_error) ** 2, attempts)
    if converged:
        stats.in_collision += 1
    else:
        stats.ik_failed += 1
    return None
