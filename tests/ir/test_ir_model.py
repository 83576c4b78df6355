"""The IR the front end produces: overload resolution, primes, logic normal forms, rules, problems.

Expected IR is written out by hand from the language rules in docs/reference.md and the
conventions of gnppdsl/ir/model.py, not derived from the checker's own tables.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import pytest

from gnppdsl.errors import UserError
from gnppdsl.ir import builtins as B
from gnppdsl.ir import load_domain, load_module, load_problem
from gnppdsl.ir import model as M
from gnppdsl.ir.expr import (Call, Constraint, CVar, Forall, Index, IterVar, Num, Obj, Param,
                             StateValue, Str, Vec, With)
from gnppdsl.lang.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[2]

HEAD = """\
domain d
type place
type region < place
type block
type gripper
type arm
state parent(o: block) : place | gripper
state holding(g: gripper) : block | none
state free(g: gripper) : bool
continuous pose(o: block) : SE3 tags object
continuous q(r: arm) : joints(r) tags robot
continuous c(g: gripper) : SE3 tags robot
traj path(r: arm) : joints(r) waypoints 10 tags traj
frame o: block = world(parent(o)) * pose(o)
frame g: gripper = c(g)
frame r: arm = fk(r, q(r))
"""


def domain(tmp_path, extra: str) -> M.Domain:
    (tmp_path / "d.pntc").write_text(HEAD + textwrap.dedent(extra))
    return load_domain(tmp_path / "d.pntc")


def body(tmp_path, params: str, stmts: str):
    d = domain(tmp_path, f"template t({params}) {{\n{stmts}\n}}\n")
    return d.templates["d.t"].body


P = Param


# ---------------------------------------------------------------- overloads
def test_pose_products_resolve_by_space(tmp_path):
    (c1, c2, c3, c4) = body(tmp_path, "a: SE2, b: SE2, p: SE3, u: quat, x: R[3], y: R[2]",
                            "a * b == a\n p * p == p\n p * x == x\n u * x == u * u * x\n")
    assert c1.lhs == Call("compose_se2", (P("a"), P("b")))
    assert c2.lhs == Call("compose_se3", (P("p"), P("p")))
    assert c3.lhs == Call("apply_se3", (P("p"), P("x")))
    assert c4.lhs == Call("quat_rotate", (P("u"), P("x")))
    assert c4.rhs == Call("quat_rotate", (Call("quat_mul", (P("u"), P("u"))), P("x")))


def test_overloaded_functions(tmp_path):
    cs = body(tmp_path, "a: SE2, p: SE3, u: quat, y: R[2]",
              "pos(p) == [0, 0, 0]\n pos(a) == y\n rot(p) == inv(u)\n rot(a) == angle(inv(a))\n"
              " axis(p, 2) == axis(u, 0)\n apply(a, y) == y\n inv(p) == p\n")
    assert cs[0].lhs == Call("pos_se3", (P("p"),))
    assert cs[1].lhs == Call("pos_se2", (P("a"),))
    assert (cs[2].lhs, cs[2].rhs) == (Call("rot_se3", (P("p"),)), Call("quat_conj", (P("u"),)))
    assert cs[3].rhs == Call("angle_se2", (Call("inv_se2", (P("a"),)),))
    assert cs[4].lhs == Call("axis_se3", (P("p"), Num(2)))
    assert cs[4].rhs == Call("quat_axis", (P("u"), Num(0)))
    assert cs[5].lhs == Call("apply_se2", (P("a"), P("y")))
    assert cs[6].lhs == Call("inv_se3", (P("p"),))


def test_arithmetic(tmp_path):
    (c,) = body(tmp_path, "x: R[3], s: R", "-x + x * s - x / s == x ^ 2")
    assert c.lhs == Call("sub", (Call("add", (Call("neg", (P("x"),)), Call("mul", (P("x"), P("s"))))),
                                 Call("div", (P("x"), P("s")))))
    assert c.rhs == Call("pow", (P("x"), Num(2)))


def test_constant_folding_and_consts(tmp_path):
    d = domain(tmp_path, "const k = 2 * 3\nconst v = [1, 2]\n"
                         "template t(y: R[2]) { y == v * k\n norm(y) <= pi / 2 }\n")
    assert d.consts == {"k": 6.0, "v": (1.0, 2.0)}
    c1, c2 = d.templates["d.t"].body
    assert c1.rhs == Call("mul", (Vec((Num(1), Num(2))), Num(6)))
    assert c2.rhs == Num(math.pi / 2)


def test_chain_and_index_and_slice(tmp_path):
    c1, c2 = body(tmp_path, "p: SE3", "0 <= pos(p)[0:2] <= 1")
    assert c1 == Constraint(Num(0), "<=", Index(Call("pos_se3", (P("p"),)), Num(0), Num(2)))
    assert c2.op == "<=" and c2.rhs == Num(1)


# ---------------------------------------------------------------- user-level functions and primes
def test_world_state_values_and_primes(tmp_path):
    cs = body(tmp_path, "o: block, b: object",
              "world(o)' == world(parent(o))' * pose(o)'\n"
              "pos(world(o) * world(b))' == pos(world(o))\n")
    w = lambda x: Call("world", (x,))  # noqa: E731
    nxt = lambda e: Call("next", (e,))  # noqa: E731
    assert cs[0].lhs == nxt(w(P("o")))
    assert cs[0].rhs == Call("compose_se3", (nxt(w(StateValue("parent", (P("o"),)))),
                                              CVar("pose", (P("o"),), True)))
    assert cs[1].lhs == Call("pos_se3", (Call("compose_se3", (nxt(w(P("o"))), nxt(w(P("b"))))),))
    assert d_two_step(tmp_path)


def d_two_step(tmp_path) -> bool:
    d = domain(tmp_path, "template a(o: block) { world(o)' == world(o) }\n"
                         "template b(o: block) { world(o) == world(o) }\n")
    return d.templates["d.a"].two_step and not d.templates["d.b"].two_step


def test_primitives_scene_attributes_and_waypoints(tmp_path):
    cs = body(tmp_path, "r: arm, o: block",
              'sdist(link(r, "hand"), o) >= radius(o)\n'
              'pos(fk(r, q(r), "panda_link5")) == pos(fk(r, q(r)))\n'
              "forall k in 0 .. waypoints(path(r)) - 1 {\n"
              "  (sdist(r, o) with q(r) = path(r)[k]) >= 0\n}\n")
    assert cs[0].lhs == Call("sdist", (Call("link", (P("r"), Str("hand"))), P("o")))
    assert cs[0].rhs == Call("radius", (P("o"),))
    assert cs[1].lhs == Call("pos_se3", (Call("fk", (P("r"), CVar("q", (P("r"),)), Str("panda_link5"))),))
    assert cs[1].rhs == Call("pos_se3", (Call("fk", (P("r"), CVar("q", (P("r"),)))),))
    f = cs[2]
    assert isinstance(f, Forall) and f.var == "k" and f.lo == Num(0)
    assert f.hi == Call("sub", (Call("waypoints", (CVar("path", (P("r"),)),)), Num(1)))
    (inner,) = f.body
    assert inner.lhs == With(Call("sdist", (P("r"), P("o"))),
                             ((CVar("q", (P("r"),)), Index(CVar("path", (P("r"),)), IterVar("k"))),))


def test_frames_and_world_space(tmp_path):
    d = domain(tmp_path, "")
    assert d.world_space == B.SE3
    fo = d.frame_of("block")
    assert fo.expr == Call("compose_se3", (Call("world", (StateValue("parent", (P("o"),)),)),
                                           CVar("pose", (P("o"),))))
    assert d.frame_of("region") is None and d.frame_of("arm").expr == Call("fk", (P("r"), CVar("q", (P("r"),))))


def test_planar_world_space():
    d = load_domain(ROOT / "examples" / "planar" / "domain.pntc")
    assert d.world_space == B.SE2
    assert d.continuous["pose"].space == B.SE2


def test_joints_space_names_the_parameter(tmp_path):
    d = domain(tmp_path, "")
    assert d.continuous["q"].space == B.Space("joints", 0, "r")
    assert d.continuous["path"].traj and d.continuous["path"].waypoints == 10


# ---------------------------------------------------------------- logic
def test_derived_formula_normal_form(tmp_path):
    d = domain(tmp_path, "derived clear(x: place) := not exists o: block . parent(o) = x\n"
                         "derived idle(g: gripper) := free(g) and not (holding(g) != none or not free(g))\n")
    clear = d.derived["clear"].body
    assert clear == M.Not(M.Exists((M.TypedParam("o", ("block",)),),
                                   M.StateLit("parent", (P("o"),), P("x"))))
    idle = d.derived["idle"].body
    assert idle.items[0] == M.StateLit("free", (P("g"),), Obj("true"))
    assert idle.items[1] == M.Not(M.Or((M.StateLit("holding", (P("g"),), Obj("none"), True),
                                        M.StateLit("free", (P("g"),), Obj("false")))))


def test_action_normal_form(tmp_path):
    d = domain(tmp_path, """\
        derived clear(x: place) := not exists o: block . parent(o) = x
        action pick(o: block, g: gripper, from: place) {
          pre parent(o) = from, holding(g) = none, not clear(from), free(g), g != from
          eff parent(o) := g, not free(g), when free(g) and holding(g) = none { holding(g) := o }
          cost 3
        }
        """)
    a = d.actions["pick"]
    assert a.pre == (M.StateLit("parent", (P("o"),), P("from")),
                     M.StateLit("holding", (P("g"),), Obj("none")),
                     M.DerivedLit("clear", (P("from"),), True),
                     M.StateLit("free", (P("g"),), Obj("true")),
                     M.Compare(P("g"), "!=", P("from")))
    assert a.effects == (
        M.Effect(M.Assign("parent", (P("o"),), P("g"))),
        M.Effect(M.Assign("free", (P("g"),), Obj("false"))),
        M.Effect(M.Assign("holding", (P("g"),), P("o")),
                 (M.StateLit("free", (P("g"),), Obj("true")), M.StateLit("holding", (P("g"),), Obj("none")))),
    )
    assert a.cost == 3


def test_rules(tmp_path):
    d = domain(tmp_path, """\
        template same(a: value, b: value) tags time { a == b }
        rule stay(o: block, p) : parent(o) = p -> parent(o) = p => same(pose(o), pose(o)') tags object
        rule apart(a: block, b: block) where a < b : always => same(world(a), world(b))
        rule home(r: arm) : initial => same(q(r), home(r))
        rule held(o: block, g: gripper) : parent(o) = g, not free(g) => same(world(o), c(g))
        """)
    stay, apart, home, held = d.rules
    assert stay.kind == "transition" and stay.params[1] == M.TypedParam("p", ("place", "gripper"))
    assert stay.pre == stay.post == (M.StateLit("parent", (P("o"),), P("p")),)
    (call,) = stay.calls
    assert call.template == "d.same" and call.tags == {"time", "object"}
    assert call.args == (CVar("pose", (P("o"),)), CVar("pose", (P("o"),), True))
    assert apart.kind == "always" and apart.where == (M.Compare(P("a"), "<", P("b")),)
    assert home.kind == "initial" and home.calls[0].args[1] == Call("home", (P("r"),))
    assert held.pre[1] == M.StateLit("free", (P("g"),), Obj("false"))


# ---------------------------------------------------------------- problems
def test_problem_defaults_settings_and_helpers(tmp_path):
    (tmp_path / "domain.pntc").write_text(HEAD + "constants { table : place }\n"
                                          "solver { seed = 3  time_limit = 10 }\n"
                                          "relaxations { a : drop robot }\n")
    (tmp_path / "p.pntc").write_text(textwrap.dedent("""\
        problem p for d
        objects { b1, b2 : block  r1 : region  g : gripper }
        init { parent(b1) = table  parent(b2) = r1  free(g) }
        goal { parent(b1) = g  not free(g) }
        solver { time_limit = 5 }
        """))
    p = load_problem(tmp_path / "p.pntc")
    assert list(p.objects) == ["table", "b1", "b2", "r1", "g"]
    assert p.settings.seed == 3 and p.settings.time_limit == 5.0 and p.settings.waypoints == 20
    assert [r.name for r in p.relaxations] == ["a"]
    init = {(a.var, a.args): a.value for a in p.init}
    assert init == {("parent", (Obj("b1"),)): Obj("table"), ("parent", (Obj("b2"),)): Obj("r1"),
                    ("holding", (Obj("g"),)): Obj("none"), ("free", (Obj("g"),)): Obj("true")}
    assert p.goal == (M.StateLit("parent", (Obj("b1"),), Obj("g")), M.StateLit("free", (Obj("g"),), Obj("false")))
    assert p.values_of(p.domain.state_vars["parent"]) == ("table", "r1", "g")
    assert p.values_of(p.domain.state_vars["holding"]) == ("b1", "b2", "none")
    assert p.values_of(p.domain.state_vars["free"]) == ("false", "true")
    assert p.objects_of("place") == ("table", "r1")
    assert list(p.groundings(p.domain.state_vars["parent"].params)) == [("b1",), ("b2",)]
    assert p.object_index("b2") == 2 and p.scene is None
    assert p.waypoints_of(p.domain.continuous["path"]) == 10


def test_load_problem_raises_diagnostic_error(tmp_path):
    (tmp_path / "domain.pntc").write_text(HEAD)
    (tmp_path / "p.pntc").write_text("problem p for d\nobjects { b : blok }\ngoal { }\n")
    with pytest.raises(DiagnosticError) as exc:
        load_problem(tmp_path / "p.pntc")
    assert isinstance(exc.value, UserError) and exc.value.exit_code == 2
    text = str(exc.value)
    assert "p.pntc:2:15: error: unknown type 'blok'" in text and "did you mean 'block'?" in text
    assert text.rstrip().endswith("1 error")


def test_load_module():
    m = load_module(ROOT / "stdlib" / "planar.pntc")
    assert m.name == "planar" and "planar.grasp" in m.templates and m.consts["grasp_tol"] == 0.01


# ---------------------------------------------------------------- the examples (contract for H2)
USER_LEVEL = {"world", "sdist", "fk", "link", "waypoints", "next"}


def _calls(e, out):
    if isinstance(e, Call):
        out.add(e.fn)
    for f in ("args", "items", "body", "lhs", "rhs", "base", "index", "stop", "lo", "hi"):
        v = getattr(e, f, None)
        if isinstance(v, tuple):
            for x in v:
                _calls(x, out)
        elif v is not None and not isinstance(v, (str, int, float, bool)):
            _calls(v, out)
    if isinstance(e, With):
        for k, v in e.substitutions:
            _calls(v, out)


EXAMPLE_PROBLEMS = sorted(p for p in (ROOT / "examples").glob("*/*.pntc") if p.name != "domain.pntc")


@pytest.mark.parametrize("problem", EXAMPLE_PROBLEMS, ids=lambda p: f"{p.parent.name}/{p.name}")
def test_example_problems_resolve_to_monomorphic_bodies(problem):
    p = load_problem(problem)
    dom = p.domain
    called = {c.template for r in dom.rules for c in r.calls}
    for name in called:
        t = dom.templates[name]
        fns: set = set()
        for st in t.body:
            _calls(st, fns)
        unknown = fns - set(B.BUILTINS) - USER_LEVEL - set(dom.scene_attrs)
        assert not unknown, f"{name}: unresolved calls {unknown}"
    for r in dom.rules:
        for c in r.calls:
            assert len(c.args) == len(dom.templates[c.template].params)
            if dom.templates[c.template].two_step:
                assert r.kind == "transition"
    assert p.scene is not None and set(p.objects) - set(dom.constants) <= \
        set(p.scene.objects) | set(p.scene.robots) | set(p.objects)
