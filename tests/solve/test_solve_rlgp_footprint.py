"""R-LGP's keyframe bases with the base's outline (`compile.placement.Footprint`) instead of the
disc of its farthest vertex: the polygon distance against brute force, the mobile Panda's
outline, and sort_random instance 5's pick of red1 started from the near (south) side."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.compile.placement import _footprint_free, _polygon_gap, base_footprint, base_radius
from gnppdsl.geometry.verify import convex_hull_2d

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"


def _boundary(P, n=200):
    P = np.asarray(P, float)
    out = [P[i] + t * (P[(i + 1) % len(P)] - P[i]) for i in range(len(P)) for t in np.linspace(0, 1, n)]
    return np.asarray(out)


def _inside(points, P):
    """Per point: inside the counter-clockwise convex polygon P (all edges' left sides)?"""
    P = np.asarray(P, float)
    ok = np.ones(len(points), bool)
    for i in range(len(P)):
        a, b = P[i], P[(i + 1) % len(P)]
        ok &= (b[0] - a[0]) * (points[:, 1] - a[1]) - (b[1] - a[1]) * (points[:, 0] - a[0]) >= -1e-12
    return ok


def test_polygon_gap_equals_brute_force():
    """`_polygon_gap` on random convex polygons: 0 exactly when a grid point lies in both, else
    the least distance between densely sampled boundaries (within the sampling's error)."""
    rng = np.random.default_rng(0)
    overlaps = separated = 0
    for _ in range(60):
        A = [tuple(p) for p in convex_hull_2d(rng.uniform(-1, 1, (8, 2)))]
        B = [tuple(p) for p in convex_hull_2d(rng.uniform(-1, 1, (8, 2)) + rng.uniform(-2.5, 2.5, 2))]
        gap = _polygon_gap(A, B)
        g = np.stack(np.meshgrid(np.linspace(-4, 4, 321), np.linspace(-4, 4, 321)), -1).reshape(-1, 2)
        common = np.any(_inside(g, A) & _inside(g, B))
        a, b = _boundary(A), _boundary(B)
        brute = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1)).min()
        if gap == 0.0:
            overlaps += 1
            assert common or brute < 0.03
        else:
            separated += 1
            assert not common
            assert gap == pytest.approx(brute, abs=0.02)
            assert gap <= brute + 1e-12              # the exact distance is never above a sample's
    assert overlaps > 5 and separated > 5


def test_convex_hull_is_counter_clockwise_and_contains_the_points():
    rng = np.random.default_rng(1)
    pts = rng.normal(size=(40, 2))
    H = [tuple(p) for p in convex_hull_2d(pts)]
    assert _inside(pts, H).all()
    area = sum(H[i][0] * H[(i + 1) % len(H)][1] - H[(i + 1) % len(H)][0] * H[i][1] for i in range(len(H)))
    assert area > 0


def _scene(name):
    from gnppdsl.ir.scene import load_scene_file

    return load_scene_file(MOBILE / name)


def test_mobile_panda_outline_reaches_less_forward_than_back():
    """panda_link0's hull reaches 0.154 m back and 0.072 m forward (x): the disc of `base_radius`
    takes 0.154 + 0.15 in every direction, the outline only what is there. Every outline vertex
    lies in the disc, and the radius is the outline's farthest vertex plus the clearance."""
    spec = _scene("sorting_setting.yaml").robots["mm"]
    fp = base_footprint(spec)
    assert fp is not None and fp.clearance == pytest.approx(0.15)
    xs = [p[0] for p in fp.hull]
    assert max(xs) == pytest.approx(0.072, abs=0.01) and min(xs) == pytest.approx(-0.154, abs=0.01)
    far = max(math.hypot(*p) for p in fp.hull)
    assert base_radius(spec) == pytest.approx(far + fp.clearance)


def test_outline_frees_the_point_facing_the_table_the_disc_refuses():
    """A base 0.289 m south of the central table's edge facing north (sort_random instance 5's
    red1 at (0.31, 0.22) on the innermost ring): its front keeps 0.217 m >= 0.15 of clearance
    (free), the disc of 0.305 m does not; turned round (back to the table) the outline does not
    clear it either; every free answer agrees with the polygons' distance."""
    scene = _scene("sorting_setting.yaml")
    spec = scene.robots["mm"]
    fp = base_footprint(spec)
    obstacles = [o for o in scene.objects.values() if o.static and len(o.pose) >= 7]
    x, y = 0.31, -0.45 - 0.289
    assert not _footprint_free(x, y, obstacles, base_radius(spec))
    assert fp.free(x, y, math.pi / 2, obstacles)
    assert not fp.free(x, y, -math.pi / 2, obstacles)
    rect = [(0.6, 0.45), (-0.6, 0.45), (-0.6, -0.45), (0.6, -0.45)]
    for yaw in np.linspace(-math.pi, math.pi, 13):
        c, s = math.cos(yaw), math.sin(yaw)
        outline = [(x + c * px - s * py, y + s * px + c * py) for px, py in fp.hull]
        gap = np.sqrt(((_boundary(outline)[:, None] - _boundary(rect)[None]) ** 2).sum(-1)).min()
        if abs(gap - fp.clearance) > 0.01:       # the brute-force gap decides the rest
            assert fp.free(x, y, yaw, obstacles) == (gap >= fp.clearance), yaw


def test_rlgp_pick_of_sort_random_5_starts_on_the_near_side():
    """sort_random instance 5, plan blue1 then red1: R-LGP's start for picking red1 (at (0.31,
    0.22), north of the table's middle, within reach from the south edge) is due south of it,
    facing north, 0.29 m off the table (the outer ring; the inner two lie in or too near the
    table). The disc refused that point and put the start at the 45-degree point (0.98, -0.46)
    on the same ring; the NLP then slid the base round to the north and the run drove 3.63 m
    against GNPP's 2.23 m."""
    from gnppdsl.compile.placement import RADII, restart_guesses
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.reach.drives import plan_bases
    from gnppdsl.solve.compiled import load_and_compile

    c = load_and_compile([str(MOBILE / "sort_random.pntc")], instance=5)
    plan = ("pick(blue1, mm, center); drop(blue1, mm, blue_tray); pick(red1, mm, center); "
            "drop(red1, mm, red_tray)")
    states = plan_states(c.task, parse_plan(c.task, plan))
    by_step = {v.step: q for v, q in restart_guesses(c.factory, c.factory.variables(states), states,
                                                     plan=plan_bases).items() if v.kind == "q"}
    red1 = np.asarray(c.problem.scene.objects["red1"].pose[:2], float)
    r = base_radius(c.problem.scene.robots["mm"])
    q = np.asarray(by_step[3][:2])
    assert np.linalg.norm(q - red1) == pytest.approx(r + RADII[2], abs=1e-6)
    assert q[1] < -0.45 - 0.2 and abs(q[0] - red1[0]) < 1e-6
    assert by_step[3][2] == pytest.approx(math.pi / 2)
