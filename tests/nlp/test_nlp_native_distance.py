"""A graph-NLP solved with the native distance queries takes the same path as with the Python
callback: same verdict, same iterations, same point (boxes: identical coal shapes on both
sides, so the answers are the same numbers), and the solution holds under coal directly."""
from __future__ import annotations

import numpy as np
import pytest

import coal  # noqa: E402,F401  (a dependency of the package: never a skip)
from gnppdsl.geometry.context import GeometryContext  # noqa: E402
from gnppdsl.nlp.evaluate import max_violation  # noqa: E402
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions  # noqa: E402
from gnppdsl.nlp.graph import GraphNLP  # noqa: E402

from nlp_toys import coal_boxes  # noqa: E402



@pytest.mark.parametrize("c", [0.5, 0.25])      # feasible (room for 4 boxes) and infeasible
def test_native_and_python_distances_give_the_same_solve(c, monkeypatch, native_library):
    results = []
    for use_native in (True, False):
        geo, fs = coal_boxes(4, c)
        if not use_native:
            monkeypatch.setattr(GeometryContext, "witness_fast",
                                lambda self, a, b, planar=False: self._callback(a, b, planar))
        solver = FeasibilitySolver(geo, SolverOptions(restarts=1))
        res = solver.solve(GraphNLP(fs), seed=3)
        results.append((res, fs, geo))
    (r1, fs1, geo1), (r2, fs2, geo2) = results
    assert r1.feasible == r2.feasible
    assert r1.iterations == r2.iterations
    v1 = np.concatenate([r1.values[v] for v in sorted(r1.values, key=str)])
    v2 = np.concatenate([r2.values[v] for v in sorted(r2.values, key=str)])
    np.testing.assert_allclose(v1, v2, rtol=0, atol=1e-9)
    if r1.feasible:
        assert max_violation(fs1, r1.values, geo1)[0] <= 1e-6        # coal directly
    else:
        assert c == 0.25
