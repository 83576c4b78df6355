"""The planar blocks domain (examples/planar/domain.pntc) built directly as IR objects.

Why: the compiler is tested without the parser, so a parser bug cannot mask (or fake) a
compiler result. The bodies are what the type checker must produce for stdlib/planar.pntc
(overloads resolved to SE2 builtins).
"""
from __future__ import annotations

from gnppdsl.ir import model as m
from gnppdsl.ir.builtins import SE2, R, SCALAR, Space
from gnppdsl.ir.expr import Call, Constraint, CVar, Forall, Index, IterVar, Num, Obj, Param, StateValue, Vec
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

P = Param


def tp(name, *types):
    return m.TypedParam(name, tuple(types))


def world(x):
    return Call("world", (x,))


def nxt(e):
    return Call("next", (e,))


def comp(a, b):
    return Call("compose_se2", (a, b))


def inv(a):
    return Call("inv_se2", (a,))


def pos(a):
    return Call("pos_se2", (a,))


def obj_sig(name):
    return m.Signature(name, "object", type="object")


def val_sig(name, space=None):
    return m.Signature(name, "value" if space else "any", space=space)


TEMPLATES = {
    "planar.same": m.Template("planar.same", (val_sig("a"), val_sig("b")),
                              (Constraint(P("a"), "==", P("b")),), frozenset({"time"}), "planar"),
    "planar.ref": m.Template("planar.ref", (val_sig("a"), val_sig("b")),
                             (Constraint(P("a"), "==", P("b")),), frozenset({"ref"}), "planar"),
    "planar.kin_switch": m.Template(
        "planar.kin_switch", (obj_sig("o"), obj_sig("from")),
        (Constraint(nxt(world(P("o"))), "==",
                    comp(nxt(world(P("from"))), comp(inv(world(P("from"))), world(P("o"))))),),
        frozenset({"kin"}), "planar"),
    "planar.grasp": m.Template(
        "planar.grasp", (obj_sig("o"), obj_sig("g")),
        (Constraint(Call("sqnorm", (pos(comp(inv(world(P("g"))), world(P("o")))),)), "<=",
                    Call("pow", (Num(0.01), Num(2)))),),
        frozenset({"grasp"}), "planar"),
    "planar.inside": m.Template(
        "planar.inside", (obj_sig("o"), obj_sig("reg")),
        (Constraint(pos(comp(inv(world(P("reg"))), world(P("o")))), "<=",
                    Call("sub", (Call("half_extent", (P("reg"),)), Call("radius", (P("o"),))))),
         Constraint(pos(comp(inv(world(P("reg"))), world(P("o")))), ">=",
                    Call("sub", (Call("radius", (P("o"),)), Call("half_extent", (P("reg"),)))))),
        frozenset({"place"}), "planar"),
    "planar.no_overlap": m.Template(
        "planar.no_overlap", (obj_sig("a"), obj_sig("b")),
        (Constraint(Call("sqnorm", (Call("sub", (pos(world(P("a"))), pos(world(P("b"))))),)), ">=",
                    Call("pow", (Call("add", (Call("radius", (P("a"),)), Call("radius", (P("b"),)))), Num(2)))),),
        frozenset({"collision"}), "planar"),
    "planar.within": m.Template(
        "planar.within", (val_sig("p", SE2), val_sig("lo", R(2)), val_sig("hi", R(2))),
        (Constraint(pos(P("p")), ">=", P("lo")), Constraint(pos(P("p")), "<=", P("hi"))),
        frozenset({"robot"}), "planar"),
    "planar.no_collision": m.Template(
        "planar.no_collision", (obj_sig("a"), obj_sig("b")),
        (Constraint(Call("sdist", (P("a"), P("b"))), ">=", Num(0.0)),), frozenset({"collision"}), "planar"),
    # a trajectory template (not in the stdlib file): consecutive waypoints close together
    "planar.smooth": m.Template(
        "planar.smooth", (obj_sig("g"),),
        (Forall("k", Num(0), Call("sub", (Call("waypoints", (CVar("path", (P("g"),)),)), Num(2))),
                (Constraint(Call("sqnorm", (Call("sub", (pos(Index(CVar("path", (P("g"),)), Call("add", (IterVar("k"), Num(1))))),
                                                         pos(Index(CVar("path", (P("g"),)), IterVar("k"))))),)),
                            "<=", Num(0.01)),)),),
        frozenset({"traj"}), "planar"),
}

SCENE_ATTRS = {name: m.SceneAttr(name, (obj_sig("o"),), space, "prelude") for name, space in [
    ("radius", SCALAR), ("half_extent", R(2)), ("reach_min", R(2)), ("reach_max", R(2)),
    ("home", Space("any")), ("size", R(3)), ("pose0", Space("any"))]}


def lit(var, args, value, neg=False):
    return m.StateLit(var, tuple(args), value, neg)


def call(name, *args, tags=()):
    return m.TemplateCall(name, tuple(args), frozenset(TEMPLATES[name].tags) | frozenset(tags))


def domain(with_traj: bool = False, with_clear: bool = False) -> m.Domain:
    types = {"object": m.Type("object", None)}
    for name, parent in [("place", "object"), ("spot", "place"), ("region", "place"),
                         ("block", "object"), ("gripper", "object")]:
        types[name] = m.Type(name, parent)
    state_vars = {
        "parent": m.StateVar("parent", (tp("o", "block"),), ("place", "gripper")),
        "holding": m.StateVar("holding", (tp("g", "gripper"),), ("block", "none")),
    }
    derived = {}
    pick_pre = [lit("parent", [P("o")], P("from")), lit("holding", [P("g")], Obj("none"))]
    if with_clear:
        # clear(x) := not exists o: block . parent(o) = x ; region capacity one block
        derived["clear"] = m.Derived("clear", (tp("x", "place"),),
                                     m.Not(m.Exists((tp("z", "block"),), lit("parent", [P("z")], P("x")))))
    place_pre = [lit("parent", [P("o")], P("g"))]
    if with_clear:
        place_pre.append(m.DerivedLit("clear", (P("to"),)))
    actions = {
        "pick": m.Action("pick", (tp("o", "block"), tp("g", "gripper"), tp("from", "place")),
                         tuple(pick_pre),
                         (m.Effect(m.Assign("parent", (P("o"),), P("g"))),
                          m.Effect(m.Assign("holding", (P("g"),), P("o"))))),
        "place": m.Action("place", (tp("o", "block"), tp("g", "gripper"), tp("to", "region")),
                          tuple(place_pre),
                          (m.Effect(m.Assign("parent", (P("o"),), P("to"))),
                           m.Effect(m.Assign("holding", (P("g"),), Obj("none"))))),
        "handover": m.Action("handover", (tp("o", "block"), tp("g", "gripper"), tp("h", "gripper")),
                             (lit("parent", [P("o")], P("g")), lit("holding", [P("h")], Obj("none")),
                              m.Compare(P("g"), "!=", P("h"))),
                             (m.Effect(m.Assign("parent", (P("o"),), P("h"))),
                              m.Effect(m.Assign("holding", (P("g"),), Obj("none"))),
                              m.Effect(m.Assign("holding", (P("h"),), P("o"))))),
    }
    continuous = {
        "pose": m.Continuous("pose", (tp("o", "block"),), SE2, frozenset({"object"})),
        "q": m.Continuous("q", (tp("g", "gripper"),), SE2, frozenset({"robot"})),
    }
    if with_traj:
        continuous["path"] = m.Continuous("path", (tp("g", "gripper"),), SE2,
                                          frozenset({"traj", "robot"}), traj=True, waypoints=5)
    frames = (m.Frame(tp("o", "block"), comp(world(StateValue("parent", (P("o"),))), CVar("pose", (P("o"),)))),
              m.Frame(tp("g", "gripper"), CVar("q", (P("g"),))))
    rules = [
        m.Rule("home", (tp("g", "gripper"),), "initial", (), (),
               (call("planar.ref", CVar("q", (P("g"),)), Call("home", (P("g"),)), tags=("robot",)),),
               tags=frozenset({"robot"})),
        m.Rule("reach", (tp("g", "gripper"),), "always", (), (),
               (call("planar.within", CVar("q", (P("g"),)), Call("reach_min", (P("g"),)),
                     Call("reach_max", (P("g"),))),)),
        m.Rule("on_spot", (tp("o", "block"), tp("s", "spot")), "state",
               (lit("parent", [P("o")], P("s")),), (),
               (call("planar.ref", CVar("pose", (P("o"),)), Vec((Num(0), Num(0), Num(0)))),)),
        m.Rule("stay", (tp("o", "block"), tp("p", "place", "gripper")), "transition",
               (lit("parent", [P("o")], P("p")),), (lit("parent", [P("o")], P("p")),),
               (call("planar.same", CVar("pose", (P("o"),)), CVar("pose", (P("o"),), next=True)),)),
        m.Rule("switch", (tp("o", "block"), tp("p", "place", "gripper"), tp("p2", "place", "gripper")),
               "transition", (lit("parent", [P("o")], P("p")),), (lit("parent", [P("o")], P("p2")),),
               (call("planar.kin_switch", P("o"), P("p")),), where=(m.Compare(P("p"), "!=", P("p2")),)),
        m.Rule("held", (tp("o", "block"), tp("g", "gripper")), "state",
               (lit("parent", [P("o")], P("g")),), (), (call("planar.grasp", P("o"), P("g")),)),
        m.Rule("placed", (tp("o", "block"), tp("r", "region")), "state",
               (lit("parent", [P("o")], P("r")),), (), (call("planar.inside", P("o"), P("r")),)),
        m.Rule("apart", (tp("a", "block"), tp("b", "block")), "always", (), (),
               (call("planar.no_overlap", P("a"), P("b")),), where=(m.Compare(P("a"), "<", P("b")),)),
    ]
    if with_traj:
        rules.append(m.Rule("smooth", (tp("g", "gripper"),), "always", (), (),
                            (call("planar.smooth", P("g")),)))
    return m.Domain("planar_blocks", "planar_ir.py", types, state_vars=state_vars, derived=derived,
                    actions=actions, continuous=continuous, frames=frames, templates=dict(TEMPLATES),
                    rules=tuple(rules), scene_attrs=dict(SCENE_ATTRS), world_space=SE2)


def _circle(r):
    return SceneShape("circle", (r,))


def problem(name: str = "p2", *, with_traj=False, with_clear=False, init_overrides=None,
            drop_init=()) -> m.Problem:
    """p1 (one block), p2 (two blocks, two regions), p5 (handover with two grippers)."""
    d = domain(with_traj, with_clear)
    if name == "p1":
        objects = {"b1": "block", "s1": "spot", "r1": "region", "g": "gripper"}
        init = {("parent", "b1"): "s1", ("holding", "g"): "none"}
        goal = [lit("parent", [Obj("b1")], Obj("r1"))]
        robots = {"g": ([0.0, 0.0, 0.0], [-1, -1], [1, 1])}
        poses = {"s1": (-0.5, 0.0, 0.0), "r1": (0.5, 0.0, 0.0), "b1": (-0.5, 0.0, 0.0)}
    elif name == "p2":
        objects = {"b1": "block", "b2": "block", "s1": "spot", "s2": "spot", "ra": "region",
                   "rb": "region", "g": "gripper"}
        init = {("parent", "b1"): "s1", ("parent", "b2"): "s2", ("holding", "g"): "none"}
        goal = [lit("parent", [Obj("b1")], Obj("rb")), lit("parent", [Obj("b2")], Obj("ra"))]
        robots = {"g": ([0.1, 0.2, 0.3], [-1, -1], [1, 1])}
        poses = {"s1": (-0.5, 0.2, 0.0), "s2": (-0.5, -0.2, 0.5), "ra": (0.5, 0.3, 0.0),
                 "rb": (0.5, -0.3, 0.0), "b1": (-0.5, 0.2, 0.0), "b2": (-0.4, -0.2, 0.5)}
    elif name == "p5":
        objects = {"b1": "block", "s1": "spot", "target": "region", "g1": "gripper", "g2": "gripper"}
        init = {("parent", "b1"): "s1", ("holding", "g1"): "none", ("holding", "g2"): "none"}
        goal = [lit("parent", [Obj("b1")], Obj("target"))]
        robots = {"g1": ([-0.5, -0.5, 0.0], [-1, -1], [0.15, 1]), "g2": ([0.5, -0.5, 0.0], [-0.15, -1], [1, 1])}
        poses = {"s1": (-0.6, 0.0, 0.0), "target": (0.6, 0.0, 0.0), "b1": (-0.6, 0.0, 0.0)}
    else:
        raise ValueError(name)
    init.update(init_overrides or {})
    for key in drop_init:
        init.pop(key, None)
    scene_objects = {}
    for o, t in objects.items():
        if t == "gripper":
            continue
        attrs = {}
        shape = SceneShape("none")
        if t == "block":
            attrs["radius"] = 0.05
            shape = _circle(0.05)
        if t == "region":
            attrs["half_extent"] = (0.15, 0.15)
            shape = SceneShape("box", (0.3, 0.3, 0.01))
        x, y, th = poses[o]
        scene_objects[o] = SceneObject(o, shape, (x, y, 0.0, 0.0, 0.0, 0.0, 1.0), (x, y, th), attributes=attrs)
    scene_robots = {g: SceneRobot(g, "planar", home=tuple(h), shape=_circle(0.03),
                                  attributes={"reach_min": tuple(lo), "reach_max": tuple(hi)})
                    for g, (h, lo, hi) in robots.items()}
    scene = Scene(name, 2, scene_robots, scene_objects)
    init_assigns = tuple(m.Assign(v, (Obj(a),), Obj(val)) for (v, a), val in init.items())
    return m.Problem(name, f"{name}.pntc", d, objects, init_assigns, tuple(goal), scene=scene)
