"""What a solution means as motion: names of coordinates, time stamps, world poses.

Why: the graph-NLP has no time variable. A trajectory `path(r)` is a list of waypoints whose
spacing the `smooth` templates bound, and a keyframe is a configuration at a mode switch. A
controller, a CSV reader or a viewer needs more: which number is which joint, and when each
waypoint is reached. This module adds both to a solved `Result` (`annotate_motion`), from the
robot models (pinocchio joint names and velocity limits) and the domain's declarations, and
nothing else: it does not change any value the solver returned.

Time parameterisation (piecewise linear in joint space, the simplest a position controller
can track): the waypoints of all trajectories of a phase s_i -> s_{i+1} share one time grid
(the NLP treats waypoint k of every robot as simultaneous: collision rows pair them); segment k
lasts as long as the slowest coordinate needs at VELOCITY_SCALE times its URDF velocity limit,
and at least MIN_SEGMENT seconds (so times strictly increase and a controller never divides
by zero). A phase without trajectories (planar domains) lasts as long as its robot
configurations need to move from keyframe to keyframe at that speed, at least MIN_PHASE.
Coordinates without a finite velocity limit (planar grippers, mobile bases whose URDF has none)
move at NOMINAL_LINEAR m/s or NOMINAL_ANGULAR rad/s.
"""
from __future__ import annotations

import math
import re
from dataclasses import dataclass
from typing import Any, Callable, Sequence

import numpy as np

VELOCITY_SCALE = 0.5        # fraction of the URDF velocity limit a timed trajectory uses
NOMINAL_LINEAR = 0.25       # m/s for translations without a velocity limit
NOMINAL_ANGULAR = 0.5       # rad/s for angles without a velocity limit
MIN_SEGMENT = 0.02          # s, shortest waypoint-to-waypoint segment
MIN_PHASE = 0.25            # s, shortest keyframe-to-keyframe phase without a trajectory

SPACE_COORDINATES = {
    "SE2": ("x", "y", "theta"),
    "SE3": ("x", "y", "z", "qx", "qy", "qz", "qw"),
    "quat": ("qx", "qy", "qz", "qw"),
}
_JOINT_SUFFIXES = {
    "planar": ("x", "y", "theta"),
    "free": ("x", "y", "z", "qx", "qy", "qz", "qw"),
    "spherical": ("qx", "qy", "qz", "qw"),
    "translation": ("x", "y", "z"),
}
_KEY = re.compile(r"^(\w+)\((.*)\)$")


@dataclass(frozen=True)
class Coordinates:
    """How to read the vector of one variable key (`q(left_arm)`)."""

    names: tuple[str, ...]              # one per component
    speed: tuple[float, ...]            # the velocity used for timing, per component (inf: ignored)
    robot: str | None = None            # the robot whose configuration (or motion) it is
    trajectory: bool = False            # a `traj` declaration: a list of waypoints


def split_key(key: str) -> tuple[str, tuple[str, ...]]:
    """`q(left_arm)` -> ("q", ("left_arm",)); `t` -> ("t", ())."""
    m = _KEY.match(key)
    if not m:
        return key, ()
    return m.group(1), tuple(a.strip() for a in m.group(2).split(",") if a.strip())


def coordinates(compiled: Any, key: str, dim: int) -> Coordinates:
    """The coordinate names and timing speeds of variable `key` (one point of `dim` numbers)."""
    kind, args = split_key(key)
    domain = getattr(compiled.problem, "domain", None)
    decl = getattr(domain, "continuous", {}).get(kind)
    space = getattr(decl, "space", None)
    tags = getattr(decl, "tags", frozenset())
    traj = bool(getattr(decl, "traj", False))
    robot = None
    if space is not None and space.kind == "joints" and decl is not None:
        names = [p.name for p in decl.params]
        robot = args[names.index(space.robot)] if space.robot in names else None
    elif "robot" in tags and len(args) == 1:
        robot = args[0]
    if space is not None and space.kind == "joints" and robot is not None and compiled.geometry is not None:
        model = compiled.geometry.robot(robot)
        jn, sp = joint_coordinates(model)
        if len(jn) == dim:
            return Coordinates(tuple(jn), tuple(sp), robot, traj)
    base = SPACE_COORDINATES.get(getattr(space, "kind", ""), ())
    if len(base) == dim:
        names = tuple(base)
    elif dim == 1:
        names = (key,)
    else:
        names = tuple(f"{key}[{k}]" for k in range(dim))
    moving = "robot" in tags
    speed = tuple(_nominal(n) if moving else math.inf for n in names)
    return Coordinates(names, speed, robot if moving else None, traj)


def _nominal(name: str) -> float:
    leaf = name.rsplit("_", 1)[-1]
    if leaf in ("theta",) or leaf.startswith("q") and len(leaf) == 2:
        return NOMINAL_ANGULAR
    return NOMINAL_LINEAR


def joint_coordinates(model: Any) -> tuple[list[str], list[float]]:
    """Planner-coordinate names of a `RobotModel` (pinocchio joint names; multi-coordinate
    joints get suffixes: `root_x`, `root_theta`) and the timing speed of each."""
    names: list[str] = []
    speeds: list[float] = []
    vlim = np.asarray(model.model.velocityLimit, float)
    for j in model.coords:
        jm = model.model.joints[model.model.getJointId(j.name)]
        if j.nc == 1:
            names.append(j.name)
            v = vlim[jm.idx_v] if jm.idx_v < vlim.size else math.inf
            linear = j.kind == "prismatic"
            speeds.append(VELOCITY_SCALE * v if 0 < v < 1e3 else
                          (NOMINAL_LINEAR if linear else NOMINAL_ANGULAR))
            continue
        for s in _JOINT_SUFFIXES[j.kind]:
            names.append(f"{j.name}_{s}")
            speeds.append(NOMINAL_ANGULAR if s == "theta" or s.startswith("q") else NOMINAL_LINEAR)
    return names, speeds


def _segment_time(a: np.ndarray, b: np.ndarray, speed: Sequence[float]) -> float:
    d = np.abs(np.asarray(b, float) - np.asarray(a, float))
    sp = np.asarray(speed, float)
    finite = np.isfinite(sp)
    return float(np.max(d[finite] / sp[finite])) if finite.any() else 0.0


def time_grid(steps: Sequence[Any], coords: dict[str, Coordinates]) -> tuple[list[float], list[dict[str, list[float]]]]:
    """Keyframe times t_0 .. t_n and, per phase, the time of every trajectory waypoint."""
    times = [0.0]
    traj_times: list[dict[str, list[float]]] = []
    for i, st in enumerate(steps):
        if i == len(steps) - 1:
            traj_times.append({})
            break
        nxt = steps[i + 1]
        t0 = times[-1]
        paths = {k: np.asarray(v, float) for k, v in st.trajectories.items() if k in coords}
        if paths:
            n = max(len(p) for p in paths.values())
            ts = [t0]
            for k in range(1, n):
                seg = max(_segment_time(p[min(k - 1, len(p) - 1)], p[min(k, len(p) - 1)], coords[key].speed)
                          for key, p in paths.items())
                ts.append(ts[-1] + max(seg, MIN_SEGMENT))
            traj_times.append({key: ts[:len(p)] for key, p in paths.items()})
            times.append(ts[-1])
            continue
        dur = 0.0
        for key, val in st.values.items():
            c = coords.get(key)
            if c is None or c.robot is None or key not in nxt.values:
                continue
            dur = max(dur, _segment_time(val, nxt.values[key], c.speed))
        traj_times.append({})
        times.append(t0 + max(dur, MIN_PHASE))
    return times, traj_times


def result_states(task: Any, plan: Sequence[str]) -> list[list[int]]:
    """The SAS+ states s_0 .. s_n of a plan given by action names (as in the result JSON),
    re-derived with the task's own semantics (`gnppdsl.compile.semantics`)."""
    from gnppdsl.compile.semantics import parse_plan, plan_states

    return [list(s) for s in plan_states(task, parse_plan(task, "\n".join(plan)))]


def motion_samples(steps: Sequence[dict], robots: dict[str, dict], interpolation: int = 8
                   ) -> list[tuple[float, int, dict[str, np.ndarray]]]:
    """The instants of a timed plan (JSON steps and `robots` of an annotated result): each
    keyframe, each interior trajectory waypoint and, in a phase without trajectories,
    `interpolation - 1` points with the robot configurations interpolated linearly (the motion
    the time stamps assume). Each as (time, step i whose kinematic chain applies, {configuration
    key: the value replacing that of step i})."""
    samples: list[tuple[float, int, dict[str, np.ndarray]]] = []
    for i, st in enumerate(steps):
        samples.append((st["time"], i, {}))
        if i == len(steps) - 1:
            break
        nxt = steps[i + 1]
        traj = {info["configuration"]: (np.asarray(st["trajectories"][info["trajectory"]], float),
                                         st["trajectory_times"][info["trajectory"]])
                for info in robots.values() if info.get("trajectory") in st["trajectories"]}
        if traj:
            n = max(len(t) for _, t in traj.values())
            for k in range(1, n - 1):
                t = max(ts[min(k, len(ts) - 1)] for _, ts in traj.values())
                samples.append((t, i, {key: pts[min(k, len(pts) - 1)] for key, (pts, _) in traj.items()}))
            continue
        for k in range(1, interpolation):
            a = k / interpolation
            over = {}
            for info in robots.values():
                key = info.get("configuration")
                if key in st["values"] and key in nxt["values"]:
                    over[key] = (1 - a) * np.asarray(st["values"][key]) + a * np.asarray(nxt["values"][key])
            samples.append(((1 - a) * st["time"] + a * nxt["time"], i, over))
    return samples


ValueOf = Callable[[str, int], "np.ndarray | None"]


def world_poses(compiled: Any, states: Sequence[Sequence[int]], step: int, value_of: ValueOf,
                entities: Sequence[str] | None = None) -> dict[str, np.ndarray]:
    """World poses (SE2 or SE3 vectors) of the movable scene entities at `step` (objects and
    planar robots; URDF robots are given by their joints), from the
    variables `value_of(key, step)` returns: `world(o)` expanded along the kinematic chain of
    that state by the factory, evaluated with the nlp layer's numpy interpreter. A caller can
    substitute a waypoint for a keyframe configuration (the pose of a held block along a
    trajectory). Objects without a frame (fixed at their scene pose) are left out."""
    from gnppdsl.compile.factors import FactorInstance
    from gnppdsl.compile.sas import PartialState
    from gnppdsl.ir.expr import Constraint, Num
    from gnppdsl.nlp.evaluate import constraint_rows

    problem = compiled.problem
    scene = getattr(problem, "scene", None)
    out: dict[str, np.ndarray] = {}
    if scene is None:               # no geometry (a logic-only or hand-built problem): no poses
        return out
    for obj in (entities if entities is not None else problem.objects):
        ent = scene.entity(obj) if scene is not None else None
        if ent is None or obj in scene.robots and scene.robots[obj].kind == "urdf":
            continue
        if problem.domain.frame_of(problem.objects[obj]) is None:
            continue
        try:
            expr, variables = compiled.factory.world_pose_expr(obj, states, step)
        except Exception:                 # noqa: BLE001 - a chain we cannot expand is not drawn
            continue
        values = {}
        for v in variables:
            x = value_of(v.key, v.step)
            if x is None:
                break
            values[v] = np.asarray(x, float)
        else:
            probe = FactorInstance("motion.world", "motion", (), frozenset(), step, 1, (PartialState(),),
                                   variables, (Constraint(expr, "==", Num(0.0)),))
            out[obj] = np.array([h for _, h in constraint_rows(probe, values, compiled.geometry)])
    return out


def annotate_motion(result: Any, compiled: Any) -> None:
    """Add coordinate names, time stamps and world poses to a solved `Result` (in place).
    Unsolved results get only the input files."""
    problem = compiled.problem
    files = {"problem": getattr(problem, "path", None), "domain": getattr(getattr(problem, "domain", None), "path", None)}
    result.inputs = {k: _abs(v) for k, v in files.items() if v}
    if not result.solved or not result.steps:
        return
    coords: dict[str, Coordinates] = {}
    for st in result.steps:
        for key, val in st.values.items():
            coords.setdefault(key, coordinates(compiled, key, len(val)))
        for key, pts in st.trajectories.items():
            coords.setdefault(key, coordinates(compiled, key, len(pts[0]) if pts else 0))
    result.coordinates = {k: list(c.names) for k, c in coords.items()}
    robots: dict[str, dict[str, Any]] = {}
    for key, c in coords.items():
        if c.robot is None:
            continue
        entry = robots.setdefault(c.robot, {"joints": list(c.names)})
        entry["trajectory" if c.trajectory else "configuration"] = key
    result.robots = robots
    times, traj_times = time_grid(result.steps, coords)
    states = result.extras.get("plan").states if result.extras.get("plan") is not None else \
        result_states(compiled.task, result.plan)
    by = {(k, i): v for i, st in enumerate(result.steps) for k, v in st.values.items()}
    for i, st in enumerate(result.steps):
        st.time = times[i]
        st.trajectory_times = traj_times[i]
        st.world = {o: [float(x) for x in p]
                    for o, p in world_poses(compiled, states, i, lambda k, s: by.get((k, s))).items()}


def _abs(path: str) -> str:
    from pathlib import Path
    return str(Path(path).resolve())
