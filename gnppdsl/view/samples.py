"""The whole plan as timed world placements: what an animation shows at each sample time.

Why: a result holds keyframes (the configuration at each mode switch) and, on robot domains,
trajectories between them; neither says where a *held* block is at a waypoint, nor where each
link of an arm is. Here every sample time gets the world 4x4 placement of every visual body:
- URDF robots: each visual geometry of the pinocchio model (the URDF's meshes) at the robot's
  configuration (pinocchio `forwardKinematics` + `updateGeometryPlacements`, scene base);
- objects and planar robots: `world(o)` expanded along the kinematic chain of the step's symbolic
  state (`gnppdsl.solve.timing.world_poses`) with the robot configuration replaced by the
  waypoint (so a held block moves with the gripper); fixed objects at their scene pose.
Samples: every keyframe at its time, every interior trajectory waypoint at its time, and for
phases without trajectories (planar domains) INTERPOLATION points in between, the robot
configurations interpolated linearly (the motion the time stamps assume).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gnppdsl.geometry.render import mobile_base
from gnppdsl.geometry.robots import se3_to_matrix
from gnppdsl.solve.timing import motion_samples, result_states, world_poses

INTERPOLATION = 8      # samples per phase without a trajectory


@dataclass
class VisualBody:
    """One drawable body: a scene object, a planar robot, or one visual geometry of a URDF robot."""

    path: str                          # scene-tree path, e.g. "robots/left_arm/panda_link1_0"
    owner: str                         # the object or robot it belongs to
    kind: str                          # "box", "cylinder", "sphere", "mesh"
    size: tuple[float, ...] = ()
    mesh_file: str | None = None
    scale: tuple[float, float, float] = (1.0, 1.0, 1.0)
    color: tuple[float, float, float, float] | None = None   # None: the mesh's own materials
    static: bool = False               # never moves (one sample)
    planar: bool = False               # an extruded 2-D shape (drawn flat)


@dataclass
class Samples:
    times: list[float]
    bodies: list[VisualBody]
    placements: dict[str, list[np.ndarray]] = field(default_factory=dict)   # path -> 4x4 per time
    keyframe_times: list[float] = field(default_factory=list)
    planar: bool = False


def pose_matrix(pose: Any, planar: bool, height: float = 0.0) -> np.ndarray:
    """An SE2 [x, y, theta] (at `height`) or SE3 [x, y, z, qx, qy, qz, qw] pose as 4x4."""
    p = np.asarray(pose, float).reshape(-1)
    if planar or p.size == 3:
        c, s = np.cos(p[2]), np.sin(p[2])
        T = np.eye(4)
        T[:2, :2] = [[c, -s], [s, c]]
        T[:3, 3] = (p[0], p[1], height)
        return T
    return se3_to_matrix(p)


def sample_motion(result: dict[str, Any], compiled: Any) -> Samples:
    """Timed placements of every body of the scene along the solved plan in `result` (the JSON
    dict of `gnpp solve --json`, annotated with times)."""
    problem = compiled.problem
    scene = problem.scene
    planar = scene.dimension == 2
    steps = result["steps"]
    states = result_states(compiled.task, result["plan"])
    robots = {r: info for r, info in result.get("robots", {}).items()}
    value = {(k, i): np.asarray(v, float) for i, st in enumerate(steps) for k, v in st["values"].items()}
    visuals = {r: _robot_visuals(compiled, r) for r, spec in scene.robots.items()
               if spec.kind == "urdf" and r in problem.objects}
    bodies = _scene_bodies(scene, problem)
    for r, vis in visuals.items():
        bodies += vis.bodies
    samples = motion_samples(steps, robots, INTERPOLATION)
    out = Samples([t for t, _, _ in samples], bodies, {}, [st["time"] for st in steps], planar)
    movable = [b for b in bodies if not b.static and b.owner not in visuals]
    heights = {b.owner: _height(b) for b in movable}
    for t, i, over in samples:
        def value_of(key: str, step: int, i=i, over=over):
            if step == i and key in over:
                return over[key]
            return value.get((key, step))
        poses = world_poses(compiled, states, i, value_of, entities=[b.owner for b in movable])
        for b in movable:
            pose = poses.get(b.owner)
            T = pose_matrix(pose, planar, heights[b.owner]) if pose is not None else \
                scene_placement(scene.entity(b.owner), planar, heights[b.owner])    # no frame: scene pose
            out.placements.setdefault(b.path, []).append(T)
        for r, vis in visuals.items():
            key = robots.get(r, {}).get("configuration")
            q = value_of(key, i) if key else None
            if q is None:
                q = compiled.geometry.robot(r).home_coords(scene.robots[r].home)
            for path, T in vis.placements(q).items():
                out.placements.setdefault(path, []).append(T)
    for b in bodies:
        if b.static:
            out.placements[b.path] = [scene_placement(scene.entity(b.owner), planar, 0.0)]
    return out


def scene_placement(ent: Any, planar: bool, height: float) -> np.ndarray:
    """The world placement a scene object or robot has in the scene file."""
    if planar:
        pose2 = getattr(ent, "pose2", None) or (getattr(ent, "home", None) if hasattr(ent, "home") else None)
        if pose2 is not None and len(pose2) == 3:
            return pose_matrix(pose2, True, height)
    pose = getattr(ent, "pose", None) or getattr(ent, "base", None)
    T = se3_to_matrix(pose)
    if planar:
        T[2, 3] = height
    return T


def _height(b: VisualBody) -> float:
    """Planar scenes: movable objects above regions, robots above objects (no z-fighting)."""
    return 0.02 if b.path.startswith("robots/") else 0.01


def _scene_bodies(scene: Any, problem: Any) -> list[VisualBody]:
    """Scene objects of this problem (and every static object: furniture) and planar robots."""
    planar = scene.dimension == 2
    out = []
    for name, obj in scene.objects.items():
        if not obj.static and name not in problem.objects:
            continue                   # a movable object of another problem sharing the scene
        sh = obj.shape
        if sh.kind == "none":
            continue
        kind = "cylinder" if sh.kind == "circle" else sh.kind
        size = sh.size
        if planar and sh.kind == "circle":
            size = (sh.size[0], 0.02)
        out.append(VisualBody(f"objects/{name}", name, kind, tuple(size), sh.mesh_file,
                              tuple(sh.size) if sh.kind == "mesh" and len(sh.size) == 3 else (1.0, 1.0, 1.0),
                              tuple(obj.color) if obj.color else None, obj.static, planar))
    for name, spec in scene.robots.items():
        if spec.kind != "planar" or name not in problem.objects:
            continue
        sh = spec.shape
        r = sh.size[0] if sh is not None and sh.size else 0.03
        out.append(VisualBody(f"robots/{name}", name, "cylinder", (r, 0.02), None, (1, 1, 1),
                              tuple(spec.color), False, True))
    return out


class _RobotVisuals:
    """The URDF's visual meshes of one robot, placed by pinocchio at a configuration."""

    def __init__(self, compiled: Any, robot: str):
        import pinocchio as pin

        from gnppdsl.ir.robot_files import resolve_model_files, robot_data_share

        self.pin = pin
        rm = compiled.geometry.robot(robot)
        spec = compiled.problem.scene.robots[robot]
        self.model = rm
        pkg = list(spec.package_dirs)
        if spec.model:
            pkg.append(resolve_model_files(spec.model)[2])
        else:
            try:
                pkg.append(robot_data_share())
            except Exception:   # noqa: BLE001 - meshes found next to the URDF or not at all
                pass
        self.visual = pin.buildGeomFromUrdf(rm.model, rm.urdf, pin.GeometryType.VISUAL, package_dirs=pkg)
        self.data = rm.model.createData()
        self.vdata = pin.GeometryData(self.visual)
        self.bodies: list[VisualBody] = []
        self.paths: list[str] = []
        for go in self.visual.geometryObjects:
            path = f"robots/{robot}/{go.name}"
            color = None if go.meshPath.lower().endswith(".dae") and not go.overrideMaterial \
                else tuple(float(c) for c in go.meshColor)
            if go.meshPath and go.meshPath.lower().endswith((".dae", ".stl", ".obj")):
                body = VisualBody(path, robot, "mesh", (), go.meshPath, tuple(float(s) for s in go.meshScale), color)
            else:
                body = _primitive(path, robot, go)
                if body is None:
                    continue
            self.bodies.append(body)
            self.paths.append(path)
        self.spec = spec
        self.base_path = f"robots/{robot}/mobile_base"
        box = mobile_base(rm, spec, rm.home_coords(spec.home))
        if box is not None:                 # the URDF has no base body: a box under the arm
            self.bodies.insert(0, VisualBody(self.base_path, robot, "box", box[0], color=(0.27, 0.27, 0.31, 1.0)))

    def placements(self, q: np.ndarray) -> dict[str, np.ndarray]:
        pin = self.pin
        pin.forwardKinematics(self.model.model, self.data, self.model.to_pin_q(q))
        pin.updateGeometryPlacements(self.model.model, self.data, self.visual, self.vdata)
        base = self.model.base
        out = {}
        for k, path in enumerate(self.paths):
            gid = self.visual.getGeometryId(path.rsplit("/", 1)[1])
            out[path] = base @ np.asarray(self.vdata.oMg[gid].homogeneous)
        box = mobile_base(self.model, self.spec, q)
        if box is not None:
            out[self.base_path] = box[1]
        return out


def _robot_visuals(compiled: Any, robot: str) -> _RobotVisuals:
    return _RobotVisuals(compiled, robot)


def _primitive(path: str, robot: str, go: Any) -> VisualBody | None:
    """A URDF visual given as a primitive (box, cylinder, sphere) instead of a mesh."""
    import coal

    g = go.geometry
    color = tuple(float(c) for c in go.meshColor)
    if isinstance(g, coal.Box):
        return VisualBody(path, robot, "box", tuple(2 * np.asarray(g.halfSide)), color=color)
    if isinstance(g, coal.Cylinder):
        return VisualBody(path, robot, "cylinder", (g.radius, 2 * g.halfLength), color=color)
    if isinstance(g, coal.Sphere):
        return VisualBody(path, robot, "sphere", (g.radius,), color=color)
    return None
