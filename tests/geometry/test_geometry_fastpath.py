"""The distance callback's fast paths give bitwise the same outputs as the general path.

Why bitwise: the callback output is the local contact model that ipopt differentiates; a change
in the last bit changes the iterates, and the fast paths exist only to be cheaper. Checked over
random poses (generic vertex/edge/face contacts), axis-aligned stacks (parallel faces), planar
bodies, curved shapes (the fallback model), penetration and non-identity shape placements.
"""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.geometry.context import GeometryContext
from gnppdsl.geometry.distance import ConvexBody, WitnessCallback
from geometry_poses import pair_inputs, rotation  # noqa: E402
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

I7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


def _obj(name, kind, size):
    return SceneObject(name, SceneShape(kind, size, None), I7)


@pytest.fixture(scope="module")
def ctx():
    objs = [_obj("box", "box", (0.3, 0.2, 0.1)), _obj("cyl", "cylinder", (0.05, 0.3)),
            _obj("ball", "sphere", (0.07,)), _obj("box2", "box", (0.1, 0.4, 0.2)), _obj("disc", "circle", (0.1,))]
    robots = {"left": SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp", base=I7)}
    return GeometryContext(Scene("t", 3, robots, {o.name: o for o in objs}))


def _check(cb: WitnessCallback, xs: list[np.ndarray]) -> dict[int, int]:
    """Fast path == general path bitwise on every input; returns the count per model mode."""
    assert cb._single is not None
    modes: dict[int, int] = {}
    for x in xs:
        fast = cb._model_single(x)
        slow = cb._model_general(x)
        if fast is None:        # degenerate query: the general path answers it
            continue
        assert fast.dtype == slow.dtype and fast.shape == slow.shape
        assert fast.tobytes() == slow.tobytes(), (x.tolist(), fast.tolist(), slow.tolist())
        m = int(np.argmax(slow[:4]))
        modes[m] = modes.get(m, 0) + 1
    return modes


@pytest.mark.parametrize("a,b", [("box", "box2"), ("box", "ball"), ("box", "cyl"), ("cyl", "ball"),
                                 (("link", "left", "panda_hand"), "box"),
                                 (("link", "left", "panda_link5"), ("link", "left", "panda_link7")),
                                 (("link", "left", "panda_leftfinger"), "box2")])
def test_single_shape_path_equals_general_path(ctx, a, b):
    rng = np.random.default_rng(7)
    cb = ctx._callback(a, b, False)
    modes = _check(cb, pair_inputs(rng, 150, 0.25) + pair_inputs(rng, 150, 0.12))
    assert sum(modes.values()) >= 250
    if "cyl" not in (a, b):
        assert set(modes) & {0, 1, 2}, modes     # the feature model itself is exercised


def test_single_shape_path_parallel_faces(ctx):
    rng = np.random.default_rng(3)
    modes = _check(ctx._callback("box", "box2", False), pair_inputs(rng, 300, 0.3, aligned_every=1))
    assert sum(modes.values()) > 200


@pytest.mark.parametrize("a,b", [("box", "box2"), ("box", "disc"), ("disc", "box2")])
def test_single_shape_path_planar(ctx, a, b):
    rng = np.random.default_rng(11)
    modes = _check(ctx._callback(a, b, True), pair_inputs(rng, 200, 0.3, planar=True))
    assert set(modes) & {1, 2}, modes


def test_single_shape_path_with_placements(ctx):
    """Shapes placed off the body origin (the general path composes the placement)."""
    rng = np.random.default_rng(5)
    box, ball = ctx.body("box"), ctx.body("ball")
    M = np.eye(4)
    M[:3, :3] = rotation(np.array([0.2, -0.1, 0.3, 0.9]) / np.linalg.norm([0.2, -0.1, 0.3, 0.9]))
    M[:3, 3] = (0.05, -0.02, 0.03)
    a = ConvexBody("box_off", list(box.shapes), [M])
    b = ConvexBody("ball_off", list(ball.shapes), [np.linalg.inv(M)])
    cb = WitnessCallback("t_off", a, b)
    modes = _check(cb, pair_inputs(rng, 200, 0.2))
    assert set(modes) & {0, 1, 2}, modes


def test_callback_uses_the_fast_path_and_agrees_with_coal(ctx):
    """The callback (through casadi) answers via the fast path, with coal's distance."""
    import casadi as ca
    cb = ctx._callback(("link", "left", "panda_hand"), "box", False)
    rng = np.random.default_rng(2)
    xs = pair_inputs(rng, 20, 0.2)
    calls = cb.calls
    for x in xs:
        o = np.array(cb(ca.DM(x))).ravel()
        assert o.tobytes() == cb._model_general(x).tobytes()
    assert cb.calls > calls


def test_memo_answers_repeated_points_with_the_same_bytes(ctx):
    """ipopt evaluates g, the Jacobian and the Hessian at one x: the second and later calls
    are memo hits with bitwise the same output, inside an SX graph as in the NLP."""
    import casadi as ca
    cb = WitnessCallback("t_memo", ctx.body("box"), ctx.body("box2"))
    xs = ca.SX.sym("x", 24)
    f = ca.Function("f", [xs], [cb(xs)])
    X = pair_inputs(np.random.default_rng(4), 30, 0.25)
    first = [np.array(f(x)).ravel() for x in X]
    assert (cb.calls, cb.hits) == (30, 0)
    again = [np.array(f(x)).ravel() for x in X]
    assert (cb.calls, cb.hits) == (30, 30)
    for x, a, b in zip(X, first, again):
        assert a.tobytes() == b.tobytes() == cb._model_general(x).tobytes()
        assert cb.model(x).tobytes() == a.tobytes()


def test_fk_matrix_memo_equals_fresh_pinocchio(ctx):
    """The numeric FK memo (exact input bytes) and its reused pinocchio Data give bitwise the
    values of a fresh Data, and callers cannot corrupt the memo through the returned array."""
    import pinocchio as pin
    from gnppdsl.geometry.robots import se3_to_matrix
    r = ctx.robot("left")
    rng = np.random.default_rng(9)
    base = np.array([0.1, -0.2, 0.05, 0.0, 0.0, 0.3826834323650898, 0.9238795325112867])
    qs = [rng.uniform(r.lower, r.upper) for _ in range(20)]
    for _round in range(2):                   # second round: all memo hits
        for q in qs:
            for frame, b in (("panda_hand", None), ("panda_link4", base)):
                T = ctx.fk_matrix("left", q, frame, b)
                data = r.model.createData()
                pin.framesForwardKinematics(r.model, data, r.to_pin_q(q))
                ref = (r.base if b is None else se3_to_matrix(b)) @ np.array(data.oMf[r.frame_id(frame)].homogeneous)
                assert T.tobytes() == ref.tobytes()
                T[:] = 0.0                    # must not reach the memo


def test_fk_matrix_one_kinematics_run_per_q(ctx, monkeypatch):
    """The frames of one q (a waypoint's collision links, asked in turn by the checker) are read
    after one forward-kinematics run, not one per frame, with bitwise the values of a fresh
    Data; `link_placements` (verification) moving the shared Data in between changes nothing."""
    import pinocchio as pin
    from gnppdsl.geometry.verify import link_placements
    r = ctx.robot("left")
    rng = np.random.default_rng(11)
    qs = [rng.uniform(r.lower, r.upper) for _ in range(6)]
    frames = ["panda_link2", "panda_link4", "panda_link7", "panda_hand"]
    ctx.forget_evaluations()
    runs = []
    real = pin.framesForwardKinematics
    monkeypatch.setattr(pin, "framesForwardKinematics", lambda *a: (runs.append(1), real(*a))[1])
    for q in qs:
        for frame in frames:
            T = ctx.fk_matrix("left", q, frame)
            link_placements(ctx, "left", qs[0] + 0.1)          # moves the verifier's Data
            data = r.model.createData()
            real(r.model, data, r.to_pin_q(q))
            ref = r.base @ np.array(data.oMf[r.frame_id(frame)].homogeneous)
            assert T.tobytes() == ref.tobytes()
    assert len(runs) == len(qs) + 1           # one per q, and one of link_placements (memoised)
