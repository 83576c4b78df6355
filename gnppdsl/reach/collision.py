"""Collision tests of one robot against the static scene: nodes (Eq. 2's g) and edges (lazy checks).

Why not `gnppdsl.geometry.verify`: the graph checks tens of thousands of configurations, so this
checker prepares everything once (coal shapes and world transforms of the obstacles, the link
shape lists, one pinocchio Data) and stops at the first pair closer than the margin. It uses
the same convex link shapes as the rest of the project (`RobotModel.links`: one hull per link,
conservative), pinocchio forward kinematics and direct `coal.distance` calls.

What counts (mirrors the verifier): every link of the robot against every obstacle, except
links no joint moves when the robot's base is fixed (the Panda's link0 stands on its table) and
pairs the scene's `ignore_collisions` names; plus the SRDF-filtered self-collision pairs.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.geometry.robots import RobotModel, se3_to_matrix
from gnppdsl.geometry.shapes import coal_shape


@dataclass
class Obstacle:
    name: str
    shape: object            # convex coal shape
    T: np.ndarray            # 4x4 world pose


def static_obstacles(scene, robot: str, names=None) -> list[Obstacle]:
    """The scene objects a robot's graph must avoid: `names`, or every static object."""
    if names is None:
        names = [n for n, o in scene.objects.items() if o.static]
    out = []
    for n in names:
        o = scene.objects.get(n)
        if o is None:
            raise UserError(f"reachability for '{robot}': unknown obstacle '{n}'")
        s = coal_shape(o.shape, False)
        if s is None:
            continue
        out.append(Obstacle(n, s, se3_to_matrix(o.pose)))
    return out


def _tf(T: np.ndarray):
    import coal
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


class CollisionChecker:
    """Is a configuration (or a straight joint-space segment) clear of the obstacles by `margin`?"""

    def __init__(self, robot: RobotModel, obstacles: list[Obstacle], margin: float = 0.0,
                 self_collision: bool = True, ignore: frozenset = frozenset(), fixed_base: bool = True):
        import coal
        import pinocchio as pin
        self._pin = pin
        self._coal = coal
        self.robot = robot
        self.margin = float(margin)
        self.obstacles = list(obstacles)
        self._data = robot.model.createData()
        self._req = coal.DistanceRequest()
        self._req.enable_signed_distance = True
        self._obs_tf = [(o.name, o.shape, _tf(o.T)) for o in self.obstacles]
        self._links = []          # (link name, frame id, [(shape, placement 4x4)])
        for ln, gs in robot.links.items():
            self._links.append((ln, robot.model.getFrameId(ln), [(g.shape, g.placement) for g in gs]))
        skip = set(robot.fixed_links) if fixed_base else set()

        def ignored(ln: str, ob: str) -> bool:
            return any(frozenset(p) in ignore for p in ((ln, ob), (robot.name, ob), (f"{robot.name}/{ln}", ob)))

        # (link index, obstacle index) pairs to test
        self._env_pairs = [(i, j) for i, (ln, _, _) in enumerate(self._links) if ln not in skip
                           for j, (ob, _, _) in enumerate(self._obs_tf) if not ignored(ln, ob)]
        idx = {ln: i for i, (ln, _, _) in enumerate(self._links)}
        self._self_pairs = [(idx[a], idx[b]) for a, b in robot.self_pairs if a in idx and b in idx] \
            if self_collision else []
        self.checks = 0           # configurations checked (for statistics)

    # -- primitives -----------------------------------------------------------------------------
    def _link_tfs(self, q) -> list:
        pin = self._pin
        pin.framesForwardKinematics(self.robot.model, self._data, self.robot.to_pin_q(q))
        B = self.robot.base
        out = []
        for _, fid, shapes in self._links:
            W = B @ np.array(self._data.oMf[fid].homogeneous)
            out.append([(s, _tf(W @ P)) for s, P in shapes])
        return out

    def _dist(self, sa, Ta, sb, Tb) -> float:
        res = self._coal.DistanceResult()
        return float(self._coal.distance(sa, Ta, sb, Tb, self._req, res))

    def min_distance(self, q, stop_below: float | None = None) -> tuple[float, str]:
        """Smallest signed distance over all checked pairs and the pair's name; with
        `stop_below`, returns as soon as a pair is closer than it."""
        self.checks += 1
        tfs = self._link_tfs(q)
        best, which = np.inf, ""
        for i, j in self._env_pairs:
            ob, so, To = self._obs_tf[j]
            for s, T in tfs[i]:
                d = self._dist(s, T, so, To)
                if d < best:
                    best, which = d, f"{self._links[i][0]} <-> {ob}"
                    if stop_below is not None and best < stop_below:
                        return best, which
        for i, k in self._self_pairs:
            for s, T in tfs[i]:
                for s2, T2 in tfs[k]:
                    d = self._dist(s, T, s2, T2)
                    if d < best:
                        best, which = d, f"{self._links[i][0]} <-> {self._links[k][0]}"
                        if stop_below is not None and best < stop_below:
                            return best, which
        return best, which

    def config_free(self, q) -> bool:
        """Clear of every obstacle (and itself) by at least the margin."""
        return self.min_distance(q, stop_below=self.margin)[0] >= self.margin

    def point_free(self, x) -> bool:
        """g_prec of Eq. 2: the end-effector target itself is not inside an obstacle."""
        sphere = self._coal.Sphere(1e-6)
        T = np.eye(4)
        T[:3, 3] = np.asarray(x, dtype=float)
        Tx = _tf(T)
        return all(self._dist(sphere, Tx, so, To) > 0 for _, so, To in self._obs_tf)

    def segment_configs(self, q1, q2, steps: int, max_step: float) -> np.ndarray:
        """Interior configurations of the straight joint-space segment q1 -> q2 that an edge
        check visits: at least `steps`, more if a coordinate would move more than `max_step`."""
        q1, q2 = np.asarray(q1, dtype=float), np.asarray(q2, dtype=float)
        span = float(np.max(np.abs(q2 - q1))) if q1.size else 0.0
        n = max(int(steps), int(np.ceil(span / max_step)) - 1 if max_step > 0 else 0)
        t = np.linspace(0.0, 1.0, n + 2)[1:-1]
        return q1[None, :] + t[:, None] * (q2 - q1)[None, :]

    def segment_free(self, q1, q2, steps: int, max_step: float) -> bool:
        """Lazy edge check: every interpolated configuration is free (endpoints are nodes,
        validated on their own). Checks from both ends inwards: collisions near a blocked
        node are found first."""
        qs = self.segment_configs(q1, q2, steps, max_step)
        order = np.argsort(np.minimum(np.arange(len(qs)), np.arange(len(qs))[::-1]), kind="stable")
        return all(self.config_free(qs[i]) for i in order)
