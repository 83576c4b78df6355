"""Base placements: the restart start of a mobile robot's configuration at a keyframe where it
picks or puts down an object (the confirmation of a conflict, `solve.confirmation`).

A robot whose scene entry has `base_joint: planar` (coordinates [x, y, theta, arm...]) starts
every keyframe at its `home`: the base where the robot stands in s_0. The NLP of a pick then
drives the base from there to the nearest side of the table, and when the object is barely in
reach from that side the solve stops in a local minimum there, however the object could be
reached from another side. The random restarts that confirm such a verdict do not help: the
perturbed initial guess has the base at home again, the random start has it anywhere in the
room. Measured (sort_random with random yaw, instance 0: blue1 at (-0.48, 0.22) turned by 74
degrees, so the fingers must close along the south-north reach and the tilted grasp that makes
up the last centimetres from the south is impossible): every start of seed 0 stopped with the
base south of the table, 1 cm into the base clearance, and the pick became a false conflict
("no plan"). From a base placed at arm's length on any free side of the object (west, north,
north-west, south-west) the same subgraph solved in 30-60 iterations.

`restart_guesses` gives, for the keyframe variables of such robots at a step where the robot
picks an object still at its scene pose or releases one onto a static place, the home
configuration with the base moved next to the target: the first point on rings of
`RADII` metres beyond the base's footprint radius around it (`base_radius`: the robot's base
link and `base_clearance`) whose disc of that radius stays out of every static obstacle's
footprint and inside the robot's `base_min`/`base_max`, nearest the previous keyframe's base
first (where the base stands before this pick or put: the robot's placement at its last
earlier pick or put, its home before the first), turned to face the target (the arm reaches
along the base's x axis, as the Panda's home does). The NLP enforces the real clearances; the
placement only decides the side. Nearest the home base instead (before), a put after a pick
on the far side of the table got a restart base on the side nearest home, away from where the
base stood.

R-LGP's keyframe starts (`restart_guesses(across_rings=True)`, `solve.rlgp`) choose per plan
instead (`plan_bases`): one free point of any ring per pick or put, together the shortest drive
from home through all of them in the plan's order (a dynamic programme over the targets' ring
points; the drive between two points by `TravelMap`, around the tables' footprints grown by the
base's radius). Why: the side nearest the previous base can be the wrong one for the rest of the
plan. sort_random_pr2 instance 4 (seed 0): the greedy choice put the second pick (blue1, west
of the table's centre) west of it, the nearest side to the red tray's base; the NLP slid the base
to the north and the plan drove 4.28 m (GNPP 2.20 m). The plan's choice picks it from the south,
where the drive to the blue tray goes: 2.44 m, 10.8 s CPU instead of 18.6, verified. A point
beyond the innermost ring costs RING_WEIGHT metres of drive per metre (the NLP has to pull an
out-of-reach base in; without it instance 0's first pick started on the PR2's 1.1 m ring and the
run drove 4.07 m). Measured (`gnpp bench examples/mobile/sort_random_pr2.pntc --algorithms rlgp
--instances 10 --time-limit 120`, GNPP_REACH_CACHE=0, 996040d against this, load 4-9):
sort_random_pr2 R-LGP solved 9/10 both (996040d failed instance 5's verification, this
instance 8's), mean base on the 7 both solved 3.10 -> 2.82 m (GNPP 2.88), on the 9 this and GNPP
solved 2.92 m against GNPP's 3.36; sort_random (Panda) 10/10 both, mean base 2.82 -> 2.94 m
(instances 4, 6, 7 longer, 5 and 9 shorter), mean CPU 6.1 -> 5.7 s.
"""
from __future__ import annotations

import math
from typing import TYPE_CHECKING, Sequence

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.compile.factors import VarInstance
    from gnppdsl.compile.factory import GraphNLPFactory

RADII = (0.25, 0.45, 0.65)      # base-to-target distances tried beyond the footprint radius (m)
ANGLES = 16                     # points per ring
BASE_RADIUS = 0.3               # the footprint radius when the robot names no base link
RING_WEIGHT = 0.5               # plan_bases: drive (m) a ring point costs per metre beyond the innermost ring


def base_radius(spec) -> float:
    """The footprint radius of a mobile robot (scene entry `spec`): the largest x-y distance of
    a vertex of its base link's collision shapes (the link of role `base`, `links: {base: ..}`)
    from the planar joint, plus the scene's `base_clearance` the NLP keeps from the tables;
    BASE_RADIUS when the scene names no base link.

    Why: the placement's free check and rings were set for the mobile Panda (panda_link0's
    hull reaches 0.155 m, its platform 0.15 m beyond: 0.305 m; rings 0.55-0.95 m). The PR2's
    base_link is its 0.67 m square platform (hull 0.43 m, clearance 0.02 m: 0.45 m): with a
    0.3 m disc and rings from 0.55 m, its keyframe bases started overlapping the tables and
    the NLP pushed them out on whichever side (sort_random_pr2, seed 0: instances 4 and 6
    drove 5.32 and 6.10 m against plain GNPP's 2.20 and 2.12 m). The rings (RADII) are now
    distances beyond this radius: the Panda's are unchanged, the PR2's 0.70-1.10 m."""
    link = getattr(spec, "links", {}).get("base")
    if not link:
        return BASE_RADIUS
    from gnppdsl.geometry.robots import load_robot

    c = [0.0, 0.0, 0.0, *list(spec.home)[3:]]        # the planar joint at the origin
    r = load_robot(spec).planar_radius(link, c)
    if r == 0.0:
        return BASE_RADIUS
    return r + float(spec.attributes.get("base_clearance", 0.0) or 0.0)


def _yaw(q: Sequence[float]) -> float:
    x, y, z, w = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def _footprint_free(x: float, y: float, obstacles, radius: float = BASE_RADIUS) -> bool:
    """Is the disc of `radius` at (x, y) outside every obstacle's footprint (a box's
    rectangle, otherwise the circle of its half-diagonal)?"""
    from gnppdsl.ir.instances import footprint_radius

    for o in obstacles:
        ox, oy = o.pose[0], o.pose[1]
        size = tuple(o.shape.size or ())
        if o.shape.kind == "box" and len(size) >= 2:
            t = _yaw(o.pose[3:7])
            dx, dy = x - ox, y - oy
            lx, ly = math.cos(t) * dx + math.sin(t) * dy, -math.sin(t) * dx + math.cos(t) * dy
            ex, ey = max(abs(lx) - size[0] / 2, 0.0), max(abs(ly) - size[1] / 2, 0.0)
            if math.hypot(ex, ey) < radius:
                return False
        elif math.hypot(x - ox, y - oy) < radius + footprint_radius(o):
            return False
    return True


def _ring_points(target: Sequence[float], obstacles, lo, hi, radius: float,
                 rings: Sequence[float] | None = None) -> list[tuple[float, float, int]]:
    """The free points (x, y, k) of the rings around target's (x, y): ring k // ANGLES, angle
    k % ANGLES; inside `lo`/`hi` when given; their disc of `radius` out of every obstacle."""
    tx, ty = float(target[0]), float(target[1])
    rings = tuple(rings) if rings is not None else tuple(radius + d for d in RADII)
    out = []
    for k in range(ANGLES * len(rings)):
        a = 2 * math.pi * (k % ANGLES) / ANGLES
        x, y = tx + rings[k // ANGLES] * math.cos(a), ty + rings[k // ANGLES] * math.sin(a)
        if lo is not None and hi is not None and not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1]):
            continue
        if _footprint_free(x, y, obstacles, radius):
            out.append((x, y, k))
    return out


def _facing(home: Sequence[float], x: float, y: float, target: Sequence[float]) -> list[float]:
    q = [float(v) for v in home]
    q[0], q[1], q[2] = x, y, math.atan2(float(target[1]) - y, float(target[0]) - x)
    return q


def base_next_to(target: Sequence[float], home: Sequence[float], obstacles,
                 lo: Sequence[float] | None = None, hi: Sequence[float] | None = None,
                 near: Sequence[float] | None = None, across_rings: bool = False,
                 radius: float = BASE_RADIUS) -> list[float] | None:
    """`home` ([x, y, theta, arm...]) with the base at the first free point around target's
    (x, y) nearest the base `near` (default: home's; see the module docstring), facing it; None
    when no ring point is free. `across_rings`: the free point of any ring nearest `near` (the
    least travel), instead of the nearest one of the innermost ring with a free point. `radius`:
    the base's footprint (`base_radius`); the rings lie RADII beyond it."""
    hx, hy = (float(near[0]), float(near[1])) if near is not None else (float(home[0]), float(home[1]))
    rings = tuple(radius + d for d in RADII)
    for r in ([rings] if across_rings else [(r,) for r in rings]):
        points = _ring_points(target, obstacles, lo, hi, radius, r)
        if points:
            x, y, _ = min(points, key=lambda p: (math.hypot(p[0] - hx, p[1] - hy), p[2]))
            return _facing(home, x, y, target)
    return None


class TravelMap:
    """Shortest drives of a disc of `radius` among the obstacles' footprints (the metric of
    `plan_bases`): each footprint grown by `radius`, as the octagon around it (a box's
    rectangle grown by `radius` on each side with its corners cut by the tangents of the
    rounded corners at 45 degrees; any other shape's circle), the distance between two points
    the straight line when it crosses no octagon's interior, else the shortest path through
    the octagons' vertices (a visibility graph; vertices inside another octagon or outside
    `lo`/`hi` are left out). Contains the disc's Minkowski sum, so a free drive is one."""

    def __init__(self, obstacles, radius: float, lo=None, hi=None):
        import numpy as np

        from gnppdsl.ir.instances import footprint_radius

        r2 = math.sqrt(2.0)
        self.planes = []                  # per octagon: normals (8, 2), offsets (8,): n.p <= b
        corners = []
        for o in obstacles:
            size = tuple(o.shape.size or ())
            if o.shape.kind == "box" and len(size) >= 2:
                t, ex, ey = _yaw(o.pose[3:7]), size[0] / 2, size[1] / 2
            else:
                t, ex, ey = 0.0, footprint_radius(o), footprint_radius(o)
            ax, ay = ex + radius, ey + radius
            cut = ex + ey + radius * r2
            local_n = np.array([[1, 0], [-1, 0], [0, 1], [0, -1],
                                [1 / r2, 1 / r2], [-1 / r2, 1 / r2], [-1 / r2, -1 / r2], [1 / r2, -1 / r2]])
            local_b = np.array([ax, ax, ay, ay] + [cut / r2] * 4)
            d = radius * (r2 - 1)
            local_v = [(sx * ax, sy * (ey + d)) for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            local_v += [(sx * (ex + d), sy * ay) for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            c, s = math.cos(t), math.sin(t)
            R = np.array([[c, -s], [s, c]])
            centre = np.array([float(o.pose[0]), float(o.pose[1])])
            N = local_n @ R.T
            self.planes.append((N, local_b + N @ centre))
            corners += [tuple(R @ (np.asarray(v) * (1 + 1e-6)) + centre) for v in local_v]
        K = np.asarray(corners, float).reshape(-1, 2)
        if len(K) and lo is not None and hi is not None:
            K = K[(K[:, 0] >= lo[0]) & (K[:, 0] <= hi[0]) & (K[:, 1] >= lo[1]) & (K[:, 1] <= hi[1])]
        if len(K):
            K = K[~self._inside(K)]
        self.corners = K
        D = self._direct(K, K)            # all-pairs shortest paths among the vertices
        for k in range(len(K)):
            D = np.minimum(D, D[:, k:k + 1] + D[k:k + 1, :])
        self.between = D

    def _inside(self, P):
        import numpy as np

        out = np.zeros(len(P), bool)
        for N, b in self.planes:
            out |= np.all(P @ N.T < b - 1e-9, axis=1)
        return out

    def _blocked(self, P, Q):
        """Per pair (P[i], Q[i]): does the segment cross an octagon's interior (Cyrus-Beck)?"""
        import numpy as np

        out = np.zeros(len(P), bool)
        D = Q - P
        for N, b in self.planes:
            t0, t1 = np.zeros(len(P)), np.ones(len(P))
            hit = np.ones(len(P), bool)
            for n, bk in zip(N, b):
                pk, qk = D @ n, (bk - 1e-9) - P @ n        # n.(p + t d) < b: pk t < qk
                par = np.abs(pk) < 1e-15
                hit &= ~(par & (qk <= 0))
                r = qk / np.where(par, 1.0, pk)
                t0 = np.where(~par & (pk < 0), np.maximum(t0, r), t0)
                t1 = np.where(~par & (pk > 0), np.minimum(t1, r), t1)
            out |= hit & (t1 - t0 > 1e-9)
        return out

    def _direct(self, A, B):
        """|a - b| where the segment is free, inf where it is blocked: shape (len A, len B)."""
        import numpy as np

        A, B = np.asarray(A, float).reshape(-1, 2), np.asarray(B, float).reshape(-1, 2)
        d = np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2)
        if len(A) and len(B) and self.planes:
            P = np.repeat(A, len(B), axis=0)
            Q = np.tile(B, (len(A), 1))
            d = np.where(self._blocked(P, Q).reshape(len(A), len(B)), np.inf, d)
        return d

    def distances(self, A, B):
        """The drives from each point of A to each of B: shape (len A, len B)."""
        import numpy as np

        d = self._direct(A, B)
        if len(self.corners):
            to = (self._direct(A, self.corners)[:, :, None] + self.between[None]).min(axis=1)
            via = (to[:, :, None] + self._direct(self.corners, B)[None]).min(axis=1)
            d = np.minimum(d, via)
        return d


def plan_bases(targets: Sequence[Sequence[float]], home: Sequence[float], obstacles,
               lo: Sequence[float] | None = None, hi: Sequence[float] | None = None,
               radius: float = BASE_RADIUS) -> list[list[float] | None]:
    """One base per target (the robot's picks and puts in the plan's order), each a free point
    of any ring around its target (`_ring_points`), together the least drive home -> first ->
    ... -> last (`TravelMap`'s distances; a dynamic programme over the targets' ring points),
    facing its target (`_facing`). None for a target without a free ring point (the chain
    skips it)."""
    import numpy as np

    travel = TravelMap(obstacles, radius, lo, hi)
    layers = []                           # (target index, points (n, 2), their ring penalties)
    for i, t in enumerate(targets):
        pts = _ring_points(t, obstacles, lo, hi, radius)
        if pts:
            layers.append((i, np.asarray([(x, y) for x, y, _ in pts], float),
                           np.asarray([RING_WEIGHT * (RADII[k // ANGLES] - RADII[0]) for *_, k in pts])))
    out: list = [None] * len(targets)
    if not layers:
        return out
    cost = travel.distances(np.asarray([home[:2]], float), layers[0][1])[0] + layers[0][2]
    back = []
    for (_, a, _), (_, b, pen) in zip(layers, layers[1:]):
        total = cost[:, None] + travel.distances(a, b) + pen[None, :]
        back.append(total.argmin(axis=0))
        cost = total.min(axis=0)
    k = int(np.argmin(cost))              # first of the least (ring order breaks ties)
    for j in range(len(layers) - 1, -1, -1):
        i, pts, _ = layers[j]
        out[i] = _facing(home, float(pts[k][0]), float(pts[k][1]), targets[i])
        if j:
            k = int(back[j - 1][k])
    return out


def restart_guesses(factory: "GraphNLPFactory", variables: Sequence["VarInstance"],
                    states: Sequence[Sequence[int]], across_rings: bool = False) -> dict["VarInstance", list[float]]:
    """The base placements of the keyframe variables among `variables` (see the module
    docstring; `across_rings`: `base_next_to`'s); empty when the scene has no robot with a
    planar base."""
    scene, task = factory.scene, factory.task
    if scene is None or getattr(scene, "dimension", 3) != 3:
        return {}
    mobile = {n: r for n, r in scene.robots.items()
              if r.attributes.get("base_joint") == "planar" and len(r.home) >= 3}
    if not mobile:
        return {}
    parents: dict[str, int] = {}          # object -> the SAS variable of its frame's parent
    for v in variables:
        if v.space in ("SE2", "SE3") and len(v.args) == 1 and v.args[0] not in parents:
            x = factory._relative_to(v)
            if x is not None:
                parents[v.args[0]] = x
    if not parents:
        return {}
    obstacles = [o for o in scene.static_obstacles(factory.problem.objects).values()
                 if len(o.pose) >= 7]
    targets = []                          # (step, robot, variable, target)
    for v in variables:
        robot = v.args[0] if len(v.args) == 1 else None
        if v.space != "joints" or v.waypoints or robot not in mobile or not 1 <= v.step < len(states):
            continue
        if len(mobile[robot].home) != v.dim:
            continue
        target = None
        for obj, x in parents.items():
            names = task.variables[x].values
            before, after = names[states[v.step - 1][x]], names[states[v.step][x]]
            if after == robot and before != robot:          # picked at this step
                if all(states[j][x] == task.initial[x] for j in range(v.step)):
                    target = factory._world_guess(obj)    # still where the scene puts it
            elif before == robot and after != robot:        # released onto `after`
                place = scene.objects.get(after)
                if place is not None and place.static:
                    target = list(place.pose)
            if target is not None:
                break
        if target is not None:
            targets.append((v.step, robot, v, target))
    out: dict = {}
    radii = {n: base_radius(r) for n, r in mobile.items() if any(t[1] == n for t in targets)}
    for robot in radii:
        spec = mobile[robot]
        lo, hi = spec.attributes.get("base_min"), spec.attributes.get("base_max")
        mine = sorted((t for t in targets if t[1] == robot), key=lambda t: t[0])
        if across_rings:                  # the plan's least drive over every ring's points
            qs = plan_bases([t[3] for t in mine], spec.home, obstacles, lo, hi, radius=radii[robot])
            out.update({t[2]: q for t, q in zip(mine, qs) if q is not None})
            continue
        previous = list(spec.home)        # the base before the step
        for _, _, v, target in mine:
            q = base_next_to(target, spec.home, obstacles, lo, hi, near=previous, radius=radii[robot])
            if q is not None:
                out[v] = q
                previous = q
    return out


__all__ = ["restart_guesses", "base_next_to", "plan_bases", "TravelMap", "base_radius", "RADII", "ANGLES", "BASE_RADIUS"]
