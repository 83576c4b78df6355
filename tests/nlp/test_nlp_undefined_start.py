"""A run that ends where a row is undefined (NaN) is a failed start, not the end of the solve.

Measured (field5 seed 0 of 709ab9a): ipopt stopped at a point where a distance row was NaN (a
coal query that failed there, `tests/geometry/test_geometry_coal_failure.py`); the NLP had one
start (restarts=0), so the solve raised "solver fault" and the whole run ended. Now up to
`UNDEFINED_RESTARTS` more starts run first; the fault stands only when they end undefined too.
"""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.errors import NumericalFault
from gnppdsl.ir.expr import Constraint, Index, Num, Slot
from gnppdsl.nlp import feasibility
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import C, factor, pose


def sqrt_graph():
    """sqrt(x) >= 0.5 of one planar pose: NaN wherever x < 0."""
    v = pose("b", 0)
    body = [Constraint(C("sqrt", Index(C("pos_se2", Slot(0)), Num(0))), ">=", Num(0.5))]
    return v, GraphNLP([factor("toy.sqrt", [v], body, 0)])


def undefined_runs(monkeypatch, n: int | None):
    """`_run` whose first n runs (None: all) end at x = -1 (the row NaN there), as ipopt did."""
    real, calls = FeasibilitySolver._run, []

    def run(self, a, x0, rho, warm=None, limit=0):
        calls.append(x0.copy())
        if n is None or len(calls) <= n:
            x = np.array(x0, float)
            x[0] = -1.0
            return x, 0.0, 3, "Invalid_Number_Detected", None
        return real(self, a, x0, rho, warm, limit)
    monkeypatch.setattr(FeasibilitySolver, "_run", run)
    return calls


def test_an_undefined_point_is_a_failed_start(monkeypatch):
    v, g = sqrt_graph()
    calls = undefined_runs(monkeypatch, 1)
    res = FeasibilitySolver(None, SolverOptions(restarts=0)).solve(g, initial_guess={v: np.array([1.0, 0.0, 0.0])})
    assert res is not None and res.feasible
    assert res.values[v][0] >= 0.25 - 1e-6
    assert len(calls) == 2                      # the added start, from another point
    assert not np.array_equal(calls[0], calls[1])


def test_undefined_from_every_start_is_still_a_fault(monkeypatch):
    _, g = sqrt_graph()
    calls = undefined_runs(monkeypatch, None)
    with pytest.raises(NumericalFault, match="toy.sqrt"):
        FeasibilitySolver(None, SolverOptions(restarts=0)).solve(g)
    assert len(calls) == 1 + feasibility.UNDEFINED_RESTARTS
