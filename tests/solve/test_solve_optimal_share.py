"""The optimisation phase's feasibility threshold per run (`solve.optimal`): a run whose point a
repair (`polish`) follows keeps iterates within FEASIBLE_SHARE x the tolerance (ipopt reaches the
optimum's cost long before its rows are below 1e-7); a run without a repair keeps only iterates
the independent re-check passes. The optimiser, the objective and the re-check are stubs here:
what is tested is what the phase asks of them and what it accepts."""
from __future__ import annotations

from types import SimpleNamespace

import numpy as np
import pytest

from gnppdsl.nlp.optimisation import Optimised
from gnppdsl.solve import optimal

TOL = 1e-6


@pytest.fixture
def stubs(monkeypatch):
    calls = []
    v = "x"                         # a variable (any hashable key)
    graph = SimpleNamespace(variables=[v], factor_instances=[])

    def optimise(graph, terms, start, compiler, *, feasible_below, **kw):
        calls.append((dict(start), feasible_below))
        # the optimiser's best iterate: cheaper, its rows violated by 5x the tolerance
        return Optimised({v: np.array([1.0]), "violation": 5 * TOL}, "Objective_Stalled", 40, 0.1)

    monkeypatch.setattr(optimal, "optimise", optimise)
    monkeypatch.setattr(optimal, "objective_value", lambda terms, values, geometry: float(values[v][0]))
    monkeypatch.setattr(optimal, "_violation", lambda graph, values, geometry: values.get("violation", 0.0))
    return graph, v, calls


def test_a_repaired_run_keeps_iterates_within_ten_tolerances(stubs):
    graph, v, calls = stubs
    polished = []

    def polish(point):
        polished.append(point)
        return {v: np.array([1.01]), "violation": 0.0}

    out = optimal.optimisation_phase(graph, [object()], {v: np.array([3.0])}, None, None, TOL, 10.0, polish)
    assert calls[0][1] == pytest.approx(optimal.FEASIBLE_SHARE * TOL) and optimal.FEASIBLE_SHARE * TOL > 5 * TOL
    assert polished and out.accepted and out.cost == pytest.approx(1.01)


def test_a_run_without_repair_keeps_only_iterates_the_recheck_passes(stubs):
    graph, v, calls = stubs
    out = optimal.optimisation_phase(graph, [object()], {v: np.array([3.0])}, None, None, TOL, 10.0, None,
                                     previous={v: np.array([2.0])})
    assert [fb for _, fb in calls] and all(fb == pytest.approx(optimal.STRICT_SHARE * TOL) for _, fb in calls)
    assert optimal.STRICT_SHARE * TOL <= TOL
    assert not out.accepted          # the stub's 5x-tolerance point is not repaired, so not taken
