"""The casadi lowering (`lowering`, `body_compiler`) vs the independent numpy evaluator, on every
builtin, plus known values."""
from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.errors import UserError
from gnppdsl.ir.builtins import BUILTINS
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Str, Vec
from gnppdsl.nlp import evaluate, lowering
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.lowering import BodyError

from nlp_toys import C, DiscGeometry, no_overlap, pose

GEOM = DiscGeometry({"a": 0.3, "b": 0.2, "arm2/l1": 0.1})


def test_every_builtin_is_implemented_in_casadi_and_numpy():
    assert set(BUILTINS) == set(lowering.IMPLEMENTED)
    assert set(BUILTINS) == set(evaluate.EVALUATED)


def var(name, space, dim, waypoints=0):
    return VarInstance(name, (), 0, space, dim, waypoints=waypoints)


S1, V3, V2 = var("s", "R", 1), var("v", "R", 3), var("w", "R", 2)
T2, T2b = var("p", "SE2", 3), var("pb", "SE2", 3)
Q = var("q", "quat", 4)
P3, P3b = var("P", "SE3", 7), var("Pb", "SE3", 7)
TR = var("path", "R", 12, waypoints=4)   # 4 waypoints of R[3]
J = var("j", "joints", 2)
ALL = [S1, V3, V2, T2, T2b, Q, P3, P3b, TR, J]
s, v, w, p, pb, q, P, Pb, tr, j = (Slot(i) for i in range(len(ALL)))

# one expression per builtin (and some extra shapes), over the slots above
CASES = {
    "add": C("add", v, s), "sub": C("sub", v, C("cross", v, v)), "mul": C("mul", s, v),
    "div": C("div", v, C("add", Num(2.0), C("sqnorm", v))), "neg": C("neg", v),
    "pow": C("pow", C("abs", v), Num(1.5)), "sqrt": C("sqrt", C("add", Num(1.0), C("sqnorm", v))),
    "sin": C("sin", v), "cos": C("cos", v), "atan2": C("atan2", Index(v, Num(0)), Index(v, Num(1))),
    "abs": C("abs", v), "exp": C("exp", s), "min": C("min", v, s), "max": C("max", v, s),
    "norm": C("norm", v), "sqnorm": C("sqnorm", v), "dot": C("dot", v, C("sin", v)),
    "cross": C("cross", v, C("cos", v)), "sum": C("sum", v),
    "concat": C("concat", s, v, w), "se2": C("se2", s, Index(w, Num(1)), Index(v, Num(2))),
    "compose_se2": C("compose_se2", p, pb), "inv_se2": C("inv_se2", C("compose_se2", p, pb)),
    "pos_se2": C("pos_se2", p), "angle_se2": C("angle_se2", p), "apply_se2": C("apply_se2", p, w),
    "angle_diff": C("angle_diff", Num(3.0), C("mul", Num(4.0), s)),
    "se3": C("se3", v, q), "compose_se3": C("compose_se3", P, Pb),
    "inv_se3": C("inv_se3", P), "pos_se3": C("pos_se3", P), "rot_se3": C("rot_se3", P),
    "apply_se3": C("apply_se3", P, v), "axis_se3": C("axis_se3", P, Num(1)),
    "quat_mul": C("quat_mul", q, C("rot_se3", P)), "quat_conj": C("quat_conj", q),
    "quat_rotate": C("quat_rotate", q, v), "quat_dist": C("quat_dist", q, C("rot_se3", Pb)),
    "quat_axis": C("quat_axis", q, Num(2)),
    "waypoint": C("waypoint", tr, Num(-1)),
    "fk": C("fk", Obj("arm2"), j, Str("tip"), P),
    "sdist": C("sdist", Obj("a"), P, C("link", Obj("arm2"), Str("l1")), Pb),
    "sdist2": C("sdist2", Obj("a"), p, Obj("b"), pb),
    "link": C("sdist2", C("link", Obj("arm2"), Str("l1")), p, Obj("b"), pb),
    "index_traj": Index(tr, Num(2)), "slice": Index(C("concat", v, w), Num(1), Num(4)),
    "inv_compose_identity": C("compose_se3", C("inv_se3", P), P),
}


def random_values(rng):
    vals = {}
    for x in ALL:
        val = rng.normal(size=x.dim)
        if x.space == "quat":
            val /= np.linalg.norm(val)
        if x.space == "SE3":
            val[3:] /= np.linalg.norm(val[3:])
        vals[x] = val
    return vals


def test_all_builtins_covered_by_cases():
    used = set()

    def walk(e):
        if isinstance(e, Call):
            used.add(e.fn)
            for a in e.args:
                walk(a)
        elif isinstance(e, Index):
            walk(e.base)
    for e in CASES.values():
        walk(e)
    assert used >= set(BUILTINS)


@pytest.mark.parametrize("name", sorted(CASES))
def test_casadi_matches_numpy_on_random_inputs(name):
    f = FactorInstance("t." + name, "r", (), frozenset(), 0, 1, (), tuple(ALL),
                       (Constraint(CASES[name], "==", Num(0.5)),
                        Constraint(CASES[name], ">=", Num(-0.25))))
    comp = BodyCompiler(GEOM)
    cb, params = comp.compile(f)
    rng = np.random.default_rng(1)
    for _ in range(20):
        vals = random_values(rng)
        h = np.asarray(cb.function(*[vals[x] for x in ALL], params)).reshape(-1)
        rows = evaluate.constraint_rows(f, vals, GEOM)
        assert [k for k, _ in rows] == list(cb.kinds)
        np.testing.assert_allclose(h, [r for _, r in rows], rtol=1e-9, atol=1e-9)


def num(expr, vals, geometry=GEOM):
    f = FactorInstance("t", "r", (), frozenset(), 0, 1, (), tuple(ALL),
                       (Constraint(expr, "==", Num(0.0)),))
    return np.array([h for _, h in evaluate.constraint_rows(f, vals, geometry)])


def test_known_values_independent_of_both_implementations():
    vals = random_values(np.random.default_rng(0))
    vals[T2] = np.array([1.0, 2.0, math.pi / 2])
    vals[V2] = np.array([1.0, 0.0])
    vals[Q] = np.array([0.0, 0.0, math.sin(math.pi / 4), math.cos(math.pi / 4)])  # 90 deg about z
    vals[V3] = np.array([1.0, 0.0, 0.0])
    vals[P3] = np.array([1.0, 2.0, 3.0, *vals[Q]])
    np.testing.assert_allclose(num(C("apply_se2", p, w), vals), [1.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(num(C("quat_rotate", q, v), vals), [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(num(C("apply_se3", P, v), vals), [1.0, 3.0, 3.0], atol=1e-12)
    np.testing.assert_allclose(num(C("inv_se3", P), vals)[:3], [-2.0, 1.0, -3.0], atol=1e-12)
    np.testing.assert_allclose(num(C("quat_axis", q, Num(0)), vals), [0.0, 1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(num(C("angle_diff", Num(3.0), Num(-3.0)), vals),
                               [6.0 - 2 * math.pi], atol=1e-12)
    vals[TR] = np.arange(12.0)
    np.testing.assert_allclose(num(C("waypoint", tr, Num(-1)), vals), [9.0, 10.0, 11.0])
    vals[J] = np.array([math.pi / 2, 0.0])
    vals[P3] = np.array([0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])
    np.testing.assert_allclose(num(C("pos_se3", C("fk", Obj("arm2"), j, Str("tip"), P)), vals),
                               [0.0, 2.0, 0.0], atol=1e-12)


def test_one_function_per_structure_constants_lifted():
    comp = BodyCompiler()
    a, b, c = pose("a", 0), pose("b", 0), pose("c", 1)
    f1 = no_overlap(a, b, 0.3, 0.2, 0)
    f2 = no_overlap(b, c, 0.5, 0.1, 1)
    (cb1, p1), (cb2, p2) = comp.compile(f1), comp.compile(f2)
    assert cb1 is cb2 and comp.compiled == 1
    assert list(p1) == [0.3, 0.2] and list(p2) == [0.5, 0.1]
    x = [np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.0, 0.0])]
    # h = (ra + rb) - |pa - pb| <= 0
    assert float(cb1.function(*x, p1)) == pytest.approx(0.5 - 1.0)
    assert float(cb2.function(*x, p2)) == pytest.approx(0.6 - 1.0)


def test_structural_constants_are_not_lifted():
    comp = BodyCompiler()
    f_k = lambda k: FactorInstance("t.w", "r", (), frozenset(), 0, 1, (), (TR,),
                                   (Constraint(C("waypoint", Slot(0), Num(k)), "==", Num(0.0)),))
    cb0, _ = comp.compile(f_k(0))
    cb1, _ = comp.compile(f_k(1))
    assert cb0 is not cb1 and comp.compiled == 2


@pytest.mark.parametrize("expr", [
    C("nosuch", s), C("add", s), C("cross", v, w), C("add", v, w), C("waypoint", v, Num(0)),
    Index(v, Num(5)), C("sdist2", Obj("a"), p, Str("x"), pb), C("fk", Obj("arm2"), j, Num(1), P),
    Obj("a"),
])
def test_malformed_bodies_raise_user_errors(expr):
    f = FactorInstance("t.bad", "r", (), frozenset(), 0, 1, (), tuple(ALL),
                       (Constraint(expr, "==", Num(0.0)),))
    with pytest.raises(UserError):
        BodyCompiler(GEOM).compile(f)


def test_geometry_required_for_primitives():
    f = FactorInstance("t.g", "r", (), frozenset(), 0, 1, (), tuple(ALL),
                       (Constraint(CASES["sdist2"], ">=", Num(0.0)),))
    with pytest.raises(BodyError, match="geometry"):
        BodyCompiler(None).compile(f)
