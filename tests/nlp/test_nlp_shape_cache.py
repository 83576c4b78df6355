"""Graph-NLPs of one structure share one assembled NLP (`gnppdsl.nlp.shape_cache`): the shared
assembly must carry the second graph's own numbers (lifted constants, bounds, factor rows) and
solve it exactly as a fresh assembly of that graph does (the oracle: a solver with its own
compiler, which cannot share anything)."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import coal_boxes

import coal  # noqa: E402,F401  (a dependency of the package: never a skip)


def _start(g: GraphNLP) -> dict:
    # the boxes start overlapping, so ipopt has to move them
    return {v: np.array([0.1 * i, 0.05 * i, 0.2 * i]) for i, v in enumerate(g.variables)}


def _pair(c1: float, c2: float, n: int = 3):
    geo, fa = coal_boxes(n, c1)
    _, fb = coal_boxes(n, c2)                     # the same structure, another region size
    return geo, GraphNLP(fa, name="A"), GraphNLP(fb, name="B")


def test_same_structure_shares_the_assembly_and_solves_like_a_fresh_one():
    geo, ga, gb = _pair(1.0, 0.55)
    opts = SolverOptions(restarts=0)
    first = FeasibilitySolver(geo, opts)
    first.solve(ga, warm_start=_start(ga))
    second = FeasibilitySolver(geo, SolverOptions(restarts=0), compiler=first.compiler)
    shared = second.assemble(gb)
    assert shared.root is not None and shared.solver is first.assemble(ga).solver
    fresh_solver = FeasibilitySolver(geo, SolverOptions(restarts=0))      # its own compiler
    fresh = fresh_solver.assemble(gb)
    assert fresh.root is None
    np.testing.assert_array_equal(shared.params, fresh.params)
    assert not np.array_equal(shared.params, first.assemble(ga).params)   # B's own numbers
    assert shared.factor_rows == fresh.factor_rows
    np.testing.assert_array_equal(shared.lbx, fresh.lbx)
    np.testing.assert_array_equal(shared.ubx, fresh.ubx)
    r_shared = second.solve(gb, warm_start=_start(gb))
    r_fresh = fresh_solver.solve(gb, warm_start=_start(gb))
    assert r_shared.feasible == r_fresh.feasible
    assert r_shared.iterations == r_fresh.iterations
    for v in gb.variables:
        np.testing.assert_allclose(r_shared.values[v], r_fresh.values[v], atol=1e-9)
    # B's region (|x|, |y| <= 0.55) is what was solved, not A's (1.0)
    assert all(np.max(np.abs(r_shared.values[v][:2])) <= 0.55 + 1e-6 for v in gb.variables)


def test_another_structure_is_assembled_anew():
    geo, ga, _ = _pair(1.0, 1.0)
    _, f2 = coal_boxes(2, 1.0)
    s = FeasibilitySolver(geo, SolverOptions(restarts=0))
    s.assemble(ga)
    other = FeasibilitySolver(geo, SolverOptions(restarts=0), compiler=s.compiler)
    assert other.assemble(GraphNLP(f2)).root is None


def test_a_wall_time_the_shared_nlp_cannot_enforce_is_not_shared():
    geo, ga, gb = _pair(1.0, 0.8)
    s = FeasibilitySolver(geo, SolverOptions(restarts=0))           # no wall time
    s.assemble(ga)
    in_loop = FeasibilitySolver(geo, SolverOptions(restarts=0, time_limit=5.0), compiler=s.compiler)
    in_loop.deadline = 1e18                         # a solve loop's deadline: the monitor stops it
    assert in_loop.assemble(gb).root is not None
    alone = FeasibilitySolver(geo, SolverOptions(restarts=0, time_limit=5.0), compiler=s.compiler)
    assert alone.assemble(gb).root is None          # no deadline for the monitor to enforce it
