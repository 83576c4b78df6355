"""Independent verification primitives: pinocchio + coal on numbers, never the casadi path.

Why separate from the NLP: a solution is only trusted if a second computation, which shares no
code with the constraint functions the solver saw, agrees. Here forward kinematics is
`pin.framesForwardKinematics` and distances are direct `coal.distance` calls on the same convex
shapes; nothing goes through `kinematics.py` or the casadi callback.

A *state* is a dict entity name -> value:
- scene object: world pose, SE3 7-vector (3-D scenes) or SE2 [x, y, theta] (planar scenes);
- URDF robot: joint coordinates, or {"q": coords, "base": SE3 7-vector} for a moving base;
- planar robot: its SE2 (or SE3) pose.
Entities missing from a state keep their scene pose (robots: home configuration).

Pairs are named "b1", "table", "left/panda_hand"; an ignore set holds frozensets of two names,
where a robot name stands for all its links.
"""
from __future__ import annotations

import itertools
from dataclasses import dataclass
from typing import Any, Iterable

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.geometry.distance import ConvexBody, se2_to_matrix, signed_distance
from gnppdsl.geometry.robots import se3_to_matrix
from gnppdsl.geometry.shapes import shape_vertices


@dataclass(frozen=True)
class PairDistance:
    a: str
    b: str
    distance: float

    def __str__(self) -> str:
        return f"{self.a} <-> {self.b}: {self.distance:+.4f}"


@dataclass(frozen=True)
class LimitViolation:
    robot: str
    coordinate: int
    joint: str
    value: float
    lower: float
    upper: float

    @property
    def amount(self) -> float:
        return max(self.lower - self.value, self.value - self.upper, 0.0)


@dataclass(frozen=True)
class GraspCheck:
    inside: bool
    local: tuple[float, float, float]      # the point in the end-effector frame
    half_extents: tuple[float, ...]


@dataclass(frozen=True)
class RestingCheck:
    ok: bool
    gap: float | None        # object bottom - support top (3-D), None for planar scenes
    inside: bool             # object centre over the support's top face / inside its footprint
    distance: float          # coal signed distance object-support


@dataclass
class _Placed:
    """A collision body at a world pose (4x4)."""

    name: str
    owner: str               # entity name (robot for links)
    body: ConvexBody
    T: np.ndarray
    static: bool = False


def _as_ctx(ctx_or_scene, models=None):
    from gnppdsl.geometry.context import GeometryContext
    if isinstance(ctx_or_scene, GeometryContext):
        return ctx_or_scene
    return GeometryContext(ctx_or_scene, models)


def entity_matrix(ctx, name: str, value) -> np.ndarray:
    """World 4x4 of an object or planar robot from a state value (SE3 7-vector or SE2 3-vector)."""
    v = np.asarray(value, dtype=float).ravel()
    if v.size == 7:
        return se3_to_matrix(v)
    if v.size == 3:
        return se2_to_matrix(v)
    raise UserError(f"pose of '{name}' must be SE3 (7 numbers) or SE2 (3 numbers), got {v.size}")


def _entity_matrix(ctx, name: str, value) -> np.ndarray:
    """`entity_matrix` memoised by the exact value (read-only): objects no motion moves keep
    their pose at every waypoint."""
    v = np.asarray(value, dtype=float).ravel()
    memo = _memo(ctx)
    key = ("pose", v.tobytes())
    T = memo.get(key)
    if T is None:
        T = entity_matrix(ctx, name, v)
        T.flags.writeable = False
        memo[key] = T
    return T


def scene_value(ctx, name: str):
    """The value an entity has when a state does not mention it."""
    sc = ctx.scene
    if name in sc.objects:
        o = sc.objects[name]
        return o.pose2 if (sc.dimension == 2 and o.pose2 is not None) else o.pose
    spec = sc.robots[name]
    if spec.kind == "urdf":
        return ctx.robot(name).home_coords(spec.home)
    return spec.home if spec.home else spec.base


def state_value(ctx, state: dict[str, Any], name: str):
    """The value of an entity in a state; missing or None: its scene value."""
    v = state.get(name)
    return scene_value(ctx, name) if v is None else v


def robot_q_base(ctx, name: str, value) -> tuple[np.ndarray, np.ndarray]:
    if isinstance(value, dict):
        q = np.asarray(value["q"], dtype=float)
        base = np.asarray(value.get("base", ctx.scene.robots[name].base), dtype=float)
    else:
        q = np.asarray(value, dtype=float)
        base = np.asarray(ctx.scene.robots[name].base, dtype=float)
    r = ctx.robot(name)
    if q.size != r.nc:
        raise UserError(f"robot {name}: a configuration needs {r.nc} numbers, got {q.size}")
    return q, base


def link_placements(ctx, robot: str, q, base=None) -> dict[str, np.ndarray]:
    """World 4x4 of every collision link of a robot, by pinocchio (read-only arrays).

    Memoised by the exact inputs in `ctx.verify_memo`: during a motion the other robots keep
    their configuration, so most of a verification's calls repeat one."""
    import pinocchio as pin
    qa = np.asarray(q, dtype=float)
    key = ("links", robot, qa.tobytes(), qa.shape, None if base is None else np.asarray(base, float).tobytes())
    memo = _memo(ctx)
    hit = memo.get(key)
    if hit is not None:
        return hit
    r = ctx.robot(robot)
    ids = memo.get(("frame_ids", robot))
    if ids is None:
        ids = memo[("frame_ids", robot)] = [(ln, r.model.getFrameId(ln)) for ln in r.links]
    data = ctx._pin_data.get(robot)
    if data is None:
        data = ctx._pin_data[robot] = r.model.createData()
    pin.framesForwardKinematics(r.model, data, r.to_pin_q(q))
    B = r.base if base is None else se3_to_matrix(base)
    out = {}
    for ln, fid in ids:
        T = B @ np.array(data.oMf[fid].homogeneous)
        T.flags.writeable = False
        out[ln] = T
    memo[key] = out
    return out


_MEMO_SIZE = 200_000


def _memo(ctx) -> dict:
    """The context's memo of this module (emptied when it grows past `_MEMO_SIZE` entries)."""
    m = ctx.verify_memo
    if len(m) > _MEMO_SIZE:
        m.clear()
    return m


def placed_bodies(ctx, state: dict[str, Any]) -> list[_Placed]:
    planar = ctx.scene.dimension == 2
    out: list[_Placed] = []
    for name, o in ctx.scene.objects.items():
        if o.shape.kind == "none":
            continue
        val = state_value(ctx, state, name)
        out.append(_Placed(name, name, ctx.body(name, planar), _entity_matrix(ctx, name, val), o.static))
    for name, spec in ctx.scene.robots.items():
        val = state_value(ctx, state, name)
        if spec.kind == "urdf":
            q, base = robot_q_base(ctx, name, val)
            fixed = ctx.robot(name).fixed_links if "base" not in (val if isinstance(val, dict) else {}) else ()
            for ln, T in link_placements(ctx, name, q, base).items():
                # a link no joint moves (the Panda's link0 on its table) counts as static
                out.append(_Placed(f"{name}/{ln}", name, ctx.body(("link", name, ln)), T, ln in fixed))
        elif spec.shape is not None and spec.shape.kind != "none":
            out.append(_Placed(name, name, ctx.body(name, planar), _entity_matrix(ctx, name, val)))
    return out


def _names(p: _Placed) -> set[str]:
    s = {p.name, p.owner}
    if "/" in p.name:
        s.add(p.name.split("/", 1)[1])
    return s


def _ignored(a: _Placed, b: _Placed, ignore: set[frozenset]) -> bool:
    for x in _names(a):
        for y in _names(b):
            if frozenset((x, y)) in ignore:
                return True
    return False


def _far(ctx, bodies: list[_Placed], cutoff: float) -> np.ndarray:
    """n x n: True where a pair's signed distance surely exceeds `cutoff` (the broadphase).

    Two lower bounds of the signed distance, a pair is far when either exceeds the cutoff:
    |c_a - c_b| - r_a - r_b of the bounding spheres (which contain the convex hulls), and the
    gap between the world AABBs of the bodies' local boxes (`ConvexBody.local_box`, coal's local
    AABBs: a box turned by R has half extents |R| h). Why both: the sphere around a long Panda
    link reaches 10-20 cm past its sides, the box is tight there (lab5: 16k of 18k distinct
    exact queries were farther than the 5 cm cutoff with spheres alone); the sphere is the
    tighter one for a rotated cube. Why not coal's DynamicAABBTreeCollisionManager: it answers
    collision / nearest-pair queries through a Python callback per pair, not "every pair closer
    than a cutoff"; with < 60 bodies per state the all-pairs bounds are a few numpy expressions."""
    planar = ctx.scene.dimension == 2
    key = ("bounds", planar, tuple(p.name for p in bodies))
    memo = _memo(ctx)
    const = memo.get(key)
    if const is None:          # per body: sphere centre, box centre (body frame); radius; half extents
        const = memo[key] = (np.array([[p.body.bounding_sphere(planar)[0], p.body.local_box()[0]] for p in bodies]),
                             np.array([p.body.bounding_sphere(planar)[1] for p in bodies]),
                             np.array([p.body.local_box()[1] for p in bodies]))
    centres, rs, h = const
    T = np.array([p.T for p in bodies])
    R = T[:, :3, :3]
    w = np.einsum("nij,nkj->nki", R, centres) + T[:, None, :3, 3]
    cs, wc = w[:, 0], w[:, 1]
    d = cs[:, None, :] - cs[None, :, :]
    sphere = np.sqrt((d * d).sum(axis=2)) - rs[:, None] - rs[None, :]
    wh = np.einsum("nij,nj->ni", np.abs(R), h)
    gaps = np.maximum(np.abs(wc[:, None, :] - wc[None, :, :]) - wh[:, None, :] - wh[None, :, :], 0.0)
    box = np.sqrt((gaps * gaps).sum(axis=2))
    return (sphere > cutoff) | (box > cutoff)


def _relevant(ctx, bodies: list[_Placed], ign: set, self_collision: bool, keep: Any) -> np.ndarray:
    """n x n (upper triangle): the pairs `pair_distances` measures, before the broadphase.

    Memoised by the bodies' names and static flags, the ignore set and the `keep` filter: the
    bodies of a scene are the same at every waypoint, so a verification builds a few of these."""
    key = ("relevant", tuple((p.name, p.owner, p.static) for p in bodies), frozenset(ign), self_collision, keep)
    memo = _memo(ctx)
    hit = memo.get(key)
    if hit is not None:
        return hit
    self_pairs = {name: {frozenset(p) for p in ctx.robot(name).self_pairs}
                  for name, s in ctx.scene.robots.items() if s.kind == "urdf"} if self_collision else {}
    n = len(bodies)
    out = np.zeros((n, n), dtype=bool)
    for i, j in itertools.combinations(range(n), 2):
        a, b = bodies[i], bodies[j]
        if a.static and b.static:
            continue
        if keep is not None and not keep(a, b):
            continue
        if a.owner == b.owner:
            if a.owner not in self_pairs:
                continue
            la, lb = a.name.split("/", 1)[1], b.name.split("/", 1)[1]
            if frozenset((la, lb)) not in self_pairs[a.owner]:
                continue
        if _ignored(a, b, ign):
            continue
        out[i, j] = True
    memo[key] = out
    return out


def pair_distances(ctx_or_scene, state: dict[str, Any], ignore: Iterable[Iterable[str]] = (), models=None,
                   self_collision: bool = True, cutoff: float | None = None,
                   keep: Any = None) -> list[PairDistance]:
    """Signed distances of every relevant pair, smallest first.

    Relevant: object-object (unless both static; a robot link no joint moves counts as static when
    the robot's base is the scene's), robot link-object, links of different robots,
    and each robot's self-collision pairs (SRDF-filtered); minus the scene's
    `ignore_collisions` and `ignore` (e.g. a held object and its robot, a block and its support).
    `cutoff`: pairs whose distance surely exceeds this are left out (`_far`: bounding spheres and
    boxes). `keep(a, b)`: a filter on the placed bodies (e.g. the categories a domain's `avoid`
    declaration names); it may read their name, owner and static flag, not their pose (its
    answers are memoised, `_relevant`).

    Each exact distance is memoised by the pair and its two world poses (exact bytes) in
    `ctx.verify_memo`: a block resting on a table, or any pair of bodies no motion moves, has
    the same distance at every waypoint of a motion (lab5: 10k of 28k queries repeated one).
    """
    ctx = _as_ctx(ctx_or_scene, models)
    ign = {frozenset(p) for p in ctx.scene.ignore_collisions} | {frozenset(p) for p in ignore}
    bodies = placed_bodies(ctx, state)
    if not bodies:
        return []
    mask = _relevant(ctx, bodies, ign, self_collision, keep)
    if cutoff is not None:
        mask = mask & ~_far(ctx, bodies, cutoff)
    ii, jj = np.nonzero(mask)             # row-major: the order of itertools.combinations
    memo = _memo(ctx)
    poses: dict[int, bytes] = {}
    out = []
    for i, j in zip(ii.tolist(), jj.tolist()):
        a, b = bodies[i], bodies[j]
        ka = poses.get(i)
        if ka is None:
            ka = poses[i] = a.T.tobytes()
        kb = poses.get(j)
        if kb is None:
            kb = poses[j] = b.T.tobytes()
        key = ("d", a.name, b.name, ka, kb)
        d = memo.get(key)
        if d is None:
            d = memo[key] = float(signed_distance(a.body, a.T[:3, :3], a.T[:3, 3], b.body, b.T[:3, :3], b.T[:3, 3]))
        out.append(PairDistance(a.name, b.name, d))
    out.sort(key=lambda p: p.distance)
    return out


def collisions(ctx_or_scene, state: dict[str, Any], margin: float = 0.0, ignore: Iterable[Iterable[str]] = (),
               models=None, tol: float = 1e-6) -> list[PairDistance]:
    """Pairs closer than `margin - tol` (empty list: the state is collision-free beyond the margin)."""
    return [p for p in pair_distances(ctx_or_scene, state, ignore, models) if p.distance < margin - tol]


def joint_limit_violations(ctx_or_scene, robot: str, q, tol: float = 1e-6, models=None) -> list[LimitViolation]:
    ctx = _as_ctx(ctx_or_scene, models)
    r = ctx.robot(robot)
    q = np.asarray(q, dtype=float).ravel()
    out = []
    for jc in r.coords:
        for k in range(jc.idx_c, jc.idx_c + jc.nc):
            if q[k] < r.lower[k] - tol or q[k] > r.upper[k] + tol:
                out.append(LimitViolation(robot, k, jc.name, float(q[k]), float(r.lower[k]), float(r.upper[k])))
    return out


DEFAULT_GRASP_BOX = (0.02, 0.04, 0.03)   # half extents around a parallel gripper's TCP (x, y, z)


def point_in_gripper(ctx_or_scene, robot: str, value, point, half_extents: tuple[float, ...] | None = None,
                     frame: str | None = None, models=None) -> GraspCheck:
    """Is a world point inside the grasp region of a robot's end effector?

    URDF robots: the box `half_extents` (default: the robot's `grasp_box` attribute or
    DEFAULT_GRASP_BOX) centred at the end-effector frame (`frame` or the scene `ee`), in that frame.
    Planar robots (`value` an SE2/SE3 pose): the same box in the robot's frame (z ignored in 2-D).
    """
    ctx = _as_ctx(ctx_or_scene, models)
    spec = ctx.scene.robots.get(robot)
    if spec is None:
        raise UserError(f"unknown robot '{robot}'")
    he = half_extents or tuple(spec.attributes.get("grasp_box", DEFAULT_GRASP_BOX))
    if spec.kind == "urdf":
        fr = frame or spec.ee
        if fr is None:
            raise UserError(f"robot {robot} has no end-effector frame (`ee:` in the scene)")
        q, base = robot_q_base(ctx, robot, value)
        T = ctx.fk_matrix(robot, q, fr, base)
    else:
        T = entity_matrix(ctx, robot, value)
    p = np.asarray(point, dtype=float).ravel()
    if p.size == 2:
        p = np.r_[p, 0.0]
    local = T[:3, :3].T @ (p - T[:3, 3])
    inside = all(abs(local[i]) <= he[i] + 1e-9 for i in range(min(3, len(he))))   # 2 extents: planar
    return GraspCheck(bool(inside), tuple(float(x) for x in local), tuple(he))


def convex_hull_2d(pts: np.ndarray) -> np.ndarray:
    """2-D convex hull (Andrew's monotone chain), counter-clockwise: the verifier's support
    polygons, the renderer's outlines and the mobile base's `compile.placement.Footprint`."""
    P = sorted(set(map(tuple, np.round(pts, 12))))
    if len(P) <= 2:
        return np.array(P)

    def cross(o, a, b):
        return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    lower, upper = [], []
    for p in P:
        while len(lower) >= 2 and cross(lower[-2], lower[-1], p) <= 0:
            lower.pop()
        lower.append(p)
    for p in reversed(P):
        while len(upper) >= 2 and cross(upper[-2], upper[-1], p) <= 0:
            upper.pop()
        upper.append(p)
    return np.array(lower[:-1] + upper[:-1])


def _in_polygon(pt, poly: np.ndarray, tol: float = 1e-9) -> bool:
    n = len(poly)
    if n < 3:
        return False
    for i in range(n):
        a, b = poly[i], poly[(i + 1) % n]
        if (b[0] - a[0]) * (pt[1] - a[1]) - (b[1] - a[1]) * (pt[0] - a[0]) < -tol:
            return False
    return True


def world_vertices(body: ConvexBody, T: np.ndarray) -> np.ndarray:
    pts = []
    for s, M in zip(body.shapes, body.placements):
        W = T @ M
        pts.append(shape_vertices(s) @ W[:3, :3].T + W[:3, 3])
    return np.vstack(pts)


def resting_on(ctx_or_scene, obj: str, obj_value, support: str, support_value=None, tol: float = 1e-3,
               models=None) -> RestingCheck:
    """Does `obj` rest on `support`?

    3-D, in the support's frame: the object's lowest point is within `tol` of the support's top,
    its centre projects inside the support's top face, and the two do not penetrate deeper than
    `tol`.
    Planar: the object's centre lies inside the support's footprint (a region on the table).
    """
    ctx = _as_ctx(ctx_or_scene, models)
    planar = ctx.scene.dimension == 2
    if support_value is None:
        support_value = scene_value(ctx, support)
    To, Ts = entity_matrix(ctx, obj, obj_value), entity_matrix(ctx, support, support_value)
    bo = ctx.body(obj, planar)
    bs = ctx.body(support, planar)
    d = signed_distance(bo, To[:3, :3], To[:3, 3], bs, Ts[:3, :3], Ts[:3, 3])
    vs = world_vertices(bs, Ts)
    if planar:
        inside = _in_polygon(To[:2, 3], convex_hull_2d(vs[:, :2]))
        return RestingCheck(inside, None, inside, d)
    # measured in the support's frame: a support that is itself slightly tilted (a block on a
    # block) still has an exact top face there, and the gap is the object's lowest point above it
    Ti = np.linalg.inv(Ts)
    vs_l = vs @ Ti[:3, :3].T + Ti[:3, 3]
    vo_l = world_vertices(bo, To) @ Ti[:3, :3].T + Ti[:3, 3]
    if Ts[2, 2] < 0:                      # the support lies upside down: its local -z is up
        vs_l[:, 2] *= -1
        vo_l[:, 2] *= -1
    top = vs_l[:, 2].max()
    gap = float(vo_l[:, 2].min() - top)
    top_face = vs_l[vs_l[:, 2] >= top - 1e-6][:, :2]
    centre = Ti[:3, :3] @ To[:3, 3] + Ti[:3, 3]
    inside = _in_polygon(centre[:2], convex_hull_2d(top_face)) if len(top_face) >= 3 else False
    ok = abs(gap) <= tol and inside and d >= -tol
    return RestingCheck(bool(ok), gap, bool(inside), d)


@dataclass
class StateReport:
    """Summary of one state: its closest pairs and limit violations."""

    distances: list[PairDistance]
    limits: list[LimitViolation]
    margin: float

    @property
    def collisions(self) -> list[PairDistance]:
        return [p for p in self.distances if p.distance < self.margin - 1e-6]

    @property
    def ok(self) -> bool:
        return not self.collisions and not self.limits

    def __str__(self) -> str:
        lines = [f"min distance {self.distances[0]}" if self.distances else "no collision pairs"]
        lines += [f"collision: {p}" for p in self.collisions]
        lines += [f"joint limit: {v.robot}.{v.joint} = {v.value:.4f} not in [{v.lower:.4f}, {v.upper:.4f}]"
                  for v in self.limits]
        return "\n".join(lines)


def check_state(ctx_or_scene, state: dict[str, Any], margin: float = 0.0, ignore: Iterable[Iterable[str]] = (),
                models=None) -> StateReport:
    """Distances of all relevant pairs and joint-limit violations of all URDF robots in a state."""
    ctx = _as_ctx(ctx_or_scene, models)
    dists = pair_distances(ctx, state, ignore)
    lims = []
    for name, spec in ctx.scene.robots.items():
        if spec.kind == "urdf":
            q, _ = robot_q_base(ctx, name, state_value(ctx, state, name))
            lims += joint_limit_violations(ctx, name, q)
    return StateReport(dists, lims, margin)



def check_states(ctx_or_scene, states: list[dict[str, Any]], margin: float = 0.0,
                 ignore: Iterable[Iterable[str]] = (), models=None) -> list[StateReport]:
    """`check_state` for a sequence (keyframes, or the waypoints of a trajectory)."""
    ctx = _as_ctx(ctx_or_scene, models)
    return [check_state(ctx, st, margin, ignore) for st in states]


def first_violation(reports: list[StateReport]) -> tuple[int, StateReport] | None:
    """Index and report of the first state that collides or leaves its joint limits."""
    for i, r in enumerate(reports):
        if not r.ok:
            return i, r
    return None
