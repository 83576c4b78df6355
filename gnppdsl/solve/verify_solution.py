"""Independent verification of a whole solution (keyframes, trajectory waypoints and the
straight segments between them).

Why a second computation: the solver's own re-check (`gnppdsl.nlp.evaluate`) re-evaluates the
factors it optimised, so a modelling gap (a link pair no template constrains, a trajectory
waypoint only the interpolation saw) cannot show up there. This module reads only the
*result* (the symbolic states as text and the numbers of each step) and the scene, and
recomputes everything with pinocchio forward kinematics and direct coal distances
(`gnppdsl.geometry.verify`): nothing goes through casadi, the factor bodies or the templates.

Conventions of the manipulation domains (configurable): `parent(o) = p` facts give the
kinematic tree of step i; `pose(o)` is o's pose relative to its parent's frame (a robot's
frame is its end effector, scene `ee`; a planar robot's frame is its pose `q`); `q(r)` is a
robot's configuration at step i and `path(r)` its motion from step i to step i+1 (objects keep
the parents of step i during it: the action switches them at the end).

Checks (each failure a `Failure`: kind, step, waypoint, bodies, distance):
- `collision`: at every keyframe, every interior waypoint and the midpoint of every segment of
  a motion (consumers replay a motion by linear interpolation in joint space; the midpoint of
  segments no longer than a robot's `max_step` catches a link sweeping through a thin body
  between two clean waypoints), every pair the domain's `avoid` categories cover (objects,
  every robot link, SRDF-filtered self pairs, static scene bodies, objects the problem does not
  declare) at signed distance >= `margin` (default: the resting contact tolerance, -1 mm: two
  boxes side by side in a tray touch) and, when one body is a robot link, >= `robot_margin`
  (default 0: nothing legitimately rests on a robot), each less `tolerance` (0.1 mm); a held
  object with its robot is exempt; far pairs are dropped first by two lower bounds on their
  distance, bounding spheres and the bodies' local AABBs turned into the world
  (`geometry.verify._far`). (sort4's R-LGP solution once left a finger 0.14 mm inside a block
  in the tray: inside the 1 mm resting tolerance then applied to every pair, so the loop
  reported it verified while `tests/rebuilt_check.py` saw the contact);
- `joint_limit` at keyframes and waypoints; `boundary`: a motion starts and ends at its
  keyframes;
- `grasp`: every held object's box contains the end-effector point and its narrow axis lies
  across the fingers, no wider than the gripper opening (3-D); planar: the gripper frame lies
  inside the object's footprint (its bounding circle);
- `placement`: every object whose parent is a place rests on it (`resting_on`); an object whose
  parent is a tool a robot holds touches the tool and rests on a static body (a pushed block);
- `plan` / `goal`: the plan is valid for the SAS+ task and reaches the goal
  (`gnppdsl.logic.validate`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from gnppdsl.geometry.robots import matrix_to_se3
from gnppdsl.geometry.verify import entity_matrix, joint_limit_violations, pair_distances, resting_on

_FACT = re.compile(r"(\w+)\((\w+)\)\s*=\s*(\w+)")

CATEGORIES = ("robots", "objects", "scene")
"""What a domain's `avoid` declaration can name: robot links (with each robot's SRDF-filtered
self pairs), the movable objects, the static scene bodies (`static: true` in the scene, robot
links no joint moves). A pair is checked when both its bodies' categories are named."""

BROADPHASE = 0.05
"""Pairs surely more than this apart (m: bounding spheres or boxes, `geometry.verify._far`) skip
the exact query: 5 cm above any margin the verification or the active set use."""


@dataclass(frozen=True)
class Failure:
    """One thing the verification found wrong. `step` i: keyframe s_i, or with `waypoint` the
    motion s_i -> s_i+1 (an integer: that waypoint; k + 0.5: the midpoint of segment k, k+1)."""

    kind: str                           # collision | joint_limit | boundary | grasp | placement | plan | goal
    step: int | None = None
    waypoint: float | None = None
    bodies: tuple[str, ...] = ()
    distance: float | None = None
    detail: str = ""

    @property
    def where(self) -> str:
        if self.step is None:
            return "plan"
        if self.waypoint is None:
            return f"s{self.step}"
        k = self.waypoint
        pos = f"waypoint {int(k)}" if float(k).is_integer() else f"midpoint {int(k)}-{int(k) + 1}"
        return f"path s{self.step}->s{self.step + 1} {pos}"

    def __str__(self) -> str:
        what = self.kind.replace("_", " ")
        if self.step is None:                 # the plan / goal: the validator's message says it
            return self.detail
        if self.kind == "boundary":
            return (f"path s{self.step}->s{self.step + 1}: {self.bodies[0]} waypoint {int(self.waypoint)} "
                    f"is not the keyframe configuration")
        if self.kind == "collision":
            return f"{self.where}: collision {self.bodies[0]} <-> {self.bodies[1]}: {self.distance:+.4f}"
        return f"{self.where}: {what} {self.detail}".rstrip()

    def to_json(self) -> dict:
        return {"kind": self.kind, "step": self.step, "waypoint": self.waypoint,
                "bodies": list(self.bodies),
                "distance": None if self.distance is None else float(self.distance),
                "message": str(self)}


@dataclass
class SolutionReport:
    ok: bool
    issues: list[Failure] = field(default_factory=list)
    keyframes: int = 0
    waypoints: int = 0
    midpoints: int = 0
    min_distance: float = np.inf          # smallest pair distance seen (keyframes, waypoints, midpoints)
    # (step, waypoint, body a, body b, distance) of every checked pair closer than `near`
    near: list[tuple] = field(default_factory=list)
    # (step i, object) -> the static bodies an object riding on a held tool rests on at keyframe
    # s_i (`placement`): its sliding contact, a resting contact like an object's with its parent
    riding: dict[tuple[int, str], tuple[str, ...]] = field(default_factory=dict)

    @property
    def failures(self) -> list[str]:
        return [str(f) for f in self.issues]

    def __str__(self) -> str:
        head = (f"{'OK' if self.ok else 'FAILED'}: {self.keyframes} keyframes, {self.waypoints} "
                f"waypoints, {self.midpoints} midpoints, min distance {self.min_distance:+.4f}")
        return "\n".join([head, *self.failures[:20]])

    def to_json(self) -> dict:
        return {"ok": self.ok, "failures": [f.to_json() for f in self.issues],
                "keyframes": self.keyframes, "waypoints": self.waypoints, "midpoints": self.midpoints,
                "min_distance": float(self.min_distance) if np.isfinite(self.min_distance) else None}


class _World:
    """World placements of one step from the result's numbers (pinocchio FK, numpy)."""

    def __init__(self, ctx: Any, parents: dict[str, str], poses: dict[str, np.ndarray],
                 configs: dict[str, np.ndarray]):
        self.ctx, self.parents, self.poses, self.configs = ctx, parents, poses, configs
        self._memo: dict[str, np.ndarray] = {}

    def matrix(self, name: str, depth: int = 0) -> np.ndarray:
        if name in self._memo:
            return self._memo[name]
        if depth > 64:
            raise ValueError(f"cyclic parent chain at {name}")
        sc = self.ctx.scene
        if name in sc.robots:
            spec = sc.robots[name]
            if spec.kind == "urdf":
                T = self.ctx.fk_matrix(name, self.configs[name], spec.ee)
            else:
                T = entity_matrix(self.ctx, name, self.configs[name])
        elif name in self.parents and name in self.poses:
            T = self.matrix(self.parents[name], depth + 1) @ entity_matrix(self.ctx, name, self.poses[name])
        else:
            o = sc.objects[name]
            pose = o.pose2 if (sc.dimension == 2 and o.pose2 is not None) else o.pose
            T = entity_matrix(self.ctx, name, pose)
        self._memo[name] = T
        return T

    def state(self) -> dict[str, Any]:
        st: dict[str, Any] = {}
        for r, q in self.configs.items():
            st[r] = np.asarray(q, float) if self.ctx.scene.robots[r].kind == "urdf" else matrix_to_se3(self.matrix(r))
        for name in self.ctx.scene.objects:
            st[name] = matrix_to_se3(self.matrix(name))
        return st


def _category(ctx: Any, body: Any, fixed: frozenset) -> str:
    if body.owner in ctx.scene.robots:
        return "robots"
    return "scene" if body.static or body.owner in fixed else "objects"


def avoid_filter(ctx: Any, avoid: tuple[str, ...] | None, fixed: frozenset = frozenset()) -> Callable | None:
    """`keep(a, b)` for `pair_distances`: both bodies' categories among `avoid` (None: all),
    and not both static. `fixed`: scene objects the problem does not declare (static obstacles
    at their scene pose)."""
    names = set(CATEGORIES if avoid is None else avoid)
    if names >= set(CATEGORIES) and not fixed:
        return None

    def keep(a, b) -> bool:
        ca, cb = _category(ctx, a, fixed), _category(ctx, b, fixed)
        return ca in names and cb in names and not (ca == cb == "scene")
    return keep


def verify_solution(ctx: Any, result: Any, *, margin: float = -1e-3, robot_margin: float = 0.0,
                    tolerance: float = 1e-4,
                    rest_tolerance: float = 2e-3, gripper_opening: float = 0.08,
                    planar_grasp: float | None = None, avoid: tuple[str, ...] | None = None,
                    declared: Any = None, near: float | None = None,
                    midpoints: bool = True,
                    parent_var: str = "parent", pose_var: str = "pose", config_var: str = "q",
                    path_var: str = "path", self_collision: bool = True,
                    check_logic: bool = True) -> SolutionReport:
    """Verify a solved `Result` against its scene (`ctx`: a `GeometryContext`). `tolerance`
    absorbs the solver's constraint tolerance; `rest_tolerance` the gap allowed under a resting
    object (the templates' upright tolerance lets a 15 cm block tilt 0.8 deg: 1.1 mm at its
    lowest corner); `avoid`: the categories of `CATEGORIES` whose pairs are checked (the
    domain's `avoid` declaration; None: all); `declared`: the problem's objects (the other scene
    objects are static obstacles; None: all are the problem's); `near`: pairs closer than this
    are listed in `SolutionReport.near` (what the active set adds). See the module docstring."""
    rep = SolutionReport(ok=True)
    fail = rep.issues.append
    sc = ctx.scene
    robots = list(sc.robots)
    urdf = {r for r in robots if sc.robots[r].kind == "urdf"}
    fixed = frozenset(set(sc.objects) - set(declared)) if declared is not None else frozenset()
    keep = avoid_filter(ctx, avoid, fixed)
    steps = list(result.steps)
    if not steps:
        return SolutionReport(False, [Failure("plan", detail="no steps in the result")])

    def parse(step) -> dict[str, str]:
        return {o: p for var, o, p in _FACT.findall(step.state) if var == parent_var}

    def values(step, var: str, name: str):
        v = step.values.get(f"{var}({name})")
        return None if v is None else np.asarray(v, float)

    def home(r: str):
        spec = sc.robots[r]
        if r in urdf:
            return ctx.robot(r).home_coords(spec.home)
        return np.asarray(spec.home or spec.base, float)

    worlds = []
    for st in steps:
        parents = parse(st)
        poses = {o: values(st, pose_var, o) for o in parents if values(st, pose_var, o) is not None}
        configs = {r: (q if (q := values(st, config_var, r)) is not None else home(r)) for r in robots}
        worlds.append(_World(ctx, parents, poses, configs))

    def collide(w: _World, step: int, waypoint: float | None) -> None:
        # resting contacts are allowed by the margin; only a held object may touch its robot
        # (planar: an object lies inside the region it is placed in, `placement` checks it)
        ignore = [(o, p) for o, p in w.parents.items() if p in sc.robots or sc.dimension == 2]
        dists = pair_distances(ctx, w.state(), ignore=ignore, self_collision=self_collision,
                               cutoff=BROADPHASE, keep=keep)
        if dists:
            rep.min_distance = min(rep.min_distance, dists[0].distance)
        for d in dists:
            floor = robot_margin if "/" in d.a or "/" in d.b else margin     # "robot/link"
            if d.distance < floor - tolerance:
                fail(Failure("collision", step, waypoint, (d.a, d.b), d.distance))
            if near is not None and d.distance < near:
                rep.near.append((step, waypoint, d.a, d.b, d.distance))

    def limits(configs: dict, step: int, waypoint: float | None) -> None:
        for r in urdf:
            for v in joint_limit_violations(ctx, r, configs[r], tol=tolerance):
                fail(Failure("joint_limit", step, waypoint, (r,), None,
                             f"{r}.{v.joint} = {v.value:.4f} not in [{v.lower:.4f}, {v.upper:.4f}]"))

    for i, w in enumerate(worlds):
        rep.keyframes += 1
        collide(w, i, None)
        limits(w.configs, i, None)
        for o, p in w.parents.items():
            To = w.matrix(o)
            if p in sc.robots:
                why = _grasp_failure(ctx, o, To, w.matrix(p), gripper_opening, tolerance, planar_grasp)
                if why:
                    fail(Failure("grasp", i, None, (o, p), None, f"of {o} by {p}: {why}"))
            elif p in w.parents and w.parents[p] in sc.robots:
                why, rep.riding[(i, o)] = _riding_failure(ctx, o, To, p, w.matrix(p), rest_tolerance)
                if why:
                    fail(Failure("placement", i, None, (o, p), None, why))
            elif _shapeless(sc, p):
                # a frame without a body (a planar spot): the object sits on that frame
                off = float(np.linalg.norm((np.linalg.inv(w.matrix(p)) @ To)[:3, 3]))
                if off > rest_tolerance:
                    fail(Failure("placement", i, None, (o, p), None, f"{o} is {off:.4f} from the frame of {p}"))
            else:
                chk = resting_on(ctx, o, matrix_to_se3(To), p, matrix_to_se3(w.matrix(p)), tol=rest_tolerance)
                if not chk.ok:
                    gap = "" if chk.gap is None else f"gap {chk.gap:+.4f}, "
                    fail(Failure("placement", i, None, (o, p), chk.distance,
                                 f"{o} does not rest on {p} ({gap}centre over face {chk.inside}, "
                                 f"distance {chk.distance:+.4f})"))
    # trajectories: interior waypoints (and segment midpoints) with the parents of step i
    for i, st in enumerate(steps[:-1]):
        paths = {r: np.asarray(st.trajectories[f"{path_var}({r})"], float)
                 for r in robots if f"{path_var}({r})" in st.trajectories}
        if not paths:
            continue
        w0, w1 = worlds[i], worlds[i + 1]
        n = max(len(p) for p in paths.values())
        for r, P in paths.items():
            for k, ref in ((0, w0.configs[r]), (len(P) - 1, w1.configs[r])):
                if np.max(np.abs(P[k] - np.asarray(ref, float))) > tolerance:
                    fail(Failure("boundary", i, float(k), (r,), None,
                                 f"{r} is not at the keyframe configuration of s{i if k == 0 else i + 1}"))

        def at(t: float) -> dict:
            configs = dict(w0.configs)
            for r, P in paths.items():
                lo = min(int(np.floor(t)), len(P) - 1)
                hi = min(lo + 1, len(P) - 1)
                configs[r] = P[lo] + (t - lo) * (P[hi] - P[lo])
            return configs

        for k in range(1, n - 1):
            configs = at(float(k))
            rep.waypoints += 1
            collide(_World(ctx, w0.parents, w0.poses, configs), i, float(k))
            limits(configs, i, float(k))
        if midpoints:
            for k in range(n - 1):
                rep.midpoints += 1
                collide(_World(ctx, w0.parents, w0.poses, at(k + 0.5)), i, k + 0.5)
    if check_logic:
        rep.issues += plan_failures(result)
    rep.ok = not rep.issues
    return rep


def plan_failures(result: Any) -> list[Failure]:
    """The logic part of the verification: the plan is valid for the SAS+ task and reaches the
    goal (`gnppdsl.logic.validate`); all a problem without a scene can be verified against."""
    extras = getattr(result, "extras", None) or {}
    task, plan = extras.get("task"), extras.get("plan")
    if task is None or plan is None:
        return [Failure("plan", detail="no task / plan in the result to validate the logic")]
    from gnppdsl.logic.validate import validate_plan
    v = validate_plan(task, plan)
    return [] if v else [Failure("goal" if v.error.startswith("goal") else "plan", detail=v.error)]


def _riding_failure(ctx: Any, obj: str, To: np.ndarray, tool: str, Tt: np.ndarray,
                    tol: float) -> tuple[str | None, tuple[str, ...]]:
    """An object whose parent is a tool a robot holds (a block pushed by a stick,
    stdlib/tools.pntc) touches the tool and rests on a static scene body (it slides on the
    table). (None, the static bodies it rests on) if so, else (the reason, those bodies). Why
    not `resting_on(obj, tool)`: the object is pushed by the tool's end, it does not lie on top
    of it."""
    sc = ctx.scene
    supports = tuple(s for s, b in sc.objects.items() if b.static and not _shapeless(sc, s)
                     and resting_on(ctx, obj, matrix_to_se3(To), s, tol=tol).ok)
    touch = resting_on(ctx, obj, matrix_to_se3(To), tool, matrix_to_se3(Tt), tol=tol).distance
    if touch > tol:
        return f"{obj} rides on {tool} {touch:.4f} away from it", supports
    if not supports:
        return f"{obj} rides on {tool} but rests on no static body", supports
    return None, supports


def _shapeless(sc: Any, name: str) -> bool:
    o = sc.objects.get(name)
    return o is not None and (o.shape is None or o.shape.kind == "none")


def _grasp_failure(ctx: Any, obj: str, To: np.ndarray, Tee: np.ndarray, opening: float,
                   tol: float, planar_grasp: float | None) -> str | None:
    """3-D boxes: the fingertip centre lies inside the box and the fingers (ee y axis) close
    across the box's axis whose extent fits the opening. Planar scenes: the gripper frame is
    within `planar_grasp` (default: the object's bounding circle) of its centre. None if fine, else the reason."""
    local = To[:3, :3].T @ (Tee[:3, 3] - To[:3, 3])
    if ctx.scene.dimension == 2:
        dist = float(np.linalg.norm(local[:2]))
        reach = planar_grasp if planar_grasp is not None else ctx.body(obj, True).bounding_sphere(True)[1]
        return None if dist <= reach + tol else f"gripper {dist:.4f} from the centre (> {reach:.4f})"
    shape = ctx.scene.objects[obj].shape
    size = np.asarray(getattr(shape, "size", None) or (), float)
    if size.size != 3:
        return None if shape.kind == "none" else f"cannot check a {shape.kind} grasp"
    if np.any(np.abs(local) > size / 2 + tol):
        return f"tcp at {np.round(local, 4).tolist()} in the box frame is outside the box {size.tolist()}"
    y = To[:3, :3].T @ Tee[:3, 1]               # finger closing direction in the box frame
    ax = int(np.argmax(np.abs(y)))
    if abs(y[ax]) < 1 - 1e-3:
        return f"fingers not aligned with a box axis (closing direction {np.round(y, 4).tolist()})"
    if size[ax] > opening + tol:
        return f"box width {size[ax]:.3f} across the fingers exceeds the opening {opening}"
    return None
