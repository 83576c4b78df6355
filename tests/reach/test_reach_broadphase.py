"""The reachability checker's broadphase (`CollisionChecker.config_free`): bounding spheres skip
the pairs that cannot be within the margin, so the decision must equal the one from every pair's
signed distance (`min_distance`), configuration by configuration, near contact included; and the
spheres must hold their shapes (every vertex inside)."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gnppdsl.geometry.robots import load_robot
from gnppdsl.geometry.shapes import shape_vertices
from gnppdsl.ir.scene import load_scene_file
from gnppdsl.reach.collision import CollisionChecker, bounding_sphere, static_obstacles

ROOT = Path(__file__).resolve().parents[2]


@pytest.mark.parametrize("scene_file, margin", [
    ("examples/mobile/sorting_setting.yaml", 0.02),       # mobile Panda among the tables
    ("examples/mobile/sorting_pr2_setting.yaml", 0.0),    # the PR2: several self pairs
    ("examples/lab/lab.yaml", 0.05),                      # two fixed Pandas on the Lab table
])
def test_broadphase_decides_as_every_pair_does(scene_file, margin):
    sc = load_scene_file(ROOT / scene_file)
    name = next(iter(sc.robots))
    robot = load_robot(sc.robots[name])
    ignore = frozenset(frozenset(p) for p in sc.ignore_collisions)
    checker = CollisionChecker(robot, static_obstacles(sc, name), margin, True, ignore,
                               fixed_base=sc.robots[name].attributes.get("base_joint") in (None, "fixed"))
    rng = np.random.default_rng(7)
    lo = np.where(np.isfinite(robot.lower), robot.lower, -np.pi)
    hi = np.where(np.isfinite(robot.upper), robot.upper, np.pi)
    home = robot.home_coords(sc.robots[name].home)
    free = blocked = near = 0
    for k in range(300):
        # half anywhere in the limits, half close to home (base and arm near the furniture)
        q = rng.uniform(lo, hi) if k % 2 else np.clip(home + rng.normal(0, 0.3, home.size), lo, hi)
        d = checker.min_distance(q)[0]
        assert checker.config_free(q) == (d >= margin), (k, d)
        free += d >= margin
        blocked += d < margin
        near += abs(d - margin) < 0.05
    assert free > 20 and blocked > 20 and near > 5, (free, blocked, near)


def test_bounding_spheres_hold_their_shapes():
    sc = load_scene_file(ROOT / "examples/mobile/sorting_pr2_setting.yaml")
    robot = load_robot(sc.robots["mm"])
    shapes = [g.shape for gs in robot.links.values() for g in gs]
    shapes += [o.shape for o in static_obstacles(sc, "mm")]
    assert len(shapes) > 20
    for s in shapes:
        c, r = bounding_sphere(s)
        v = shape_vertices(s)
        assert np.all(np.linalg.norm(v - c, axis=1) <= r + 1e-9)
        assert r < np.inf
