"""`distance.signed_distance_at`, the numeric checker's query from SE3 poses (shape placements
and poses composed in plain floats): the same values as the 4x4-matrix path
(`robots.se3_to_matrix` then `signed_distance`), for robot links (placed shapes), scene
objects (identity placements) and unnormalised quaternions."""
from __future__ import annotations

import numpy as np

from gnppdsl.geometry import distance as D
from gnppdsl.geometry.context import GeometryContext
from gnppdsl.geometry.robots import se3_to_matrix
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

I7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


def _ctx() -> GeometryContext:
    objs = [SceneObject("box", SceneShape("box", (0.3, 0.2, 0.1), None), I7),
            SceneObject("cyl", SceneShape("cylinder", (0.05, 0.3), None), I7),
            SceneObject("ball", SceneShape("sphere", (0.07,), None), I7)]
    robots = {"left": SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp", base=I7)}
    return GeometryContext(Scene("t", 3, robots, {o.name: o for o in objs}))


def _matrix_path(A, pa, B, pb) -> float:
    Ta, Tb = se3_to_matrix(pa), se3_to_matrix(pb)
    return D.signed_distance(A, Ta[:3, :3], Ta[:3, 3], B, Tb[:3, :3], Tb[:3, 3])


def test_signed_distance_at_equals_the_matrix_path():
    ctx = _ctx()
    links = list(ctx.robot("left").links)
    bodies = [ctx.body(("link", "left", k)) for k in links] + [ctx.body(n) for n in ("box", "cyl", "ball")]
    # a shape placed in its body (a turned, shifted cylinder), and a body of two shapes
    M = se3_to_matrix(np.r_[0.1, -0.05, 0.2, 0.2, -0.3, 0.1, 0.9])
    bodies.append(D.ConvexBody("placed", [ctx.body("cyl").shapes[0]], [M]))
    bodies.append(D.ConvexBody("pair", [ctx.body("box").shapes[0], ctx.body("ball").shapes[0]], [np.eye(4), M]))
    assert any(not all(b.identity()) for b in bodies)
    rng = np.random.default_rng(3)
    worst, n_pen = 0.0, 0
    for i in range(300):
        A, B = bodies[i % len(bodies)], bodies[(7 * i + 3) % len(bodies)]
        pa = np.r_[rng.normal(size=3) * 0.2, rng.normal(size=4) * 3]      # quaternions unnormalised
        pb = np.r_[rng.normal(size=3) * 0.2, rng.normal(size=4) * 3]
        d, ref = D.signed_distance_at(A, pa, B, pb), _matrix_path(A, pa, B, pb)
        worst = max(worst, abs(d - ref))
        n_pen += ref < 0
        assert isinstance(d, float)
    assert worst <= 1e-12 and n_pen > 10
    # the context's numeric query is this path
    pa, pb = np.r_[0.0, 0, 0.3, 0, 0, 0, 1], np.r_[0.05, 0, 0.1, 0, 0, 0.3, 0.95]
    assert ctx.sdist_numeric(("link", "left", links[3]), pa, "box", pb) == \
        D.signed_distance_at(ctx.body(("link", "left", links[3])), pa, ctx.body("box"), pb)


def test_placed_transforms_are_remembered_per_body_and_pose():
    """A pose asked again for the same body reuses its coal transform (`_placed_at`); another
    body at the same pose, or the same body at another pose, gets its own."""
    ctx = _ctx()
    box, ball = ctx.body("box"), ctx.body("ball")
    M = se3_to_matrix(np.r_[0.1, -0.05, 0.2, 0.2, -0.3, 0.1, 0.9])
    placed = D.ConvexBody("placed", [ctx.body("cyl").shapes[0]], [M])
    pa = np.r_[0.3, 0.1, 0.2, 0.1, 0.2, 0.3, 0.9]
    T1 = D._placed_at(box, pa)
    assert D._placed_at(box, pa.copy()) is T1
    assert D._placed_at(ball, pa) is not T1
    assert D._placed_at(box, pa + 1e-9) is not T1
    T2 = D._placed_at(placed, pa)
    R, p = se3_to_matrix(pa)[:3, :3], se3_to_matrix(pa)[:3, 3]
    np.testing.assert_allclose(np.asarray(T2.getRotation()), R @ M[:3, :3], atol=1e-15)
    np.testing.assert_allclose(np.asarray(T2.getTranslation()), R @ M[:3, 3] + p, atol=1e-15)
    d = D.signed_distance_at(box, pa, placed, np.r_[0.0, 0, 0, 0, 0, 0, 1])
    assert d == D.signed_distance_at(box, pa, placed, np.r_[0.0, 0, 0, 0, 0, 0, 1])     # from the memo
    assert abs(d - _matrix_path(box, pa, placed, np.r_[0.0, 0, 0, 0, 0, 0, 1])) <= 1e-12
