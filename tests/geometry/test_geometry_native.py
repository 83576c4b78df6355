"""The native distance twin (`geometry/native_witness.cpp`) answers as the Python callback does.

The Python `WitnessCallback` is the reference: the C++ twin must give the same local contact
model (mode, sign, witness points in the body frames, feature directions, radii, normal) on
random poses over every shape kind it handles, planar and 3-D, with generic and axis-aligned
(parallel face) contacts, penetration, shape placements off the body origin and the Panda's
link hulls. Curved shapes (cylinders against hulls) fall back to coal's normal, where two GJK
runs on differently ordered hull vertices agree only to GJK's tolerance: there the *distance
value* of the model is compared instead of the raw numbers.

The library is built here when it is missing (about 6 s) and a compiler and coal's headers
exist; without them the test is skipped (the solver then uses the Python callback).
"""
from __future__ import annotations


import casadi as ca
import numpy as np
import pytest

from gnppdsl.geometry import native
from gnppdsl.geometry.context import GeometryContext
from gnppdsl.geometry.distance import ConvexBody, WitnessCallback
from gnppdsl.geometry.features import model_expression
from geometry_poses import pair_inputs, rotation  # noqa: E402
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

I7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


@pytest.fixture(scope="module")
def lib(native_library):
    return native_library


def _obj(name, kind, size):
    return SceneObject(name, SceneShape(kind, size, None), I7)


@pytest.fixture(scope="module")
def ctx():
    objs = [_obj("box", "box", (0.06, 0.15, 0.09)), _obj("cyl", "cylinder", (0.05, 0.3)),
            _obj("ball", "sphere", (0.07,)), _obj("slab", "box", (0.4, 0.3, 0.05)),
            _obj("disc", "circle", (0.1,))]
    robots = {"left": SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp", base=I7)}
    return GeometryContext(Scene("t", 3, robots, {o.name: o for o in objs}))


_MODEL = None


def _distance(o: np.ndarray, x: np.ndarray) -> float:
    """The model's value (what ipopt sees) for callback output o at input x."""
    global _MODEL
    if _MODEL is None:
        RA, RB = ca.SX.sym("RA", 3, 3), ca.SX.sym("RB", 3, 3)
        pA, pB, oo = ca.SX.sym("pA", 3), ca.SX.sym("pB", 3), ca.SX.sym("o", 24)
        _MODEL = ca.Function("m", [RA, pA, RB, pB, oo], [model_expression(oo, RA, pA, RB, pB)])
    RA, pA = x[0:9].reshape(3, 3, order="F"), x[9:12]
    RB, pB = x[12:21].reshape(3, 3, order="F"), x[21:24]
    return float(_MODEL(RA, pA, RB, pB, o))


def _aligned(x: np.ndarray) -> bool:
    return bool(np.array_equal(x[0:9], np.eye(3).reshape(-1)) and np.array_equal(x[12:21], np.eye(3).reshape(-1)))


def _compare(lib, a: ConvexBody, b: ConvexBody, xs, planar: bool = False, curved: bool = False,
             exact: bool = False) -> dict:
    """Native vs Python on every input; `exact`: all 24 numbers within 1e-9 even for parallel
    faces (shapes built identically on both sides: boxes, spheres, cylinders)."""
    name = "".join(c if c.isalnum() else "x" for c in f"t_{a.name}_{b.name}_{int(planar)}")
    cb = WitnessCallback(name, a, b, planar=planar)
    fn = lib.function(cb.name(), a, b, planar)
    assert fn is not None
    pid = lib._pairs[(id(a), id(b), planar)][0]
    modes: dict[int, int] = {}
    for x in xs:
        ref = cb._model_general(x)                       # the Python reference (no memo)
        got = lib.model(pid, x)
        via = np.array(fn(x)).ravel()                    # through casadi, with the memo
        assert via.tobytes() == got.tobytes()
        mode = int(np.argmax(ref[:4]))
        modes[mode] = modes.get(mode, 0) + 1
        if curved and mode == 3:
            assert int(np.argmax(got[:4])) == 3
            assert abs(_distance(got, x) - _distance(ref, x)) < 1e-7
        elif exact or not _aligned(x):
            np.testing.assert_allclose(got, ref, rtol=0, atol=1e-9)
        else:
            # parallel faces: any point of the overlap is a witness, and GJK on a hull whose
            # vertices come in another order picks another one; the distance is the same
            assert abs(_distance(got, x) - _distance(ref, x)) < 1e-9
    return modes


def test_boxes_spheres_and_placements_agree_with_the_python_callback(lib, ctx):
    rng = np.random.default_rng(0)
    box, slab, ball = ctx.body("box"), ctx.body("slab"), ctx.body("ball")
    seen: dict[int, int] = {}
    for a, b in ((box, slab), (slab, box), (box, ball), (ball, box), (box, box)):
        for mode, k in _compare(lib, a, b, pair_inputs(rng, 150, 0.25, aligned_every=3), exact=True).items():
            seen[mode] = seen.get(mode, 0) + k
    M = np.eye(4)
    M[:3, :3] = rotation(np.array([0.2, -0.1, 0.3, 0.9]) / np.linalg.norm([0.2, -0.1, 0.3, 0.9]))
    M[:3, 3] = (0.05, -0.02, 0.03)
    off_a = ConvexBody("box_off", list(box.shapes), [M])
    off_b = ConvexBody("ball_off", list(ball.shapes), [np.linalg.inv(M)])
    _compare(lib, off_a, off_b, pair_inputs(rng, 150, 0.2, aligned_every=3), exact=True)
    # face-vertex / edge-edge, edge-vertex and vertex-vertex (sphere) models all occur
    assert {0, 1, 2} <= set(seen), seen


def test_panda_link_hulls_agree_with_the_python_callback(lib, ctx):
    rng = np.random.default_rng(1)
    for link in ("panda_hand", "panda_link5", "panda_leftfinger"):
        hull = ctx.body(("link", "left", link))
        for other in (ctx.body("box"), ctx.body("slab"), ctx.body("ball")):
            _compare(lib, hull, other, pair_inputs(rng, 80, 0.2, aligned_every=3))
        _compare(lib, ctx.body("cyl"), hull, pair_inputs(rng, 60, 0.2, aligned_every=3), curved=True)


def test_planar_bodies_agree_with_the_python_callback(lib, ctx):
    rng = np.random.default_rng(2)
    pairs = (("box", "slab"), ("disc", "box"), ("cyl", "disc"), ("box", "cyl"))
    for a, b in pairs:
        _compare(lib, ctx.body(a, True), ctx.body(b, True), pair_inputs(rng, 120, 0.3, planar=True), planar=True)


def test_the_native_model_is_coal_distance(lib, ctx):
    """The model's value at the native answer is coal's distance (a direct coal query)."""
    import coal
    box, slab = ctx.body("box"), ctx.body("slab")
    fn = lib.function("t_grad", box, slab, False)
    req = coal.DistanceRequest()
    req.enable_signed_distance = True
    for xv in pair_inputs(np.random.default_rng(3), 40, 0.25, aligned_every=3):
        o = np.array(fn(xv)).ravel()
        Ta = coal.Transform3s(xv[0:9].reshape(3, 3, order="F"), xv[9:12])
        Tb = coal.Transform3s(xv[12:21].reshape(3, 3, order="F"), xv[21:24])
        d = coal.distance(box.shapes[0], Ta, slab.shapes[0], Tb, req, coal.DistanceResult())
        assert abs(_distance(o, xv) - d) < 1e-6


def test_the_context_hands_out_the_native_twin_for_single_shape_pairs(lib, ctx):
    """witness_fast gives the native Function (one per pair) and the distance through it and
    sdist_parts' model equals the numeric distance (pinocchio + coal, no casadi)."""
    _, to_rp, model = ctx.sdist_parts(("link", "left", "panda_hand"), "box")
    cbf = ctx.witness_fast(("link", "left", "panda_hand"), "box")
    assert "native" in cbf.name()
    assert ctx.witness_fast(("link", "left", "panda_hand"), "box") is cbf
    rng = np.random.default_rng(4)
    q = rng.uniform(-1, 1, 7)
    T = ctx.fk_matrix("left", q, "panda_hand")
    pose = np.r_[0.3, 0.1, 0.5, 0, 0, 0, 1.0]
    R, p = to_rp(pose)
    xv = np.concatenate([T[:3, :3].reshape(-1, order="F"), T[:3, 3], np.array(R).reshape(-1, order="F"),
                         np.array(p).ravel()])
    o = np.array(cbf(xv)).ravel()
    d = float(model(T[:3, :3], T[:3, 3], R, p, o))
    ref = ctx.sdist_numeric(("link", "left", "panda_hand"), ctx.fk_numeric("left", q, "panda_hand", ctx.base("left")),
                            "box", pose)
    assert abs(d - ref) < 1e-7


def test_the_memo_answers_repeated_points_until_forget(lib, ctx):
    """ipopt evaluates g, the Jacobian and the Hessian at one point: the repeats are memo
    hits (no coal query) with the same bytes; after `forget` every point is queried again."""
    fn = lib.function("t_memo", ctx.body("box"), ctx.body("ball"), False)
    xs = pair_inputs(np.random.default_rng(5), 3, 0.2, aligned_every=3)      # fewer points than the memo holds
    n0 = lib.queries()
    first = [np.array(fn(x)).ravel().tobytes() for x in xs]
    assert lib.queries() - n0 == 3
    assert [np.array(fn(x)).ravel().tobytes() for x in xs] == first
    assert lib.queries() - n0 == 3
    lib.forget()
    assert [np.array(fn(x)).ravel().tobytes() for x in xs] == first
    assert lib.queries() - n0 == 6


def test_a_missing_library_is_not_remembered_by_a_look_without_build(tmp_path, monkeypatch):
    """`describe()` (benchmark headers) looks without building; a later load that may build
    must still see the library missing and start the build, not a remembered None."""
    if native.library_path() is None:
        pytest.skip("no C++ compiler or no coal headers")
    monkeypatch.setenv("GNPP_NATIVE_CACHE", str(tmp_path))
    monkeypatch.setattr(native, "_LOADED", {})
    started = []
    monkeypatch.setattr(native, "_start_background_build", lambda: started.append(1))
    assert native.load(start_build=False) is None and "lib" not in native._LOADED
    assert native.describe() == "python (native library not built)"
    assert native.load() is None and started == [1]
