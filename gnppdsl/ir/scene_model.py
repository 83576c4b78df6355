"""Scene model: the geometry a problem refers to (robots, objects, regions), loaded from YAML.

Why a separate contract: the YAML loader (`gnppdsl.ir.scene`, validation with file:line errors),
the graph-NLP factory (scene constants such as `radius(o)`), the geometry layer (pinocchio models,
coal shapes) and the renderer all read these dataclasses; none of them re-reads YAML.

Poses are stored fully resolved in the *world* frame as SE3 `[x, y, z, qx, qy, qz, qw]`, and for
planar scenes (`dimension: 2`) also as SE2 `[x, y, theta]` (`pose2`). The YAML schema is
documented in docs/scene.md.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Iterable


@dataclass(frozen=True)
class SceneShape:
    kind: str                               # "box", "cylinder", "sphere", "circle", "mesh", "none"
    size: tuple[float, ...] = ()            # box: (sx, sy, sz) full lengths; cylinder: (radius, length);
                                            # sphere/circle: (radius,); mesh: scale (sx, sy, sz)
    mesh_file: str | None = None            # absolute path for "mesh"


@dataclass(frozen=True)
class SceneObject:
    name: str
    shape: SceneShape
    pose: tuple[float, ...]                 # SE3 world pose [x, y, z, qx, qy, qz, qw]
    pose2: tuple[float, float, float] | None = None   # SE2 world pose for planar scenes
    parent: str | None = None               # kinematic parent in the scene file (informational)
    color: tuple[float, float, float, float] = (0.6, 0.6, 0.6, 1.0)
    static: bool = False                    # table, walls: never moved
    attributes: dict[str, Any] = field(default_factory=dict)   # extra numeric fields: radius, ...
    source: str = ""                        # "file:line:col" of its YAML entry, for diagnostics


@dataclass(frozen=True)
class SceneRobot:
    name: str
    kind: str                               # "urdf" (pinocchio model) or "planar" (SE2 gripper)
    model: str | None = None                # example-robot-data name, e.g. "panda"
    urdf: str | None = None                 # absolute path to a URDF
    srdf: str | None = None                 # optional SRDF (self-collision filtering)
    package_dirs: tuple[str, ...] = ()
    base: tuple[float, ...] = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)   # SE3 world pose of the base
    ee: str | None = None                   # end-effector frame, e.g. "panda_hand_tcp"
    locked: dict[str, float] = field(default_factory=dict)        # joint name -> locked value
    links: dict[str, str] = field(default_factory=dict)           # role -> link name (`link(r, "hand")`)
    home: tuple[float, ...] = ()            # home configuration (planar: SE2 pose)
    held_pose: tuple[float, ...] | None = None   # initial guess of a held object's pose
                                            # relative to the robot's gripper frame (SE3 / SE2)
    shape: SceneShape | None = None         # planar robots: their collision shape
    color: tuple[float, float, float, float] = (0.9, 0.9, 0.9, 1.0)
    attributes: dict[str, Any] = field(default_factory=dict)
    source: str = ""


@dataclass(frozen=True)
class Scene:
    name: str
    dimension: int                          # 2 (planar) or 3
    robots: dict[str, SceneRobot]
    objects: dict[str, SceneObject]
    ignore_collisions: frozenset[frozenset[str]] = frozenset()
    workspace: tuple[tuple[float, ...], tuple[float, ...]] | None = None   # (lower, upper) bounds
    path: str = ""                          # the YAML file

    def entity(self, name: str) -> SceneObject | SceneRobot | None:
        return self.objects.get(name) or self.robots.get(name)

    def static_obstacles(self, declared: Iterable[str]) -> dict[str, SceneObject]:
        """The objects with a shape that never move when the problem's objects are `declared`:
        those marked `static: true` and those the problem does not declare (a scene may hold
        more than one problem uses, e.g. a scene shared by a family; an object the logic cannot
        move stays at its scene pose). Scene order. Robots and declared movable objects must
        not collide with them: `Problem.static_obstacles` is what the solver's collision
        coverage and the independent verifier read."""
        names = set(declared)
        return {n: o for n, o in self.objects.items()
                if o.shape.kind != "none" and (o.static or n not in names)}


#: scene attributes the factory derives from an entry itself rather than from a key of the same
#: name (`compile.factory._attr_value`): a shape's `size` and `radius`, a robot's `home`,
#: `joint_min` / `joint_max` (its model) and `base`, any entry's `pose0` / `pose`
DERIVED_ATTRIBUTES = frozenset({"size", "radius", "home", "joint_min", "joint_max", "pose0", "pose", "base"})
