"""Randomised instance families (paper 002 evaluates over randomised object positions, 100 runs):
a scene object may give ranges for its pose, and instance k of a problem is its scene with those
poses drawn with seed k.

Scene attributes (extra numeric keys of an object, `docs/scene.md`):
    random_xy: [x_lo, y_lo, x_hi, y_hi]   world box of the object's centre (x, y)
    random_yaw: [lo, hi]                  radians about the world z axis added to its pose
    random_clearance: d                   gap kept to the other drawn objects (default 0.03 m)
The height and the rest of the orientation stay as the scene gives them. Objects are drawn in
scene order; a draw whose footprint (the circle of the object's half-diagonal in x-y) comes
closer than the clearance to an object drawn before is drawn again (rejection sampling), so
drawn objects never overlap one another. Why attributes rather than new scene keys: extra
numeric keys are already part of the scene language (the loader checks and locates them), so an
instance family needs no new syntax and its scene stays a valid fixed scene (instance "none":
the poses as written).

Reproducible: `draw_instance(problem, k)` depends only on the scene and k (numpy's PCG64 seeded
with k), never on what was drawn before.
"""
from __future__ import annotations

import math
from dataclasses import replace
from typing import TYPE_CHECKING

from gnppdsl.errors import UserError

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.ir.model import Problem
    from gnppdsl.ir.scene_model import Scene, SceneObject

DEFAULT_CLEARANCE = 0.03
RANDOM_KEYS = ("random_xy", "random_yaw", "random_clearance")   # an object's draw ranges
MAX_DRAWS = 2000          # rejection-sampling attempts per object before the family is refused


def random_objects(scene: "Scene") -> list[str]:
    """The objects of `scene` whose pose is drawn per instance (scene order)."""
    return [n for n, o in scene.objects.items() if "random_xy" in o.attributes]


def footprint_radius(obj: "SceneObject") -> float:
    """Half the diagonal of the object's x-y extent (a circle containing its footprint)."""
    size = tuple(obj.shape.size or ())
    if obj.shape.kind in ("circle", "sphere", "cylinder") and size:
        return float(size[0])
    if len(size) >= 2:
        return 0.5 * math.hypot(size[0], size[1])
    return 0.0


def _numbers(value) -> tuple[float, ...]:
    return tuple(value) if isinstance(value, (list, tuple)) else (value,)


def range_error(key: str, value) -> str | None:
    """What is wrong with the value of a `random_*` attribute (None: nothing), by its shape
    alone: the scene loader reports it at the key (`gnpp check`), `draw_scene` again for scenes
    built in code. Pure Python: the loader stays free of numpy."""
    v = _numbers(value)
    if key == "random_xy":
        if len(v) != 4 or v[0] > v[2] or v[1] > v[3]:
            return f"random_xy must be [x_lo, y_lo, x_hi, y_hi] with lo <= hi (got {list(v)})"
    elif key == "random_yaw":
        if len(v) == 1:
            v = v * 2
        if len(v) != 2 or v[0] > v[1]:
            return f"random_yaw must be [lo, hi] in radians with lo <= hi, or one angle (got {list(v)})"
    elif key == "random_clearance":
        if len(v) != 1 or not v[0] >= 0:
            return f"random_clearance must be one distance >= 0 (got {value})"
    return None


def _ranges(obj: "SceneObject") -> tuple[tuple[float, float], tuple[float, float], tuple[float, float], float]:
    a = obj.attributes
    where = f"{obj.source}: object '{obj.name}'" if obj.source else f"object '{obj.name}'"
    for key in RANDOM_KEYS:
        problem = range_error(key, a[key]) if key in a else None
        if problem:
            raise UserError(f"{where}: {problem}")
    xy = tuple(float(x) for x in _numbers(a["random_xy"]))
    yaw = _numbers(a.get("random_yaw", 0.0))
    yaw = (float(yaw[0]), float(yaw[-1]))
    gap = float(_numbers(a.get("random_clearance", DEFAULT_CLEARANCE))[0])
    return xy[:2], xy[2:], yaw, gap


def _yawed(obj: "SceneObject", x: float, y: float, yaw: float, dim: int) -> "SceneObject":
    pose = list(obj.pose)
    pose[0], pose[1] = x, y
    if yaw:
        qx, qy, qz, qw = pose[3:7]
        c, s = math.cos(yaw / 2), math.sin(yaw / 2)          # q_z(yaw) * q (Hamilton, xyzw)
        pose[3:7] = [c * qx - s * qy, c * qy + s * qx, c * qz + s * qw, c * qw - s * qz]
    pose2 = obj.pose2
    if dim == 2 and pose2 is not None:
        pose2 = (x, y, pose2[2] + yaw)
    return replace(obj, pose=tuple(pose), pose2=pose2)


def draw_scene(scene: "Scene", seed: int) -> "Scene":
    """The scene of instance `seed`: every object with `random_xy` at a uniform draw."""
    names = random_objects(scene)
    if not names:
        return scene
    import numpy as np            # here: the scene loader imports this module for `range_error`

    rng = np.random.default_rng(int(seed))
    placed: list[tuple[np.ndarray, float, float]] = []          # (centre, radius, clearance)
    objects = dict(scene.objects)
    for name in names:
        obj = scene.objects[name]
        lo, hi, yaw, gap = _ranges(obj)
        lo, hi = np.array(lo), np.array(hi)
        r = footprint_radius(obj)
        for _ in range(MAX_DRAWS):
            p = lo + (hi - lo) * rng.random(2)
            t = yaw[0] + (yaw[1] - yaw[0]) * rng.random()
            if all(np.linalg.norm(p - c) >= r + rc + max(gap, gc) for c, rc, gc in placed):
                break
        else:
            raise UserError(f"{obj.source or scene.path}: object '{name}': no position in random_xy "
                            f"keeps {gap:g} m from the objects drawn before it after {MAX_DRAWS} draws "
                            f"(instance {seed}); widen the range or lower random_clearance")
        placed.append((p, r, gap))
        objects[name] = _yawed(obj, float(p[0]), float(p[1]), t, scene.dimension)
    return replace(scene, objects=objects)


def draw_instance(problem: "Problem", seed: int) -> "Problem":
    """`problem` with the scene of instance `seed` (`draw_scene`); an error when its scene
    has no object with `random_xy` (the family would have one member)."""
    scene = getattr(problem, "scene", None)
    if scene is None or not random_objects(scene):
        raise UserError(f"problem '{problem.name}': its scene gives no `random_xy` range, so it has "
                        f"no randomised instances (docs/scene.md, \"Randomised instances\")")
    if seed < 0:
        raise UserError(f"instance {seed}: must be >= 0")
    return replace(problem, scene=draw_scene(scene, seed))


__all__ = ["draw_instance", "draw_scene", "random_objects", "footprint_radius", "range_error"]
