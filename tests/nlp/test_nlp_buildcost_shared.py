"""Fewer Functions to build: bodies that differ only in the names of same-shaped objects or
same-model robots share one compiled Function (`GeometryContext.structure_key`), and a robot
base pose repeated in a body is lifted once so equal `fk(...)` chains are built once. Every
shared Function is checked against the independent numpy evaluator (pinocchio + coal) on each
instance it serves."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.compile.factors import VarInstance
from gnppdsl.geometry.context import GeometryContext
from gnppdsl.ir.expr import Call, Constraint, Num, Obj, Slot, Str, Vec
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.lowering import lift_constants
from gnppdsl.nlp.evaluate import constraint_rows

from nlp_toys import C, factor

BOX = SceneShape("box", (0.06, 0.15, 0.09))
Q0 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.7071068, 0.7071068)


@pytest.fixture(scope="module")
def geo():
    objs = {"b1": SceneObject("b1", BOX, (-0.2, 0.2, 0.645, 0, 0, 0, 1)),
            "b2": SceneObject("b2", BOX, (0.3, 0.1, 0.645, 0, 0, 0, 1)),
            "c": SceneObject("c", SceneShape("box", (0.1, 0.1, 0.1)), (0.0, 0.3, 0.65, 0, 0, 0, 1))}
    robots = {"left": SceneRobot("left", "urdf", model="panda", base=(-0.4, -0.3, 0.6, *Q0[3:]),
                                 ee="panda_hand_tcp", locked={"panda_finger_joint1": 0.04,
                                                              "panda_finger_joint2": 0.04}),
              "right": SceneRobot("right", "urdf", model="panda", base=(0.4, -0.3, 0.6, *Q0[3:]),
                                  ee="panda_hand_tcp", locked={"panda_finger_joint1": 0.04,
                                                               "panda_finger_joint2": 0.04}),
              "open": SceneRobot("open", "urdf", model="panda", base=(0.0, -0.6, 0.6, *Q0[3:]),
                                 ee="panda_hand_tcp", locked={"panda_finger_joint1": 0.01,
                                                              "panda_finger_joint2": 0.01})}
    return GeometryContext(Scene("s", 3, robots, objs))


def test_structure_keys(geo):
    assert geo.structure_key("b1") == geo.structure_key("b2") != geo.structure_key("c")
    assert geo.structure_key("left") == geo.structure_key("right")
    assert geo.structure_key("open") != geo.structure_key("left")     # other finger opening
    assert geo.structure_key("nothing") != geo.structure_key("b1")


def vec(xs):
    return Vec(tuple(Num(float(x)) for x in xs))


Q = lambda r: VarInstance("q", (r,), 0, "joints", 7)          # noqa: E731
POSE = lambda o: VarInstance("pose", (o,), 0, "SE3", 7)       # noqa: E731


def clear(geo, r, o, frames=("panda_link5", "panda_hand")):
    """panda.clear_object-like body: links of arm r keep off object o (o's pose a variable)."""
    base = vec(geo.scene.robots[r].base)
    body = [Constraint(C("sdist", C("link", Obj(r), Str(f)), C("fk", Obj(r), Slot(0), Str(f), base),
                         Obj(o), C("compose_se3", vec((0, 0, 0.575, 0, 0, 0, 1)), Slot(1))),
                       ">=", Num(0.01)) for f in frames]
    return factor("t.clear", [Q(r), POSE(o)], body, 0)


def test_same_shapes_and_models_share_one_function_with_exact_values(geo):
    comp = BodyCompiler(geo)
    fs = [clear(geo, r, o) for r in ("left", "right") for o in ("b1", "b2")]
    cbs = [comp.compile(f)[0] for f in fs]
    assert all(cb is cbs[0] for cb in cbs) and comp.compiled == 1
    other = comp.compile(clear(geo, "left", "c"))[0]
    assert other is not cbs[0] and comp.compiled == 2
    rng = np.random.default_rng(0)
    for f in fs + [clear(geo, "left", "c")]:
        cb, p = comp.compile(f)
        for _ in range(3):
            q = rng.uniform(-1.0, 1.0, 7)
            pose = np.r_[rng.uniform(-0.3, 0.3, 3), 0, 0, 0, 1]
            got = np.asarray(cb.function(q, pose, p)).ravel()
            ref = [h for _, h in constraint_rows(f, {Q(f.bindings[0][1]): q,
                                                     f.variables[1]: pose}, geo)]
            assert np.allclose(got, ref, atol=1e-9), (f.label, got, ref)


def test_repeated_robot_base_is_lifted_once_and_its_pattern_is_structural(geo):
    f = clear(geo, "left", "b1", frames=("panda_link5", "panda_hand", "panda_link5"))
    key, params = lift_constants(f.body)
    fk_bases = [c.lhs.args[1].args[3] for c in key]
    assert fk_bases[0] is fk_bases[1] is fk_bases[2]
    # 7 (base) + per constraint: 7 (table pose) + 1 (margin)
    assert len(params) == 7 + 3 * 8
    comp = BodyCompiler(geo)
    cb, p = comp.compile(f)
    # a body whose two bases differ (same structure otherwise) must not reuse that Function
    g = clear(geo, "left", "b1", frames=("panda_link5", "panda_hand", "panda_link5"))
    body = list(g.body)
    c2 = body[2]
    moved = Call("fk", (*c2.lhs.args[1].args[:3], vec((-0.4, -0.3, 0.61, *Q0[3:]))))
    body[2] = Constraint(Call("sdist", (c2.lhs.args[0], moved, *c2.lhs.args[2:])), c2.op, c2.rhs)
    g2 = factor("t.clear", g.variables, body, 0)
    cb2, p2 = comp.compile(g2)
    assert cb2 is not cb and p2.size == p.size + 7
    q, pose = np.full(7, 0.3), np.array([0.1, 0.2, 0.1, 0, 0, 0, 1])
    for ff, c, pp in ((f, cb, p), (g2, cb2, p2)):
        ref = [h for _, h in constraint_rows(ff, {Q("left"): q, POSE("b1"): pose}, geo)]
        assert np.allclose(np.asarray(c.function(q, pose, pp)).ravel(), ref, atol=1e-9)
    # the shared chain: one FK per (frame, joints) instead of one per constraint
    assert cb.function.n_instructions() < cb2.function.n_instructions()


@pytest.mark.parametrize("seed", [0, 1])
def test_stop_gradient_symbols_give_the_callback_derivatives(geo, seed):
    """Derivatives built with the distance callbacks' outputs as held-constant symbols
    (`GeometryContext.sdist_parts`) equal those of casadi differentiating the closed body
    through the callback call nodes (zero derivatives), near and far from contact."""
    import casadi as ca
    from gnppdsl.nlp.body_compiler import direct_hessian, direct_jacobian
    comp = BodyCompiler(geo)
    f = clear(geo, "left", "b1", frames=("panda_link5", "panda_link7", "panda_hand"))
    cb, p = comp.compile(f)
    assert cb.open_function is not None and cb.stops is not None
    q, x = ca.SX.sym("q", 7), ca.SX.sym("x", 7)
    lam = ca.SX.sym("lam", cb.n_rows)
    X = ca.vertcat(q, x)
    h = cb.function(q, x, p)
    ref_j = ca.Function("rj", [q, x], [ca.jacobian(h, X)])
    ref_h = ca.Function("rh", [q, x, lam], [ca.hessian(ca.dot(lam, h), X)[0]])
    jf, hf = direct_jacobian(cb), direct_hessian(cb)
    rng = np.random.default_rng(seed)
    for _ in range(4):
        qv = rng.uniform(-1.5, 1.5, 7)
        hand = geo.fk_numeric("left", qv, "panda_hand", np.asarray(geo.scene.robots["left"].base))
        xv = np.r_[hand[:3] + rng.normal(0, 0.05, 3) - [0, 0, 0.575], 0, 0, 0, 1]   # near the hand
        lv = rng.normal(0, 1, cb.n_rows)
        J0, J1 = np.asarray(ref_j(qv, xv).full()), np.asarray(jf(qv, xv, p).full())
        H0, H1 = np.asarray(ref_h(qv, xv, lv).full()), np.asarray(hf(qv, xv, p, lv).full())
        assert np.allclose(J0, J1, rtol=1e-10, atol=1e-10)
        assert np.allclose(H0, H1, rtol=1e-9, atol=1e-9)
        assert np.abs(H0).max() > 1e-3


def test_grouped_waypoint_derivatives_with_stop_gradients(geo):
    """A `forall k` Panda body over a trajectory: the grouped Jacobian/Hessian (one
    representative, stop-gradient symbols) equal casadi's through the closed body."""
    import casadi as ca
    path = VarInstance("path", ("left",), 0, "joints", 5 * 7, waypoints=5)
    base = vec(geo.scene.robots["left"].base)
    body = [Constraint(C("sdist", C("link", Obj("left"), Str(fr)),
                         C("fk", Obj("left"), C("waypoint", Slot(0), Num(k)), Str(fr), base),
                         Obj("b1"), C("compose_se3", vec((0, 0, 0.575, 0, 0, 0, 1)), Slot(1))),
                       ">=", Num(0.01)) for k in range(1, 4) for fr in ("panda_hand", "panda_link5")]
    comp = BodyCompiler(geo)
    cb, p = comp.compile(factor("t.path_clear", [path, POSE("b1")], body, 0))
    assert [(len(g.members), g.n_rows) for g in cb.groups] == [(3, 2)]   # one block per k
    jf, hf = comp.jacobian(cb), comp.hessian(cb)
    w, x = ca.SX.sym("w", 35), ca.SX.sym("x", 7)
    lam = ca.SX.sym("lam", cb.n_rows)
    X = ca.vertcat(w, x)
    h = cb.function(w, x, p)
    ref_j = ca.Function("rj", [w, x], [ca.jacobian(h, X)])
    ref_h = ca.Function("rh", [w, x, lam], [ca.hessian(ca.dot(lam, h), X)[0]])
    assert jf.sparsity_out(0) == ref_j.sparsity_out(0)
    rng = np.random.default_rng(5)
    wv = np.tile(rng.uniform(-1, 1, 7), 5) + rng.normal(0, 0.2, 35)
    xv = np.array([-0.2, 0.2, 0.07, 0, 0, 0, 1])
    lv = rng.normal(0, 1, cb.n_rows)
    assert np.allclose(np.asarray(jf(wv, xv, p).full()), np.asarray(ref_j(wv, xv).full()),
                       rtol=1e-10, atol=1e-10)
    H0 = np.asarray(ref_h(wv, xv, lv).full())
    assert np.allclose(np.asarray(hf(wv, xv, p, lv).full()), H0, rtol=1e-9, atol=1e-9)
    assert np.abs(H0).max() > 1e-3


def test_frame_chain_shares_joints_and_matches_pinocchio(geo):
    import casadi as ca
    q = ca.SX.sym("q", 7)
    base = np.asarray(geo.scene.robots["right"].base, float)
    chain = geo.fk_chain("right", q, ca.DM(base))
    frames = ("panda_link5", "panda_link7", "panda_hand", "panda_hand_tcp")
    f = ca.Function("f", [q], [ca.vertcat(*(ca.vertcat(ca.vec(R), p)
                                            for R, p in map(chain.frame, frames)))])
    alone = sum(ca.Function("g", [q], [ca.vertcat(*map(ca.vec, geo.fk_rp("right", q, fr, ca.DM(base))))])
                .n_instructions() for fr in frames)
    assert f.n_instructions() < 0.6 * alone            # the joint prefix is built once
    rng = np.random.default_rng(2)
    for _ in range(5):
        qv = rng.uniform(-2.0, 2.0, 7)
        out = np.asarray(f(qv)).reshape(len(frames), 12)
        for row, fr in zip(out, frames):
            T = geo.fk_matrix("right", qv, fr, base)
            assert np.allclose(row[:9].reshape(3, 3, order="F"), T[:3, :3], atol=1e-12)
            assert np.allclose(row[9:], T[:3, 3], atol=1e-12)


def test_box_feature_fast_path_equals_the_plane_product():
    """`shape_feature` on boxes tests the six planes in plain floats; it must classify every
    boundary point (faces, edges, corners, 3-D and planar) exactly as the numpy product over
    `_planes` that other polytopes use."""
    import coal
    from gnppdsl.geometry import features as FT
    box = coal.Box(0.06, 0.15, 0.09)
    h = np.array([0.03, 0.075, 0.045])
    rng = np.random.default_rng(4)
    pts = []
    for _ in range(300):
        p = rng.uniform(-1, 1, 3) * h
        fix = rng.random(3) < 0.5                       # snap 1-3 coordinates onto faces
        fix[rng.integers(3)] = True
        p[fix] = np.sign(rng.normal(size=3))[fix] * h[fix] * (1 + rng.normal(0, 1e-9, 3)[fix])
        pts.append(tuple(float(v) for v in p))
    for planar in (False, True):
        fast = [FT.shape_feature(box, p, planar) for p in pts]
        FT._KIND[id(box)] = (box, "other", 0.0, None)      # force the generic numpy path
        try:
            slow = [FT.shape_feature(box, p, planar) for p in pts]
        finally:
            FT._KIND.pop(id(box))
        assert fast == slow
        assert {f[0] for f in fast if f} >= ({"edge", "vertex"} if planar else {"face", "edge", "vertex"})
