"""Scene shapes -> convex coal collision shapes.

Why convex only: coal's signed distance between two convex shapes (GJK + EPA) gives a normal that
is the exact gradient of the distance; BVH meshes give wrong penetration depths and zero normals,
so meshes become the convex hull of their vertices.

Planar scenes (`dimension: 2`) reuse the same 3-D machinery: every shape is extruded along z and
centred at z = 0. The extrusion height is chosen per shape (`planar_height`) so that two shapes
can never prefer to separate along z: for sizes a, b the z-overlap (hA + hB) / 2 exceeds any
in-plane penetration, which is at most min(a, b).
"""
from __future__ import annotations

import functools
import math

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.ir.scene_model import SceneShape

DEFAULT_CIRCLE_HEIGHT = 0.01   # a "circle" in a 3-D scene: a thin disc


def planar_extent(shape: SceneShape) -> float:
    """Largest in-plane size (diameter of the xy footprint's bounding circle)."""
    k, s = shape.kind, shape.size
    if k == "box":
        return math.hypot(s[0], s[1])
    if k in ("circle", "sphere", "cylinder"):
        return 2.0 * s[0]
    if k == "mesh":
        v = mesh_vertices(shape)
        return float(2.0 * np.linalg.norm(v[:, :2], axis=1).max())
    raise UserError(f"shape kind '{k}' has no planar extent")


def planar_height(shape: SceneShape) -> float:
    return 2.0 * planar_extent(shape) + 1.0


def _check(shape: SceneShape, n: int, what: str) -> None:
    if len(shape.size) < n or any((not math.isfinite(v)) or v <= 0 for v in shape.size[:n]):
        raise UserError(f"a {shape.kind} shape needs {what} (positive numbers), got {list(shape.size)}")


@functools.lru_cache(maxsize=256)
def mesh_vertices(shape: SceneShape) -> np.ndarray:
    """Scaled vertices of a mesh shape (trimesh loads STL/OBJ/DAE/...)."""
    import trimesh
    if not shape.mesh_file:
        raise UserError("a mesh shape needs a mesh file")
    try:
        m = trimesh.load(shape.mesh_file, force="mesh")
    except Exception as e:
        raise UserError(f"cannot load mesh {shape.mesh_file}: {e}") from None
    scale = np.ones(3)
    if shape.size:
        scale = np.resize(np.asarray(shape.size, dtype=float), 3)
    return np.asarray(m.vertices, dtype=float) * scale


def convex_from_points(points: np.ndarray, what: str = "mesh"):
    """coal.Convex hull of a point cloud (coal computes the hull; trimesh would need scipy)."""
    import coal
    pts = np.ascontiguousarray(np.asarray(points, dtype=float).reshape(-1, 3))
    if pts.shape[0] < 4:
        raise UserError(f"{what}: a convex shape needs at least 4 vertices, got {pts.shape[0]}")
    vec = coal.StdVec_Vec3s()
    for row in pts:
        vec.append(row)
    return coal.Convex.convexHull(vec, False, None)


def coal_shape(shape: SceneShape, planar: bool = False):
    """The convex coal shape of a scene shape (None for kind "none").

    `planar`: extrude in z for planar scenes (boxes given as (sx, sy) or (sx, sy, sz) keep their
    footprint; circles and spheres become cylinders)."""
    return _coal_shape_cached(shape, planar)


@functools.lru_cache(maxsize=1024)
def _coal_shape_cached(shape: SceneShape, planar: bool):
    import coal
    k = shape.kind
    if k == "none":
        return None
    if planar:
        h = planar_height(shape)
        if k == "box":
            _check(shape, 2, "size [sx, sy]")
            return coal.Box(float(shape.size[0]), float(shape.size[1]), h)
        if k in ("circle", "sphere", "cylinder"):
            _check(shape, 1, "a radius")
            return coal.Cylinder(float(shape.size[0]), h)
        if k == "mesh":
            v = mesh_vertices(shape)
            pts = np.vstack([np.c_[v[:, :2], np.full(len(v), -h / 2)], np.c_[v[:, :2], np.full(len(v), h / 2)]])
            return convex_from_points(pts, shape.mesh_file or "mesh")
        raise UserError(f"unknown shape kind '{k}'")
    if k == "box":
        _check(shape, 3, "size [sx, sy, sz]")
        return coal.Box(*(float(v) for v in shape.size[:3]))
    if k == "cylinder":
        _check(shape, 2, "[radius, length]")
        return coal.Cylinder(float(shape.size[0]), float(shape.size[1]))
    if k == "sphere":
        _check(shape, 1, "a radius")
        return coal.Sphere(float(shape.size[0]))
    if k == "circle":
        _check(shape, 1, "a radius")
        return coal.Cylinder(float(shape.size[0]), DEFAULT_CIRCLE_HEIGHT)
    if k == "mesh":
        return convex_from_points(mesh_vertices(shape), shape.mesh_file or "mesh")
    raise UserError(f"unknown shape kind '{k}' (expected box, cylinder, sphere, circle, mesh or none)")


def shape_vertices(shape) -> np.ndarray:
    """Vertices (n x 3, shape frame) approximating a convex coal shape: used by the renderer and
    the resting-on-support check. Curved shapes are sampled (24 points per circle)."""
    import coal
    if isinstance(shape, coal.Box):
        h = np.array(shape.halfSide)
        return np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * h
    if isinstance(shape, coal.Cylinder):
        a = np.linspace(0, 2 * np.pi, 24, endpoint=False)
        ring = np.c_[shape.radius * np.cos(a), shape.radius * np.sin(a)]
        return np.vstack([np.c_[ring, np.full(24, -shape.halfLength)], np.c_[ring, np.full(24, shape.halfLength)]])
    if isinstance(shape, coal.Sphere):
        pts = []
        for el in np.linspace(-np.pi / 2, np.pi / 2, 7):
            for az in np.linspace(0, 2 * np.pi, 12, endpoint=False):
                pts.append([np.cos(el) * np.cos(az), np.cos(el) * np.sin(az), np.sin(el)])
        return np.array(pts) * shape.radius
    if isinstance(shape, coal.Capsule):
        a = np.linspace(0, 2 * np.pi, 16, endpoint=False)
        pts = []
        for z in (-shape.halfLength, shape.halfLength):
            for el in np.linspace(-np.pi / 2, np.pi / 2, 5):
                for az in a:
                    pts.append([shape.radius * np.cos(el) * np.cos(az), shape.radius * np.cos(el) * np.sin(az),
                                z + shape.radius * np.sin(el)])
        return np.array(pts)
    if hasattr(shape, "points"):
        return np.array(shape.points())
    raise TypeError(f"no vertices for {type(shape).__name__}")
