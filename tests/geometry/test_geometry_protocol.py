"""GeometryContext satisfies the nlp layer's geometry protocol (structurally: geometry does not
import nlp) and accepts its Body objects."""
from __future__ import annotations

import casadi as ca
import numpy as np

from gnppdsl.geometry.context import GeometryContext
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape


def test_protocol_conformance_and_bodies():
    from gnppdsl.nlp.geometry_protocol import Body, Geometry
    objs = {"b": SceneObject("b", SceneShape("box", (0.1, 0.1, 0.1)), (0.5, 0.0, 0.3, 0, 0, 0, 1))}
    robots = {"arm": SceneRobot("arm", "urdf", model="panda", ee="panda_hand_tcp")}
    g = GeometryContext(Scene("s", 3, robots, objs))
    assert isinstance(g, Geometry)
    assert not g.needs_mx("sdist") and not g.needs_mx("fk")
    q = ca.SX.sym("q", 7)
    base = ca.DM(g.base("arm"))
    pose = g.fk("arm", q, "panda_hand", base)
    assert pose.shape == (7, 1)
    d = g.sdist(Body("arm", link="panda_hand"), pose, Body("b"), ca.DM(objs["b"].pose))
    assert d.shape == (1, 1)
    f = ca.Function("f", [q], [d])
    qv = g.robot("arm").home_coords()
    num = g.sdist_numeric(Body("arm", link="panda_hand"), g.fk_numeric("arm", qv, "panda_hand", g.base("arm")),
                          Body("b"), np.array(objs["b"].pose))
    assert abs(float(f(qv)) - num) < 1e-9
    n, lo, hi = g.robot_dims("arm")
    assert n == 7 and lo.shape == hi.shape == (7,)
    assert "panda_hand" in g.links("arm") and ("panda_link0", "panda_link5") in g.self_collision_pairs("arm")


def test_forget_evaluations_empties_the_memos_and_keeps_the_answers():
    """A solve starts with `forget_evaluations` (gnppdsl.solve.loop): the distance callbacks and
    the numeric forward kinematics answer again from coal and pinocchio, with the same values."""
    objs = {"b": SceneObject("b", SceneShape("box", (0.1, 0.1, 0.1)), (0.5, 0.0, 0.3, 0, 0, 0, 1))}
    robots = {"arm": SceneRobot("arm", "urdf", model="panda", ee="panda_hand_tcp")}
    g = GeometryContext(Scene("s", 3, robots, objs))
    from gnppdsl.nlp.geometry_protocol import Body

    q = ca.SX.sym("q", 7)
    pose = g.fk("arm", q, "panda_hand", ca.DM(g.base("arm")))
    f = ca.Function("f", [q], [g.sdist(Body("arm", link="panda_hand"), pose, Body("b"), ca.DM(objs["b"].pose))])
    qv = g.robot("arm").home_coords()
    d1 = float(f(qv))
    T1 = g.fk_matrix("arm", qv, "panda_hand")
    (cb,) = g._callbacks.values()
    assert len(cb._memo) == 1 and len(g._fk_memo) == 1
    calls = cb.calls
    assert float(f(qv)) == d1 and cb.calls == calls            # answered from the memo
    g.forget_evaluations()
    assert len(cb._memo) == 0 and len(g._fk_memo) == 0
    assert float(f(qv)) == d1 and cb.calls == calls + 1        # coal queried again, same value
    assert np.array_equal(g.fk_matrix("arm", qv, "panda_hand"), T1)
