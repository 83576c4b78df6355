"""Verification primitives (pinocchio + coal on numbers) against closed forms and the casadi path."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from gnppdsl.geometry import verify
from gnppdsl.geometry.context import GeometryContext
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape


@pytest.fixture(scope="module")
def ctx():
    objs = [SceneObject("table", SceneShape("box", (1.2, 0.8, 0.05)), (0.4, 0, -0.025, 0, 0, 0, 1), static=True),
            SceneObject("b1", SceneShape("box", (0.05, 0.05, 0.05)), (0.5, 0.1, 0.025, 0, 0, 0, 1)),
            SceneObject("b2", SceneShape("box", (0.05, 0.05, 0.05)), (0.5, -0.1, 0.025, 0, 0, 0, 1))]
    robots = {"left": SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp"),
              "right": SceneRobot("right", "urdf", model="panda", ee="panda_hand_tcp",
                                  base=(1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0))}
    # no ignore_collisions for the arms' link0 on the table: links no joint moves count as static
    scene = Scene("lab", 3, robots, {o.name: o for o in objs})
    return GeometryContext(scene)


def test_scene_state_is_collision_free(ctx):
    rep = verify.check_state(ctx, {}, margin=0.0, ignore=[("b1", "table"), ("b2", "table")])
    print("\n" + str(rep))
    assert rep.ok, str(rep)
    names = {(p.a, p.b) for p in rep.distances}
    assert ("b1", "b2") in names and not any("table" in n and "link0" in m for n, m in names)


def test_block_distances_closed_form(ctx):
    d = {(p.a, p.b): p.distance for p in verify.pair_distances(ctx, {"b2": (0.58, 0.1, 0.025, 0, 0, 0, 1)})}
    assert abs(d[("b1", "b2")] - (0.08 - 0.05)) < 1e-9
    # penetrating by 1 cm -> reported as a collision with its name
    cols = verify.collisions(ctx, {"b2": (0.54, 0.1, 0.025, 0, 0, 0, 1)}, margin=0.0,
                             ignore=[("b1", "table"), ("b2", "table")])
    assert [(c.a, c.b) for c in cols] == [("b1", "b2")] and abs(cols[0].distance + 0.01) < 1e-9
    # a margin turns a 3 cm gap into a violation
    assert verify.collisions(ctx, {"b2": (0.58, 0.1, 0.025, 0, 0, 0, 1)}, margin=0.05,
                             ignore=[("b1", "table"), ("b2", "table")])


def test_link_distances_agree_with_casadi_path(ctx):
    """Same shapes, different kinematics: pinocchio FK here, casadi FK + callback in the NLP."""
    robot = ctx.robot("left")
    q = ca.SX.sym("q", robot.nc)
    base = ctx.base("left")
    rng = np.random.default_rng(2)
    fns = {ln: ca.Function("f", [q], [ctx.sdist(("link", "left", ln), ctx.fk("left", q, ln, base), "b1",
                                                np.r_[0.5, 0.1, 0.025, 0, 0, 0, 1])]) for ln in ctx.links("left")}
    for _ in range(10):
        qv = robot.random_coords(rng)
        ref = {(p.a, p.b): p.distance for p in verify.pair_distances(ctx, {"left": qv})}
        for ln, f in fns.items():
            assert abs(float(f(qv)) - ref[("b1", f"left/{ln}")]) < 1e-9


def test_joint_limits(ctx):
    r = ctx.robot("left")
    q = r.home_coords()
    assert verify.joint_limit_violations(ctx, "left", q) == []
    q2 = q.copy()
    q2[3] = 0.5            # panda_joint4 upper limit is -0.0698
    v = verify.joint_limit_violations(ctx, "left", q2)
    assert len(v) == 1 and v[0].joint == "panda_joint4" and abs(v[0].amount - (0.5 + 0.0698)) < 1e-9
    rep = verify.check_state(ctx, {"left": q2}, ignore=[("b1", "table"), ("b2", "table")])
    assert rep.limits and not rep.ok


def test_point_in_gripper(ctx):
    import pinocchio as pin
    r = ctx.robot("right")
    q = r.home_coords()
    data = r.model.createData()
    pin.framesForwardKinematics(r.model, data, q)
    T = r.base @ np.array(data.oMf[r.model.getFrameId("panda_hand_tcp")].homogeneous)
    inside = verify.point_in_gripper(ctx, "right", q, T[:3, 3] + T[:3, :3] @ [0.0, 0.03, 0.01])
    assert inside.inside and np.allclose(inside.local, [0.0, 0.03, 0.01], atol=1e-12)
    outside = verify.point_in_gripper(ctx, "right", q, T[:3, 3] + T[:3, :3] @ [0.0, 0.06, 0.0])
    assert not outside.inside


def test_resting_on(ctx):
    ok = verify.resting_on(ctx, "b1", (0.5, 0.1, 0.025, 0, 0, 0, 1), "table")
    assert ok.ok and abs(ok.gap) < 1e-12 and ok.inside
    lifted = verify.resting_on(ctx, "b1", (0.5, 0.1, 0.035, 0, 0, 0, 1), "table")
    assert not lifted.ok and abs(lifted.gap - 0.01) < 1e-12
    off = verify.resting_on(ctx, "b1", (1.1, 0.1, 0.025, 0, 0, 0, 1), "table")    # table ends at x = 1.0
    assert not off.ok and not off.inside
    stacked = verify.resting_on(ctx, "b1", (0.5, -0.1, 0.075, 0, 0, 0, 1), "b2")
    assert stacked.ok


def test_planar_scene():
    objs = [SceneObject("left", SceneShape("box", (0.4, 0.4)), (0,) * 6 + (1,), pose2=(-0.5, 0, 0), static=True),
            SceneObject("c1", SceneShape("circle", (0.05,)), (0,) * 6 + (1,), pose2=(-0.5, 0.1, 0)),
            SceneObject("c2", SceneShape("circle", (0.05,)), (0,) * 6 + (1,), pose2=(0.3, 0.0, 0))]
    robots = {"g": SceneRobot("g", "planar", shape=SceneShape("circle", (0.04,)), home=(0.0, 0.5, 0.0))}
    g = GeometryContext(Scene("p", 2, robots, {o.name: o for o in objs}))
    assert verify.resting_on(g, "c1", (-0.5, 0.1, 0), "left").ok
    assert not verify.resting_on(g, "c2", (0.3, 0.0, 0), "left").ok
    d = {(p.a, p.b): p.distance for p in verify.pair_distances(g, {"g": (0.3, 0.2, 0)})}
    assert abs(d[("c2", "g")] - (0.2 - 0.09)) < 1e-6
    assert verify.point_in_gripper(g, "g", (0.3, 0.01, 0.0), (0.3, 0.0), half_extents=(0.02, 0.02)).inside


def test_trajectory_check_finds_the_colliding_waypoint(ctx):
    """b2 slides along x through b1 (at x = 0.5, y = 0.1): waypoints within 5 cm of it collide."""
    xs = np.linspace(0.2, 0.8, 13)
    states = [{"b2": (x, 0.1, 0.025, 0, 0, 0, 1)} for x in xs]
    reps = verify.check_states(ctx, states, margin=0.0, ignore=[("b1", "table"), ("b2", "table")])
    colliding = [i for i, r in enumerate(reps) if not r.ok]
    assert colliding == [i for i, x in enumerate(xs) if abs(x - 0.5) < 0.05 - 1e-9]
    i, r = verify.first_violation(reps)
    assert i == colliding[0] and ("b1", "b2") == (r.collisions[0].a, r.collisions[0].b)


def test_resting_on_a_tilted_support_is_measured_in_its_frame():
    """A block stacked exactly on a slightly tilted block rests on it (the world-frame highest
    vertex of the tilted support is not its top face); lifted 5 mm it does not."""
    from gnppdsl.geometry.context import GeometryContext
    from gnppdsl.geometry.verify import resting_on
    from gnppdsl.ir.scene import load_scene_file as load_scene
    from pathlib import Path
    import numpy as _np

    scene = load_scene(Path(__file__).resolve().parents[2] / "examples" / "lab" / "lab.yaml")
    ctx = GeometryContext(scene)
    a = 0.014                                       # 0.8 deg about x
    q = [_np.sin(a / 2), 0.0, 0.0, _np.cos(a / 2)]
    Ts = _np.eye(4)
    Ts[:3, :3] = [[1, 0, 0], [0, _np.cos(a), -_np.sin(a)], [0, _np.sin(a), _np.cos(a)]]
    Ts[:3, 3] = [0.0, 0.2, 0.645]
    up = Ts[:3, :3] @ [0, 0, 0.09]                  # one block height along the support's z
    support = [0.0, 0.2, 0.645, *q]
    on_top = [*(Ts[:3, 3] + up), *q]
    chk = resting_on(ctx, "b2", on_top, "b1", support)
    assert chk.ok and abs(chk.gap) < 1e-9 and chk.inside
    lifted = [*(Ts[:3, 3] + up + Ts[:3, :3] @ [0, 0, 0.005]), *q]
    chk = resting_on(ctx, "b2", lifted, "b1", support)
    assert not chk.ok and abs(chk.gap - 0.005) < 1e-9


def test_broadphase_keeps_every_pair_within_the_cutoff(ctx):
    """The broadphase (bounding spheres and turned local boxes) and the memos of
    `pair_distances` must not drop or change a pair: at random arm configurations and block
    poses (random orientations, in the arms' reach), the pairs it returns with a cutoff are
    exactly the pairs a fresh context (no memo) measures at most that far, same distances."""
    fresh = GeometryContext(ctx.scene, ctx.models)
    rng = np.random.default_rng(7)
    within = dropped = 0
    for _ in range(12):
        state = {r: ctx.robot(r).random_coords(rng) for r in ("left", "right")}
        for b in ("b1", "b2"):
            quat = rng.normal(size=4)
            state[b] = np.r_[rng.uniform(0.2, 0.8), rng.uniform(-0.4, 0.4), rng.uniform(0.0, 0.8), quat / np.linalg.norm(quat)]
        fresh.forget_evaluations()
        full = {(p.a, p.b): p.distance for p in verify.pair_distances(fresh, state)}
        for cutoff in (0.0, 0.05, 0.15):
            fast = {(p.a, p.b): p.distance for p in verify.pair_distances(ctx, state, cutoff=cutoff)}
            expected = {k: d for k, d in full.items() if d <= cutoff}
            assert expected.items() <= fast.items(), set(expected) - set(fast)
            assert all(full[k] == d for k, d in fast.items())
            within += len(expected)
            dropped += len(full) - len(fast)
    assert within > 50 and dropped > 1000          # not vacuous: near pairs kept, far ones skipped
