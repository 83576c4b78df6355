"""`evaluate.factor_margins`: per factor its largest row, signed (h for inequalities, |h| for
equalities), which tells how far a factor that holds is from becoming active -- what collision
screening (`gnppdsl.solve.screening`) selects by; `max_violation` says 0 for all of them."""
from __future__ import annotations

import math

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.ir.expr import Constraint, Num, Slot
from gnppdsl.nlp.evaluate import factor_margins, max_violation

X = VarInstance("pose", ("b1",), 0, "R", 1, frozenset({"object"}))
Y = VarInstance("pose", ("b2",), 0, "R", 1, frozenset({"object"}))


def _factor(name: str, variables, *body) -> FactorInstance:
    return FactorInstance(f"t.{name}", name, (), frozenset({"collision"}), 0, 1, (PartialState(),),
                          tuple(variables), tuple(body))


def test_margins_are_signed_where_violations_are_zero():
    below = _factor("below", [X], Constraint(Slot(0), "<=", Num(1.0)))            # x <= 1
    above = _factor("above", [X, Y], Constraint(Slot(1), ">=", Slot(0)))          # y >= x
    both = _factor("both", [X], Constraint(Slot(0), "<=", Num(1.0)), Constraint(Slot(0), ">=", Num(-2.0)))
    equal = _factor("equal", [X, Y], Constraint(Slot(0), "==", Slot(1)))
    values = {X: np.array([0.25]), Y: np.array([0.75])}
    m = factor_margins([below, above, both, equal], values)
    assert np.allclose(m, [-0.75, -0.5, -0.75, 0.5])
    # the violation of the three inequality factors is 0: it cannot rank them
    for f in (below, above, both):
        assert max_violation([f], values)[0] == 0.0
    # a violated inequality has a positive margin equal to its violation
    values[X] = np.array([1.5])
    m = factor_margins([below, above], values)
    assert np.allclose(m, [0.5, 0.75])
    assert math.isclose(max_violation([below], values)[0], 0.5)
