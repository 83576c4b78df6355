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

R-LGP's keyframe starts choose all of a robot's bases of a plan at once instead: `restart_guesses`
takes that choice as `plan` (`gnppdsl.reach.drives.plan_bases`, the shortest drive through the
ring points; R-LGP's module, above this layer, passes it in).
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING, Callable, Sequence

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.compile.factors import VarInstance
    from gnppdsl.compile.factory import GraphNLPFactory

RADII = (0.25, 0.45, 0.65)      # base-to-target distances tried beyond the footprint radius (m)
ANGLES = 16                     # points per ring
BASE_RADIUS = 0.3               # the footprint radius when the robot names no base link


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


@dataclass(frozen=True)
class Footprint:
    """A mobile base's outline in its own frame (x forward, where the arm reaches and the base
    faces its target): the convex hull of its base link's collision vertices, counter-clockwise,
    and the `clearance` the NLP keeps between that link and the tables (`base_clearance`).

    Why, beside the disc of `base_radius`: the disc takes the hull's farthest vertex in every
    direction. The mobile Panda's panda_link0 reaches 0.154 m backwards but 0.072 m forwards, so
    with its 0.15 m platform the disc (0.305 m) rejects a base facing a table at 0.29 m whose
    front keeps 0.22 m. sort_random instance 5 (red1 north of the central table's middle): every
    south ring point within reach failed the disc by 1.6 cm or more, `plan_bases` started that
    pick from the 45-degree point 0.96 m away, and the NLP slid the base round to the north
    (3.63 m of drive; plain GNPP 2.23 m, picking from the south)."""
    hull: tuple[tuple[float, float], ...]
    clearance: float

    def free(self, x: float, y: float, yaw: float, obstacles) -> bool:
        """Does the outline at (x, y) turned by `yaw`, grown by the clearance, stay out of every
        obstacle's footprint (a box's rectangle, otherwise the circle of its half-diagonal)?"""
        from gnppdsl.ir.instances import footprint_radius

        c, s = math.cos(yaw), math.sin(yaw)
        outline = [(x + c * px - s * py, y + s * px + c * py) for px, py in self.hull]
        reach = max(math.hypot(px, py) for px, py in self.hull)   # the outline within this of (x, y)
        for o in obstacles:
            ox, oy = float(o.pose[0]), float(o.pose[1])
            size = tuple(o.shape.size or ())
            if o.shape.kind == "box" and len(size) >= 2:
                t, ex, ey = _yaw(o.pose[3:7]), size[0] / 2, size[1] / 2
                ct, st = math.cos(t), math.sin(t)
                u, v = ct * (x - ox) + st * (y - oy), -st * (x - ox) + ct * (y - oy)
                if math.hypot(max(abs(u) - ex, 0.0), max(abs(v) - ey, 0.0)) - reach >= self.clearance:
                    continue              # far enough whatever the outline's turn: same verdict, cheaper
                rect = [(ox + ct * u - st * v, oy + st * u + ct * v)
                        for u, v in ((ex, ey), (-ex, ey), (-ex, -ey), (ex, -ey))]
                if _polygon_gap(outline, rect) < self.clearance:
                    return False
            elif _point_gap((ox, oy), outline) < self.clearance + footprint_radius(o):
                return False
        return True


def base_footprint(spec) -> Footprint | None:
    """The outline of a mobile robot's base link (`links: {base: ..}`) with its
    `base_clearance`; None when the scene names no base link or it has no collision shapes."""
    link = getattr(spec, "links", {}).get("base")
    if not link:
        return None
    from gnppdsl.geometry.robots import load_robot

    c = [0.0, 0.0, 0.0, *list(spec.home)[3:]]        # the planar joint at the origin, theta 0
    P = load_robot(spec).planar_points(link, c)
    if not len(P):
        return None
    from gnppdsl.geometry.verify import convex_hull_2d

    return Footprint(tuple((float(px), float(py)) for px, py in convex_hull_2d(P)),
                     float(spec.attributes.get("base_clearance", 0.0) or 0.0))


def _segment_gap(p, a, b) -> float:
    ax, ay, bx, by = a[0], a[1], b[0], b[1]
    dx, dy = bx - ax, by - ay
    L = dx * dx + dy * dy
    t = 0.0 if L == 0 else max(0.0, min(1.0, ((p[0] - ax) * dx + (p[1] - ay) * dy) / L))
    return math.hypot(p[0] - ax - t * dx, p[1] - ay - t * dy)


def _separated(A, B) -> bool:
    """Is there a separating axis among A's and B's edge normals (convex polygons)?"""
    for P in (A, B):
        for i in range(len(P)):
            (ax, ay), (bx, by) = P[i], P[(i + 1) % len(P)]
            nx, ny = ay - by, bx - ax
            a = [nx * x + ny * y for x, y in A]
            b = [nx * x + ny * y for x, y in B]
            if max(a) < min(b) or max(b) < min(a):
                return True
    return False


def _polygon_gap(A, B) -> float:
    """The distance between two convex polygons (0 when they overlap)."""
    if not _separated(A, B):
        return 0.0
    gaps = [_segment_gap(p, Q[i], Q[(i + 1) % len(Q)])
            for P, Q in ((A, B), (B, A)) for p in P for i in range(len(Q))]
    return min(gaps)


def _point_gap(p, A) -> float:
    """The distance from a point to a convex polygon (0 inside)."""
    if len(A) >= 3 and not _separated([p], A):
        return 0.0
    return min(_segment_gap(p, A[i], A[(i + 1) % len(A)]) for i in range(len(A)))


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
                 rings: Sequence[float] | None = None,
                 footprint: Footprint | None = None) -> list[tuple[float, float, int]]:
    """The free points (x, y, k) of the rings around target's (x, y): ring k // ANGLES, angle
    k % ANGLES; inside `lo`/`hi` when given; their disc of `radius` out of every obstacle, or,
    given the base's `footprint`, its outline facing the target (`Footprint.free`)."""
    tx, ty = float(target[0]), float(target[1])
    rings = tuple(rings) if rings is not None else tuple(radius + d for d in RADII)
    out = []
    for k in range(ANGLES * len(rings)):
        a = 2 * math.pi * (k % ANGLES) / ANGLES
        x, y = tx + rings[k // ANGLES] * math.cos(a), ty + rings[k // ANGLES] * math.sin(a)
        if lo is not None and hi is not None and not (lo[0] <= x <= hi[0] and lo[1] <= y <= hi[1]):
            continue
        free = (footprint.free(x, y, a + math.pi, obstacles) if footprint is not None
                else _footprint_free(x, y, obstacles, radius))
        if free:
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


PlanBases = Callable[..., list]
"""(targets, home, obstacles, lo, hi, radius=, footprint=) -> one base (or None) per target: a robot's bases
for all its picks and puts of a plan at once (`gnppdsl.reach.drives.plan_bases`)."""


def restart_guesses(factory: "GraphNLPFactory", variables: Sequence["VarInstance"],
                    states: Sequence[Sequence[int]], plan: PlanBases | None = None) -> dict["VarInstance", list[float]]:
    """The base placements of the keyframe variables among `variables` (see the module
    docstring): each robot's from `plan` when given, else one by one (`base_next_to`, nearest
    the previous base); empty when the scene has no robot with a planar base."""
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
        if plan is not None:              # the plan's choice (R-LGP: the least drive)
            qs = plan([t[3] for t in mine], spec.home, obstacles, lo, hi, radius=radii[robot],
                      footprint=base_footprint(spec))
            out.update({t[2]: q for t, q in zip(mine, qs) if q is not None})
            continue
        previous = list(spec.home)        # the base before the step
        for _, _, v, target in mine:
            q = base_next_to(target, spec.home, obstacles, lo, hi, near=previous, radius=radii[robot])
            if q is not None:
                out[v] = q
                previous = q
    return out


__all__ = ["restart_guesses", "base_next_to", "base_radius", "base_footprint", "Footprint", "RADII", "ANGLES", "BASE_RADIUS"]
