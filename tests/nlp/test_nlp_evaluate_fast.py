"""The compiled numpy evaluator (`gnppdsl.nlp.evaluate`) against two references.

1. The plain tree walk (`tests/nlp/evaluate_reference.py`, `_reference_rows`, with its own numeric
   kernels: it imports nothing from the evaluator): the compiled steps share nodes across rows and
   factors, fold constants, and remember a factor's rows at recent inputs; none of that may change
   any row beyond rounding (relative 1e-10; the kernels differ, so not bit for bit), on real graph-NLPs of the bundled examples
   (planar blocks, the Lab with Panda arms and trajectories, a mobile manipulator) at random
   points.
2. The casadi path (`body_compiler.BodyCompiler`, quaternion algebra instead of rotation
   matrices) on the planar and Lab graphs: the same rows up to rounding.

Also: errors still come out as `EvaluationError`, and the memos never answer for other values,
another geometry or another factor.
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Str, Vec
from gnppdsl.nlp import evaluate
from gnppdsl.nlp.evaluate import EvaluationError, constraint_rows, factor_violation, max_violation

from evaluate_reference import _reference_rows

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = {
    "planar_p3": ROOT / "examples" / "planar" / "p3_occupied.pntc",
    "planar_p5": ROOT / "examples" / "planar" / "p5_handover.pntc",
    "lab1": ROOT / "examples" / "lab" / "lab1.pntc",
    "mobile": ROOT / "examples" / "mobile" / "pick_place.pntc",
}
_GRAPHS: dict[str, tuple] = {}


def graph(name: str):
    """(compiled problem, factors, variables, initial guess) of the first plan of an example."""
    if name not in _GRAPHS:
        path = EXAMPLES[name]
        from gnppdsl.logic.planner import IncrementalPlanner
        from gnppdsl.solve.compiled import load_and_compile

        c = load_and_compile(str(path))
        res = IncrementalPlanner(c.task).next_plan(max_horizon=8)
        assert res.found, name
        fac = c.factory
        factors = fac.factors(res.plan.states)
        variables = fac.variables(res.plan.states)
        guess = {v: np.asarray(g, float) for v in variables if (g := fac.initial_guess(v)) is not None}
        _GRAPHS[name] = (c, factors, variables, guess)
    return _GRAPHS[name]


def random_point(variables, guess, rng, scale):
    """The initial guess (zeros where there is none) moved by Gaussian noise."""
    out = {}
    for v in variables:
        base = guess.get(v, np.zeros(v.dim))
        out[v] = np.asarray(base, float).reshape(-1) + scale * rng.standard_normal(v.dim)
    return out


def reference_violation(rows) -> float:
    worst = 0.0
    for kind, h in rows:
        v = abs(h) if kind == "eq" else max(h, 0.0)
        if math.isnan(v):
            return math.inf
        worst = max(worst, v)
    return worst


def same_bits(a: float, b: float) -> bool:
    """Equal to rounding: the reference's kernels are written independently (relative 1e-10)."""
    if math.isnan(a) or math.isnan(b):
        return math.isnan(a) and math.isnan(b)
    if math.isinf(a) or math.isinf(b):
        return a == b
    return abs(a - b) <= 1e-10 * max(1.0, abs(a), abs(b))


def same_rows(got, want) -> bool:
    return len(got) == len(want) and all(k == k2 and same_bits(a, b) for (k, a), (k2, b) in zip(got, want))


@pytest.mark.parametrize("name", list(EXAMPLES))
def test_rows_are_those_of_the_tree_walk(name):
    c, factors, variables, guess = graph(name)
    rng = np.random.default_rng(7)
    rows_seen = 0
    for scale in (0.0, 0.05, 0.5):
        x = random_point(variables, guess, rng, scale)
        # graph-level call first (nodes shared across factors), then factor by factor
        worst, arg = max_violation(factors, x, c.geometry)
        ref = [reference_violation(_reference_rows(f, x, c.geometry)) for f in factors]
        expected = max(ref)
        assert same_bits(worst, expected)
        assert same_bits(ref[factors.index(arg)], expected)
        for f in factors:
            got, want = constraint_rows(f, x, c.geometry), _reference_rows(f, x, c.geometry)
            assert [k for k, _ in got] == [k for k, _ in want], f.label
            bad = [(i, a, b) for i, ((_, a), (_, b)) in enumerate(zip(got, want)) if not same_bits(a, b)]
            assert not bad, (f.label, bad[:3])
            assert same_bits(factor_violation(f, x, c.geometry), reference_violation(want)), f.label
            rows_seen += len(want)
    assert rows_seen > 0
    print(f"{name}: {len(factors)} factors, {rows_seen} rows compared")


@pytest.mark.parametrize("name", ["planar_p3", "lab1"])
def test_rows_agree_with_the_casadi_path(name):
    """An independent implementation (quaternion algebra, casadi geometry callbacks)."""
    from gnppdsl.nlp.body_compiler import BodyCompiler

    c, factors, variables, guess = graph(name)
    comp = BodyCompiler(c.geometry)
    rng = np.random.default_rng(3)
    x = random_point(variables, guess, rng, 0.05)
    for v in variables:                 # unit quaternions: the two paths normalise differently
        if v.space == "SE3" and not v.waypoints:
            x[v][3:7] /= np.linalg.norm(x[v][3:7])
    for f in factors:
        cb, params = comp.compile(f)
        h = np.asarray(cb.function(*[x[v] for v in f.variables], params), float).reshape(-1)
        rows = constraint_rows(f, x, c.geometry)
        assert [k for k, _ in rows] == list(cb.kinds), f.label
        ours = np.array([v for _, v in rows])
        assert np.allclose(ours, h, rtol=1e-9, atol=1e-9), (f.label, np.max(np.abs(ours - h)))


def test_sharing_and_memo_never_answer_for_other_inputs():
    """Subsets, other orders, changed values, arrays changed in place: the tree walk's rows."""
    c, factors, variables, guess = graph("lab1")
    rng = np.random.default_rng(11)
    x1 = random_point(variables, guess, rng, 0.1)
    x2 = dict(x1)
    moved = next(v for v in variables if v.kind == "path") if any(v.kind == "path" for v in variables) \
        else variables[0]
    x2[moved] = x1[moved] + 0.01
    for x in (x1, x2, x1, x2):
        for subset in (factors, factors[::-1], factors[::3]):
            worst, _ = max_violation(subset, x, c.geometry)
            assert same_bits(worst, max(reference_violation(_reference_rows(f, x, c.geometry))
                                        for f in subset))
    # in-place change of the caller's array after a call: the memo is keyed by the bytes
    f = next(f for f in factors if moved in f.variables)
    x3 = {v: a.copy() for v, a in x1.items()}
    before = constraint_rows(f, x3, c.geometry)
    x3[moved] += 0.02
    after = constraint_rows(f, x3, c.geometry)
    assert same_rows(after, _reference_rows(f, x3, c.geometry)) and same_rows(before, _reference_rows(f, x1, c.geometry))
    assert not same_rows(after, before)


class _Disc:
    """A toy geometry: discs of radius r at the first two coordinates of a pose."""

    def __init__(self, r: float):
        self.r, self.calls = r, 0

    def sdist2_numeric(self, a, pa, b, pb):
        self.calls += 1
        return float(np.hypot(pa[0] - pb[0], pa[1] - pb[1]) - 2 * self.r)


def _apart_factor(p, q):
    body = (Constraint(Call("sdist2", (Obj("a"), Slot(0), Obj("b"), Slot(1))), ">=", Num(0.0)),)
    return FactorInstance("toy.apart", "apart", (), frozenset(), 0, 1, (), (p, q), body)


def test_results_follow_the_geometry_object():
    p = VarInstance("pose", ("a",), 0, "SE2", 3)
    q = VarInstance("pose", ("b",), 0, "SE2", 3)
    f = _apart_factor(p, q)
    x = {p: np.zeros(3), q: np.array([1.0, 0.0, 0.0])}
    small, large = _Disc(0.25), _Disc(1.0)
    assert factor_violation(f, x, small) == 0.0
    assert factor_violation(f, x, large) == 1.0
    assert factor_violation(f, x, small) == 0.0 and small.calls == 1     # remembered
    # a structurally equal factor with other variables is its own program
    p1 = VarInstance("pose", ("a",), 1, "SE2", 3)
    g = _apart_factor(p1, q)
    assert max_violation([f, g], {**x, p1: np.array([3.0, 0.0, 0.0])}, large) == (1.0, f)


def _factor(body, variables=None):
    variables = variables or (VarInstance("x", (), 0, "R", 3),)
    return FactorInstance("toy.t", "r", (), frozenset(), 0, 1, (), tuple(variables), tuple(body))


@pytest.mark.parametrize("body,values,message", [
    ([Constraint(Call("no_such_builtin", (Slot(0),)), "==", Num(0.0))], [1.0, 2.0, 3.0], "primitive"),
    ([Constraint(Call("add", (Slot(0), Vec((Num(1.0), Num(2.0))))), "==", Num(0.0))],
     [1.0, 2.0, 3.0], None),                                                       # sizes 3 and 2
    ([Constraint(Call("angle_diff", (Slot(0), Num(0.0))), "==", Num(0.0))], [1.0, 2.0, 3.0], "scalar"),
    ([Constraint(Call("waypoint", (Slot(0), Num(1))), "==", Num(0.0))], [1.0, 2.0, 3.0], "trajectory"),
    ([Constraint(Index(Slot(0), Num(5)), "==", Num(0.0))], [1.0, 2.0, 3.0], None),   # out of range
    ([Constraint(Str("frame"), "==", Num(0.0))], [1.0, 2.0, 3.0], "cannot evaluate"),
    ([Constraint(Slot(1), "==", Num(0.0))], [1.0, 2.0, 3.0], "slot"),
    ([Constraint(Call("fk", (Obj("arm"), Slot(0), Str("tcp"), Vec((Num(0.0),) * 7))), "==", Num(0.0))],
     [1.0, 2.0, 3.0], None),                                                       # no geometry
])
def test_what_cannot_be_evaluated_raises_evaluation_error(body, values, message):
    f = _factor(body)
    x = {f.variables[0]: np.array(values)}
    for call in (lambda: constraint_rows(f, x), lambda: factor_violation(f, x),
                 lambda: max_violation([f], x)):
        with pytest.raises(EvaluationError, match=message):
            call()


def test_a_missing_value_raises_evaluation_error():
    f = _factor([Constraint(Slot(0), "<=", Num(1.0))])
    with pytest.raises(EvaluationError, match="no value"):
        max_violation([f], {})


def test_constant_rows_nan_and_broadcasting_as_the_tree_walk():
    v = VarInstance("x", (), 0, "R", 3)
    body = [Constraint(Num(1.0), "<=", Num(2.0)),                                  # constant row
            Constraint(Call("sqrt", (Call("neg", (Index(Slot(0), Num(0)),)),)), "<=", Num(0.0)),
            Constraint(Call("mul", (Num(2.0), Slot(0))), ">=", Vec((Num(-1.0), Num(0.0), Num(-0.0)))),
            Constraint(Call("norm", (Index(Slot(0), Num(0), Num(2)),)), "==", Num(1.0))]
    f = _factor(body, [v])
    for vals in ([1.0, 2.0, 3.0], [-1.0, 0.0, -0.0]):
        x = {v: np.array(vals)}
        with np.errstate(invalid="ignore"):
            got, want = constraint_rows(f, x), _reference_rows(f, x)
            assert all(k == k2 and same_bits(a, b) for (k, a), (k2, b) in zip(got, want))
            assert len(got) == len(want) == 6
            assert same_bits(factor_violation(f, x), reference_violation(want))
    assert factor_violation(f, {v: np.array([1.0, 2.0, 3.0])}) == math.inf       # sqrt(-1): NaN


def test_the_caches_are_emptied_when_they_grow_too_large(monkeypatch):
    c, factors, variables, guess = graph("planar_p3")
    x = random_point(variables, guess, np.random.default_rng(5), 0.1)
    first = max_violation(factors, x, c.geometry)
    monkeypatch.setattr(evaluate, "_MAX_NODES", 1)
    monkeypatch.setattr(evaluate, "_MAX_HELD", 1)
    table = evaluate._TABLE
    assert evaluate._BODIES
    assert max_violation(factors, x, c.geometry) == first
    assert evaluate._TABLE is not table
    assert max_violation(factors[:1], x, c.geometry) == max_violation(factors[:1], x, c.geometry)
    assert len(evaluate._BODIES) == 1             # emptied before the call, then one body


def test_bodies_equal_up_to_the_sign_of_a_zero_keep_their_own_constants():
    """Num(0.0) == Num(-0.0), but atan2(+-0, -1) = +-pi: each body object is compiled as is."""
    v = VarInstance("x", (), 0, "R", 1)

    def body(zero):
        return [Constraint(Call("atan2", (Num(zero), Slot(0))), "<=", Num(0.0))]

    pos, neg = _factor(body(0.0), [v]), _factor(body(-0.0), [v])
    assert pos.body == neg.body                                   # equal as IR
    x = {v: np.array([-1.0])}
    assert constraint_rows(pos, x) == _reference_rows(pos, x) == [("ineq", math.pi)]
    assert constraint_rows(neg, x) == _reference_rows(neg, x) == [("ineq", -math.pi)]
    assert max_violation([neg, pos], x) == (math.pi, pos)



def test_a_check_of_a_large_graph_keeps_its_compiled_factors_for_the_next_call():
    """A check whose factors build more than 200k nodes of the shared table (stack_32's plan
    graph: ~400k) leaves them compiled for the next check: the table is not emptied, so the
    factors' programs and remembered rows are reused (with 200k, every call after such a check
    compiled every factor again)."""
    body = [Constraint(Call("mul", (Num(2.0), Call("add", (Index(Slot(0), Num(0)), Num(1.0))))), "<=", Num(1e6)),
            Constraint(Call("sub", (Call("mul", (Index(Slot(0), Num(1)), Index(Slot(0), Num(2)))), Num(3.0))),
                       "<=", Num(1e6))]
    variables = [VarInstance("x", (f"o{i}",), 0, "R", 3) for i in range(30_000)]
    factors = [_factor(body, [v]) for v in variables]
    x = {v: np.array([1.0, 2.0, 3.0]) for v in variables}
    evaluate._TABLE = evaluate._Table()
    evaluate._PROGRAMS.clear()
    try:
        first = max_violation(factors, x)
        table = evaluate._TABLE
        assert len(table.op) > 200_000
        programs = [evaluate._program(f) for f in factors[:100]]
        assert max_violation(factors, x) == first
        assert evaluate._TABLE is table
        assert all(evaluate._program(f) is p for f, p in zip(factors[:100], programs))
    finally:                     # the next tests start from an empty table, as after a large solve
        evaluate._TABLE = evaluate._Table()
        evaluate._PROGRAMS.clear()
