"""Factory features of 3-D domains: fk frames, robot links in sdist, `with` along trajectories,
joints(r) dimensions from an injected `robot_dims`, scene attributes from the robot model."""
from __future__ import annotations

from gnppdsl.compile.factory import GraphNLPFactory
from gnppdsl.compile.semantics import plan_states
from gnppdsl.compile.task import build_task
from gnppdsl.ir import model as m
from gnppdsl.ir.builtins import SE3, Space
from gnppdsl.ir.expr import (Call, Constraint, CVar, Forall, Index, IterVar, Num, Obj, Param, Slot,
                             StateValue, Str, Vec, With)
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

P = Param
BASE = (0.1, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


def _problem():
    types = {"object": m.Type("object", None), "arm": m.Type("arm", "object"),
             "block": m.Type("block", "object"), "surface": m.Type("surface", "object")}
    tp = lambda n, *t: m.TypedParam(n, t)
    state_vars = {"parent": m.StateVar("parent", (tp("o", "block"),), ("surface", "arm"))}
    actions = {"pick": m.Action("pick", (tp("o", "block"), tp("r", "arm"), tp("s", "surface")),
                                (m.StateLit("parent", (P("o"),), P("s")),),
                                (m.Effect(m.Assign("parent", (P("o"),), P("r"))),))}
    continuous = {
        "pose": m.Continuous("pose", (tp("o", "block"),), SE3, frozenset({"object"})),
        "q": m.Continuous("q", (tp("r", "arm"),), Space("joints", 0, "r"), frozenset({"robot"})),
        "path": m.Continuous("path", (tp("r", "arm"),), Space("joints", 0, "r"),
                             frozenset({"traj", "robot"}), traj=True, waypoints=None),
    }
    frames = (m.Frame(tp("o", "block"), Call("compose_se3", (Call("world", (StateValue("parent", (P("o"),)),)),
                                                              CVar("pose", (P("o"),))))),
              m.Frame(tp("r", "arm"), Call("fk", (P("r"), CVar("q", (P("r"),))))))
    sig_o = lambda n: m.Signature(n, "object", type="object")
    sig_v = lambda n: m.Signature(n, "any")
    templates = {
        "t.path_clear": m.Template("t.path_clear", (sig_o("r"), sig_o("o"), sig_v("t")), (
            Forall("k", Num(0), Call("sub", (Call("waypoints", (P("t"),)), Num(1))), (
                Constraint(With(Call("sdist", (Call("link", (P("r"), Str("hand"))), P("o"))),
                                ((CVar("q", (P("r"),)), Index(P("t"), IterVar("k"))),)),
                           ">=", Num(0.01)),)),), frozenset({"traj", "collision"})),
        "t.above": m.Template("t.above", (sig_o("r"),), (
            Constraint(Index(Call("pos_se3", (Call("world", (P("r"),)),)), Num(2)), ">=", Num(0.0)),),
            frozenset({"robot"})),
        "t.limits": m.Template("t.limits", (sig_v("q"), sig_v("lo"), sig_v("hi")),
                               (Constraint(P("lo"), "<=", P("q")), Constraint(P("q"), "<=", P("hi"))),
                               frozenset({"robot"})),
        "t.grasp": m.Template("t.grasp", (sig_o("o"), sig_o("r")), (
            Constraint(Call("pos_se3", (Call("compose_se3", (Call("inv_se3", (Call("world", (P("r"),)),)),
                                                              Call("world", (P("o"),)))),)),
                       "==", Vec((Num(0), Num(0), Num(0)))),), frozenset({"grasp"})),
    }
    call = lambda name, *args: m.TemplateCall(name, tuple(args), templates[name].tags)
    rules = (
        m.Rule("motion", (tp("r", "arm"), tp("o", "block"), tp("s", "surface")), "state",
               (m.StateLit("parent", (P("o"),), P("s")),), (),
               (call("t.path_clear", P("r"), P("o"), CVar("path", (P("r"),))),)),
        m.Rule("limits", (tp("r", "arm"),), "always", (), (),
               (call("t.limits", CVar("q", (P("r"),)), Call("joint_min", (P("r"),)), Call("joint_max", (P("r"),))),)),
        m.Rule("above", (tp("r", "arm"),), "initial", (), (), (call("t.above", P("r")),)),
        m.Rule("held", (tp("o", "block"), tp("r", "arm")), "state",
               (m.StateLit("parent", (P("o"),), P("r")),), (), (call("t.grasp", P("o"), P("r")),)),
    )
    attrs = {n: m.SceneAttr(n, (sig_o("o"),), Space("any")) for n in ("joint_min", "joint_max")}
    domain = m.Domain("arm3d", "x", types, state_vars=state_vars, actions=actions,
                      continuous=continuous, frames=frames, templates=templates, rules=rules,
                      scene_attrs=attrs, world_space=SE3)
    scene = Scene("s", 3, {"r": SceneRobot("r", "urdf", model="toy", base=BASE, ee="tcp", home=(0.0, 0.0))},
                  {"b": SceneObject("b", SceneShape("box", (0.1, 0.1, 0.1)), (0.5, 0, 0.1, 0, 0, 0, 1)),
                   "tab": SceneObject("tab", SceneShape("box", (1, 1, 0.1)), (0.5, 0, 0, 0, 0, 0, 1))})
    objects = {"r": "arm", "b": "block", "tab": "surface"}
    init = (m.Assign("parent", (Obj("b"),), Obj("tab")),)
    return m.Problem("p", "p.pntc", domain, objects, init, (), settings=m.SolverSettings(waypoints=4), scene=scene)


def _dims(robot):
    assert robot == "r"
    return 3, (-1.0, -2.0, -3.0), (1.0, 2.0, 3.0)


def test_links_fk_with_and_joint_dimensions():
    problem = _problem()
    task = build_task(problem)
    fac = GraphNLPFactory(problem, task, robot_dims=_dims)
    states = plan_states(task, [0])          # pick(b, r, tab)
    base = Vec(tuple(Num(x) for x in BASE))
    factors = fac.factors(states)
    assert sorted((f.rule, f.step) for f in factors) == [("above", 0), ("held", 1), ("limits", 0), ("limits", 1), ("motion", 0)]
    above = next(f for f in factors if f.rule == "above")
    assert above.body[0].lhs == Index(Call("pos_se3", (Call("fk", (Obj("r"), Slot(0), Str("tcp"), base)),)), Num(2))
    motion = next(f for f in factors if f.rule == "motion")
    path, pose = motion.variables          # the block's world pose = table * pose(b)@0
    assert pose.name == "pose(b)@0" and pose.dim == 7
    assert (path.name, path.dim, path.waypoints, path.point_dim) == ("path(r)@0", 12, 4, 3)
    assert path.lower == (-1.0, -2.0, -3.0) * 4
    assert len(motion.body) == 4                                   # k = 0 .. waypoints(t) - 1
    base = Vec(tuple(Num(x) for x in BASE))
    hand = Call("link", (Obj("r"), Str("hand")))
    table = Vec(tuple(Num(x) for x in (0.5, 0, 0, 0, 0, 0, 1)))
    for k, c in enumerate(motion.body):
        fk = Call("fk", (Obj("r"), Call("waypoint", (Slot(0), Num(k))), Str("hand"), base))
        assert c.lhs == Call("sdist", (hand, fk, Obj("b"), Call("compose_se3", (table, Slot(1))))), k
    # joint limits folded from robot_dims
    lim = next(f for f in factors if f.rule == "limits")
    assert lim.variables[0].dim == 3 and lim.body[0].lhs == Vec((Num(-1.0), Num(-2.0), Num(-3.0)))
    # the held block's world pose is fk(r, q(r)) * pose(b); the grasp relates it to fk(r, q(r))
    # itself, so inv(fk) * (fk * pose(b)) cancels to pose(b): no q(r), no fk in the body,
    # but the chain fact parent(b) = r read on the way stays in the generator
    held = next(f for f in factors if f.rule == "held")
    assert [v.name for v in held.variables] == ["pose(b)@1"]
    assert held.body[0].lhs == Call("pos_se3", (Slot(0),))
    assert [task.partial_state_str(p) for p in held.generator] == ["{parent(b) = r}"]
    # elsewhere fk gets the default end effector `tcp` and the robot base
    fks = [n for f in factors for n in _walk(f.body) if isinstance(n, Call) and n.fn == "fk"]
    assert fks and all(n.args[3] == base for n in fks)
    # warm start of a joints variable: the home configuration does not fit nq = 3 -> midpoint
    assert fac.initial_guess(lim.variables[0]) == [0.0, 0.0, 0.0]


def _walk(node):
    yield node
    if isinstance(node, tuple):
        for x in node:
            yield from _walk(x)
    elif hasattr(node, "__dataclass_fields__"):
        for name in node.__dataclass_fields__:
            if name != "span":
                yield from _walk(getattr(node, name))
