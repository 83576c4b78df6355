"""The numpy evaluator's broadphase (issue 19): a row `sdist(a, b) >= c` whose bound from two
balls about the bodies' frames is far below the threshold of the question is not computed.
`max_violation` returns the same number as computing every distance; `factor_margins(floor=)`
is exact above the floor and at most the floor (never below the true margin) under it."""
from __future__ import annotations

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Call, Constraint, Num, Obj, Slot
from gnppdsl.nlp.evaluate import constraint_rows, factor_margins, max_violation


class _Box:
    def __init__(self, half: float):
        self.half = half

    def local_box(self):
        return np.zeros(3), np.full(3, self.half)


class _Cubes:
    """A toy 3-D geometry: bodies are balls of radius r at a pose's position (boxes of half
    side r hold them); counts the distances computed."""

    def __init__(self, r: float = 0.1):
        self.r, self.calls = r, 0

    def body(self, body):
        return _Box(self.r)

    def sdist_numeric(self, a, pa, b, pb):
        self.calls += 1
        return float(np.linalg.norm(np.asarray(pa[:3]) - np.asarray(pb[:3])) - 2 * self.r)


def _pose(name: str) -> VarInstance:
    return VarInstance("pose", (name,), 0, "SE3", 7)


def _clear(p: VarInstance, q: VarInstance, c: float = 0.01) -> FactorInstance:
    body = (Constraint(Call("sdist", (Obj(p.args[0]), Slot(0), Obj(q.args[0]), Slot(1))), ">=", Num(c)),)
    return FactorInstance("toy.clear", "clear", (), frozenset({"collision"}), 0, 1, (), (p, q), body)


def _at(x: float) -> np.ndarray:
    return np.array([x, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0])


def _scene():
    a, near, far, inside = _pose("a"), _pose("near"), _pose("far"), _pose("inside")
    values = {a: _at(0.0), near: _at(0.23), far: _at(2.0), inside: _at(0.15)}
    return [_clear(a, near), _clear(a, far), _clear(a, inside)], values


def test_margins_exact_above_the_floor_bounded_below_it():
    factors, values = _scene()
    exact = factor_margins(factors, values, _Cubes())
    assert np.allclose(exact, [0.01 - 0.03, 0.01 - 1.8, 0.01 + 0.05])
    geo = _Cubes()
    m = factor_margins(factors, values, geo, floor=-0.05)
    assert m[0] == exact[0] and m[2] == exact[2]          # near and colliding: exact
    assert exact[1] <= m[1] <= -0.05                        # far: a bound, below the floor
    assert geo.calls == 2                                   # the far distance was not computed
    # without a floor every distance is computed and the rows are exact
    geo = _Cubes()
    assert factor_margins(factors, values, geo) == exact and geo.calls == 3


def test_max_violation_is_the_same_number_with_fewer_distances():
    factors, values = _scene()
    geo = _Cubes()
    worst, arg = max_violation(factors, values, geo)
    assert np.isclose(worst, 0.06) and arg is factors[2]
    assert geo.calls == 2
    # a bounded result is not remembered as the factor's rows: asked for its rows, the far
    # factor computes its distance
    rows = constraint_rows(factors[1], values, geo)
    assert geo.calls == 3 and np.isclose(rows[0][1], 0.01 - 1.8)
    held = {v: x for v, x in values.items()}
    assert max_violation(factors[:2], held, _Cubes()) == (0.0, factors[0])


def test_a_row_that_reads_the_distance_otherwise_is_computed():
    """`sdist <= c` (the row grows with the distance) and a distance read by two rows are
    never bounded: only `c - sdist` rows whose distance nothing else reads."""
    a, b = _pose("a"), _pose("b")
    s = Call("sdist", (Obj("a"), Slot(0), Obj("b"), Slot(1)))
    touch = FactorInstance("toy.touch", "touch", (), frozenset(), 0, 1, (), (a, b),
                           (Constraint(s, "<=", Num(5.0)),))
    twice = FactorInstance("toy.twice", "twice", (), frozenset(), 0, 1, (), (a, b),
                           (Constraint(s, ">=", Num(0.0)), Constraint(s, "<=", Num(5.0))))
    values = {a: _at(0.0), b: _at(3.0)}
    for f in (touch, twice):
        geo = _Cubes()
        assert max_violation([f], values, geo)[0] == 0.0 and geo.calls == 1
        geo = _Cubes()
        assert factor_margins([f], values, geo, floor=-0.05) == factor_margins([f], values, _Cubes())
        assert geo.calls == 1


def test_bounded_rows_are_remembered_for_thresholds_not_below_theirs():
    factors, values = _scene()
    geo = _Cubes()
    first = factor_margins(factors, values, geo, floor=-0.05)
    assert geo.calls == 2
    # asked again (the same input, the same or a higher threshold): nothing computed again
    assert factor_margins(factors, values, geo, floor=-0.05) == first and geo.calls == 2
    assert max_violation(factors, values, geo)[0] == max_violation(factors, values, _Cubes())[0]
    assert geo.calls == 2
    # a lower floor than the remembered bound's threshold: the far distance is computed
    deep = factor_margins(factors, values, geo, floor=-5.0)
    assert geo.calls == 3 and np.isclose(deep[1], 0.01 - 1.8)
