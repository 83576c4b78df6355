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


def bounding_sphere(shape) -> tuple[np.ndarray, float]:
    """Centre (shape frame) and radius of a sphere that holds the whole convex coal shape: the
    broadphase bound of `CollisionChecker.config_free`. Exact for the primitives (a box's half
    diagonal, a cylinder's rim); a convex hull's is the largest vertex distance from the centre
    of its vertices' box."""
    import coal
    if isinstance(shape, coal.Box):
        return np.zeros(3), float(np.linalg.norm(shape.halfSide))
    if isinstance(shape, coal.Sphere):
        return np.zeros(3), float(shape.radius)
    if isinstance(shape, coal.Cylinder):
        return np.zeros(3), float(np.hypot(shape.radius, shape.halfLength))
    if isinstance(shape, coal.Capsule):
        return np.zeros(3), float(shape.radius + shape.halfLength)
    if isinstance(shape, coal.Cone):
        return np.zeros(3), float(np.hypot(shape.radius, shape.halfLength))
    if hasattr(shape, "points"):
        pts = np.array(shape.points())
        c = (pts.min(axis=0) + pts.max(axis=0)) / 2
        return c, float(np.max(np.linalg.norm(pts - c, axis=1)))
    return np.zeros(3), np.inf            # unknown kind: never skipped


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
        self._spheres()

    def _spheres(self) -> None:
        """Broadphase data: a bounding sphere per link shape (centre in its link's frame) and per
        obstacle (world), and every pair `min_distance` measures flattened to shape level."""
        link_of, centre, radius, shape_index = [], [], [], []
        for i, (_, _, shapes) in enumerate(self._links):
            shape_index.append([])
            for s, P in shapes:
                c, r = bounding_sphere(s)
                shape_index[i].append(len(link_of))
                link_of.append(i)
                centre.append(P[:3, :3] @ c + P[:3, 3])
                radius.append(r)
        self._sh_link = np.array(link_of, dtype=int)
        self._sh_centre = np.array(centre, dtype=float).reshape(-1, 3)
        self._sh_radius = np.array(radius, dtype=float)
        self._sh_local = [(i, k) for i, (_, _, shapes) in enumerate(self._links) for k in range(len(shapes))]
        ob_c, ob_r = [], []
        for o in self.obstacles:
            c, r = bounding_sphere(o.shape)
            ob_c.append(o.T[:3, :3] @ c + o.T[:3, 3])
            ob_r.append(r)
        ob_c = np.array(ob_c, dtype=float).reshape(-1, 3)
        env = [(a, j) for i, j in self._env_pairs for a in shape_index[i]]
        self._env_a = np.array([a for a, _ in env], dtype=int)
        self._env_o = np.array([j for _, j in env], dtype=int)
        self._env_oc = ob_c[self._env_o] if env else np.zeros((0, 3))
        self._env_r = (self._sh_radius[self._env_a] + np.array(ob_r)[self._env_o]) if env else np.zeros(0)
        own = [(a, b) for i, k in self._self_pairs for a in shape_index[i] for b in shape_index[k]]
        self._self_a = np.array([a for a, _ in own], dtype=int)
        self._self_b = np.array([b for _, b in own], dtype=int)
        self._self_r = self._sh_radius[self._self_a] + self._sh_radius[self._self_b] if own else np.zeros(0)

    # -- primitives -----------------------------------------------------------------------------
    def _link_poses(self, q) -> np.ndarray:
        """World pose (4x4) of every link at configuration q (n_links x 4 x 4): one stacked
        product with the base (33 separate ones were a quarter of `config_free` on the PR2)."""
        pin = self._pin
        pin.framesForwardKinematics(self.robot.model, self._data, self.robot.to_pin_q(q))
        oMf = self._data.oMf
        H = np.array([oMf[fid].homogeneous for _, fid, _ in self._links]).reshape(-1, 4, 4)
        return np.matmul(self.robot.base, H)

    def _link_tfs(self, q) -> list:
        return [[(s, _tf(W @ P)) for s, P in shapes]
                for W, (_, _, shapes) in zip(self._link_poses(q), self._links)]

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
        """Clear of every obstacle (and itself) by at least the margin: the same decision as
        `min_distance(q)[0] >= margin`, with a broadphase first. A pair whose bounding spheres
        are farther apart than the margin cannot be closer, so only the others go to coal
        (nearest bound first, stopping at the first pair closer than the margin). The graph
        checks thousands of configurations per query, most of whose pairs are far apart
        (sort2: 1,525 checks, ~1 ms each with every pair measured). Written with numpy rather
        than coal's broadphase managers because the pairs are a fixed, filtered list (SRDF,
        `ignore_collisions`, base links) and the self pairs need the same filter."""
        self.checks += 1
        W = self._link_poses(q)
        if not len(self._sh_link):
            return True
        Wl = W[self._sh_link]
        centre = np.einsum("nij,nj->ni", Wl[:, :3, :3], self._sh_centre) + Wl[:, :3, 3]
        bound_env = np.linalg.norm(centre[self._env_a] - self._env_oc, axis=1) - self._env_r \
            if len(self._env_a) else np.zeros(0)
        bound_self = np.linalg.norm(centre[self._self_a] - centre[self._self_b], axis=1) - self._self_r \
            if len(self._self_a) else np.zeros(0)
        tfs: dict[int, object] = {}

        def tf(a: int):
            if a not in tfs:
                i, k = self._sh_local[a]
                tfs[a] = _tf(W[i] @ self._links[i][2][k][1])
            return tfs[a]

        for n in np.argsort(bound_env, kind="stable"):
            if bound_env[n] >= self.margin:
                break
            a = self._env_a[n]
            _, so, To = self._obs_tf[self._env_o[n]]
            if self._dist(self._links[self._sh_local[a][0]][2][self._sh_local[a][1]][0], tf(a), so, To) \
                    < self.margin:
                return False
        for n in np.argsort(bound_self, kind="stable"):
            if bound_self[n] >= self.margin:
                break
            a, b = self._self_a[n], self._self_b[n]
            sa = self._links[self._sh_local[a][0]][2][self._sh_local[a][1]][0]
            sb = self._links[self._sh_local[b][0]][2][self._sh_local[b][1]][0]
            if self._dist(sa, tf(a), sb, tf(b)) < self.margin:
                return False
        return True

    def point_free(self, x) -> bool:
        """g_prec of Eq. 2: the end-effector target itself is not inside an obstacle."""
        sphere = self._coal.Sphere(1e-6)
        T = np.eye(4)
        T[:3, 3] = np.asarray(x, dtype=float)
        Tx = _tf(T)
        return all(self._dist(sphere, Tx, so, To) > 0 for _, so, To in self._obs_tf)

    def segment_configs(self, q1, q2, steps: int, max_step: float) -> np.ndarray:
        """Interior configurations of the straight joint-space segment q1 -> q2 that an edge
        check visits: at least `steps`, more if a coordinate would move more than `max_step`.
        Angles (continuous joints, a planar heading: `RobotModel.angle_mask`) turn the short
        way round, as the graph's edge costs measure them (`RobotModel.coord_difference`)."""
        q1, q2 = np.asarray(q1, dtype=float), np.asarray(q2, dtype=float)
        d = self.robot.coord_difference(q1, q2)
        span = float(np.max(np.abs(d))) if q1.size else 0.0
        n = max(int(steps), int(np.ceil(span / max_step)) - 1 if max_step > 0 else 0)
        t = np.linspace(0.0, 1.0, n + 2)[1:-1]
        return q1[None, :] + t[:, None] * d[None, :]

    def segment_free(self, q1, q2, steps: int, max_step: float) -> bool:
        """Lazy edge check: every interpolated configuration is free (endpoints are nodes,
        validated on their own). Checks from both ends inwards: collisions near a blocked
        node are found first."""
        qs = self.segment_configs(q1, q2, steps, max_step)
        order = np.argsort(np.minimum(np.arange(len(qs)), np.arange(len(qs))[::-1]), kind="stable")
        return all(self.config_free(qs[i]) for i in order)
