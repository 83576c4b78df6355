"""The rows h(x) of an assembled NLP are evaluated once per point (`_Assembled.rows`): a run
that returns its start (`START_HELD`) takes its verdict from the rows its start check just
evaluated, not from a second evaluation; another point, or the same point with other numbers
(another graph of the same structure), evaluates again. The parameter vectors handed to
casadi are kept as DMs per assembly (`params_dm`, `p_dm`): the solver's buffer carries each
run's start and pull, and an assembly with other numbers makes its own."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.monitor import START_HELD

from nlp_toys import ARM_GEOM, arm_reach_graph
from test_nlp_start_holds import _polished, _solved


class _Counting:
    """A stand-in for `h_fun` that counts its calls."""

    def __init__(self, f):
        self.f, self.calls = f, 0

    def __call__(self, *args):
        self.calls += 1
        return self.f(*args)


def test_a_held_start_evaluates_its_rows_once():
    g, values = _solved()
    start = _polished(g, values)
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX"))
    a = s.assemble(g)
    counting = _Counting(a.h_fun)
    a.h_fun = counting
    r = s.solve(g, warm_start=start, seed=1)
    assert r.status == START_HELD and r.feasible
    assert counting.calls == 1                  # the start check's rows served the verdict


def test_rows_are_evaluated_again_at_another_point_or_with_other_numbers():
    g = arm_reach_graph()
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX"))
    a = s.assemble(g)
    counting = _Counting(a.h_fun)
    a.h_fun = counting
    x = np.linspace(0.1, 0.9, a.n_x)
    h1 = a.rows(x)
    assert np.array_equal(a.rows(x.copy()), h1) and counting.calls == 1
    with np.testing.assert_raises(ValueError):
        h1[0] = 0.0                             # read-only: the memo cannot be changed
    h2 = a.rows(x + 0.01)
    assert counting.calls == 2 and not np.array_equal(h1, h2)
    fresh = np.asarray(a.h_fun.f(x, a.params)).reshape(-1)
    np.testing.assert_array_equal(a.rows(x), fresh)
    # other numbers (a graph of the same structure, `shape_cache`): evaluated with its own
    other = replace(a, params=a.params + 1e-3)
    assert not np.array_equal(np.asarray(other.params_dm()).reshape(-1), np.asarray(a.params_dm()).reshape(-1))
    other.rows(x)
    assert counting.calls == 4


def test_the_solver_parameter_buffer_carries_each_runs_start_and_pull():
    g = arm_reach_graph()
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX"))
    a = s.assemble(g)
    for k, rho in enumerate((1e-2, 1e-6)):
        x0 = np.full(a.n_x, 0.1 * (k + 1))
        p = np.asarray(a.p_dm(x0, rho)).reshape(-1)
        np.testing.assert_array_equal(p, np.concatenate([x0, a.params, [rho]]))
    other = replace(a, params=a.params + 1.0)
    p = np.asarray(other.p_dm(np.zeros(a.n_x), 0.5)).reshape(-1)
    np.testing.assert_array_equal(p, np.concatenate([np.zeros(a.n_x), a.params + 1.0, [0.5]]))
