"""Independent verification of a whole 3-D manipulation solution (keyframes AND trajectories).

Why a second computation: the solver's own re-check (`gnppdsl.nlp.evaluate`) re-evaluates the
factors it optimised, so a modelling gap (a link pair no template constrains, a trajectory
waypoint only the interpolation saw) cannot show up there. This module reads only the
*result* (the symbolic states as text and the numbers of each step) and the scene, and
recomputes everything with pinocchio forward kinematics and direct coal distances
(`gnppdsl.geometry.verify`): nothing goes through casadi, the factor bodies or the templates.

Conventions of the manipulation domains (configurable): `parent(o) = p` facts give the
kinematic tree of step i; `pose(o)` is o's pose relative to its parent's frame (a robot's
frame is its end effector, scene `ee`); `q(r)` is a robot's configuration at step i and
`path(r)` its motion from step i to step i+1 (objects keep the parents of step i during it:
the action switches them at the end).

Checks, each with the worst offender in the report:
- every keyframe and every interior waypoint: all pairs (objects, every robot link, self
  collisions) at signed distance >= `margin` (default: resting contact tolerance, -1 mm),
  except an object with its parent (it rests on it / is held by it);
- the collision bodies the domain constrains (`links`) keep `link_margin` from every object
  they do not hold, at keyframes;
- joint limits at keyframes and waypoints; trajectories start and end at their keyframes;
- every held object: the end-effector point lies inside the object and the object's
  narrow axis is across the fingers, no wider than the gripper opening;
- every object whose parent is a place rests on it (`resting_on`: no gap, centre over the face);
- the plan is valid for the SAS+ task and reaches the goal (`gnppdsl.logic.validate`).
"""
from __future__ import annotations

import re
from dataclasses import dataclass, field
from typing import Any, Iterable

import numpy as np

from gnppdsl.geometry.robots import matrix_to_se3, se3_to_matrix
from gnppdsl.geometry.verify import joint_limit_violations, pair_distances, resting_on

_FACT = re.compile(r"(\w+)\((\w+)\)\s*=\s*(\w+)")


@dataclass
class SolutionReport:
    ok: bool
    failures: list[str] = field(default_factory=list)
    keyframes: int = 0
    waypoints: int = 0
    min_distance: float = np.inf          # smallest pair distance seen (keyframes + waypoints)
    min_link_distance: float = np.inf     # smallest constrained link - object distance (keyframes)

    def __str__(self) -> str:
        head = (f"{'OK' if self.ok else 'FAILED'}: {self.keyframes} keyframes, {self.waypoints} "
                f"waypoints, min distance {self.min_distance:+.4f}, min link distance "
                f"{self.min_link_distance:+.4f}")
        return "\n".join([head, *self.failures[:20]])


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
            T = self.ctx.fk_matrix(name, self.configs[name], spec.ee)
        elif name in self.parents and name in self.poses:
            T = self.matrix(self.parents[name], depth + 1) @ se3_to_matrix(self.poses[name])
        else:
            T = se3_to_matrix(np.asarray(sc.objects[name].pose, float))
        self._memo[name] = T
        return T

    def state(self) -> dict[str, Any]:
        st: dict[str, Any] = {r: np.asarray(q, float) for r, q in self.configs.items()}
        for name in self.ctx.scene.objects:
            st[name] = matrix_to_se3(self.matrix(name))
        return st


def verify_solution(ctx: Any, result: Any, *, margin: float = -1e-3, link_margin: float = 0.01,
                    links: Iterable[str] = ("panda_link5", "panda_link6", "panda_hand"),
                    tolerance: float = 1e-4, rest_tolerance: float = 2e-3,
                    gripper_opening: float = 0.08,
                    parent_var: str = "parent", pose_var: str = "pose", config_var: str = "q",
                    path_var: str = "path", self_collision: bool = True,
                    check_logic: bool = True) -> SolutionReport:
    """Verify a solved `Result` of a 3-D manipulation problem against its scene (`ctx`: a
    `GeometryContext`). `tolerance` absorbs the solver's constraint tolerance and the 1 mm
    resting contact; `rest_tolerance` the gap allowed under a resting object (the templates'
    upright tolerance lets a 15 cm block tilt 0.8 deg: 1.1 mm at its lowest corner); see the
    module docstring for what is checked."""
    rep = SolutionReport(ok=True)
    fail = rep.failures.append
    sc = ctx.scene
    robots = [r for r, s in sc.robots.items() if s.kind == "urdf"]
    links = tuple(links)
    steps = list(result.steps)
    if not steps:
        return SolutionReport(False, ["no steps in the result"])

    def parse(step) -> dict[str, str]:
        return {o: p for var, o, p in _FACT.findall(step.state) if var == parent_var}

    def values(step, var: str, name: str):
        v = step.values.get(f"{var}({name})")
        return None if v is None else np.asarray(v, float)

    worlds = []
    for st in steps:
        parents = parse(st)
        poses = {o: values(st, pose_var, o) for o in parents if values(st, pose_var, o) is not None}
        configs = {}
        for r in robots:
            q = values(st, config_var, r)
            configs[r] = q if q is not None else ctx.robot(r).home_coords(sc.robots[r].home)
        worlds.append(_World(ctx, parents, poses, configs))

    def collide(w: _World, where: str) -> None:
        # resting contacts are allowed by the margin; only a held object may touch its robot
        ignore = [(o, p) for o, p in w.parents.items() if p in sc.robots]
        dists = pair_distances(ctx, w.state(), ignore=ignore, self_collision=self_collision)
        if dists:
            rep.min_distance = min(rep.min_distance, dists[0].distance)
        for d in dists:
            if d.distance < margin - tolerance:
                fail(f"{where}: collision {d}")

    for i, w in enumerate(worlds):
        where = f"s{i}"
        rep.keyframes += 1
        collide(w, where)
        state = w.state()
        for r in robots:
            for v in joint_limit_violations(ctx, r, w.configs[r], tol=tolerance):
                fail(f"{where}: joint limit {r}.{v.joint} = {v.value:.4f} not in [{v.lower:.4f}, {v.upper:.4f}]")
        # constrained links keep their margin from objects they do not hold
        held = {o: p for o, p in w.parents.items() if p in sc.robots}
        lk = [d for d in pair_distances(ctx, state, ignore=[(o, p) for o, p in w.parents.items()
                                                           if p not in sc.robots],
                                        self_collision=False)
              if "/" in d.a or "/" in d.b]
        for d in lk:
            link_side, other = (d.a, d.b) if "/" in d.a else (d.b, d.a)
            robot, link = link_side.split("/", 1)
            if link not in links or "/" in other or held.get(other) == robot:
                continue
            rep.min_link_distance = min(rep.min_link_distance, d.distance)
            if d.distance < link_margin - tolerance:
                fail(f"{where}: {link_side} closer than {link_margin} to {other}: {d.distance:+.4f}")
        for o, p in w.parents.items():
            To = w.matrix(o)
            if p in sc.robots:
                fail_grasp = _grasp_failure(ctx, o, To, w.matrix(p), gripper_opening, tolerance)
                if fail_grasp:
                    fail(f"{where}: grasp of {o} by {p}: {fail_grasp}")
            else:
                chk = resting_on(ctx, o, matrix_to_se3(To), p, matrix_to_se3(w.matrix(p)),
                                 tol=rest_tolerance)
                if not chk.ok:
                    fail(f"{where}: {o} does not rest on {p} (gap {chk.gap:+.4f}, centre over "
                         f"face {chk.inside}, distance {chk.distance:+.4f})")
    # trajectories: interior waypoints with the parents of step i
    for i, st in enumerate(steps[:-1]):
        paths = {r: np.asarray(st.trajectories[f"{path_var}({r})"], float)
                 for r in robots if f"{path_var}({r})" in st.trajectories}
        if not paths:
            continue
        w0, w1 = worlds[i], worlds[i + 1]
        n = max(len(p) for p in paths.values())
        for r, P in paths.items():
            for k, ref in ((0, w0.configs[r]), (len(P) - 1, w1.configs[r])):
                if np.max(np.abs(P[k] - ref)) > tolerance:
                    fail(f"path s{i}->s{i + 1}: {r} waypoint {k} is not the keyframe configuration")
        for k in range(1, n - 1):
            configs = dict(w0.configs)
            for r, P in paths.items():
                configs[r] = P[min(k, len(P) - 1)]
            w = _World(ctx, w0.parents, w0.poses, configs)
            rep.waypoints += 1
            collide(w, f"path s{i}->s{i + 1} waypoint {k}")
            for r in paths:
                for v in joint_limit_violations(ctx, r, configs[r], tol=tolerance):
                    fail(f"path s{i}->s{i + 1} waypoint {k}: joint limit {r}.{v.joint} = {v.value:.4f}")
    if check_logic:
        extras = getattr(result, "extras", None) or {}
        task, plan = extras.get("task"), extras.get("plan")
        if task is None or plan is None:
            fail("no task / plan in the result to validate the logic")
        else:
            from gnppdsl.logic.validate import validate_plan
            v = validate_plan(task, plan)
            if not v:
                fail(f"plan invalid: {v.error}")
    rep.ok = not rep.failures
    return rep


def _grasp_failure(ctx: Any, obj: str, To: np.ndarray, Tee: np.ndarray, opening: float,
                   tol: float) -> str | None:
    """The fingertip centre lies inside the box and the fingers (ee y axis) close across the
    box's axis whose extent fits the opening. None if fine, else the reason."""
    shape = ctx.scene.objects[obj].shape
    size = np.asarray(getattr(shape, "size", None) or (), float)
    if size.size != 3:
        return None if shape.kind == "none" else f"cannot check a {shape.kind} grasp"
    local = To[:3, :3].T @ (Tee[:3, 3] - To[:3, 3])
    if np.any(np.abs(local) > size / 2 + tol):
        return f"tcp at {np.round(local, 4).tolist()} in the box frame is outside the box {size.tolist()}"
    y = To[:3, :3].T @ Tee[:3, 1]               # finger closing direction in the box frame
    ax = int(np.argmax(np.abs(y)))
    if abs(y[ax]) < 1 - 1e-3:
        return f"fingers not aligned with a box axis (closing direction {np.round(y, 4).tolist()})"
    if size[ax] > opening + tol:
        return f"box width {size[ax]:.3f} across the fingers exceeds the opening {opening}"
    return None
