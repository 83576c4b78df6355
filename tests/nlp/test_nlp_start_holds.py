"""A first run whose start already holds (every row and unit quaternion within 0.1 tolerance)
is decided at the start without running ipopt (`IterationMonitor.start_holds`): ipopt's
iteration monitor would stop such a run at iteration 0, so its answer is the start, and the
run was all set-up (~8 ms on `bench_komo.py`'s path NLPs whose straight line holds). Checked:
the start comes back unchanged, feasible, with no ipopt run; a start that misses by more than
the monitor's threshold still runs; without a monitor (early_stop off) ipopt runs as before."""
from __future__ import annotations

import numpy as np

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.monitor import START_HELD

from nlp_toys import ARM_GEOM, arm_reach_graph


def _solved():
    g = arm_reach_graph()
    first = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=1, assembly="MX")).solve(g, seed=1)
    assert first.feasible
    return g, first.values


def _polished(g, values):
    """`values` moved to where every row holds within 1e-9 (a tight re-solve)."""
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX", tolerance=1e-9))
    r = s.solve(g, warm_start=values, seed=1)
    worst, _ = max_violation(g.factor_instances, r.values, ARM_GEOM)
    assert worst <= 1e-8
    return r.values


def test_a_start_that_holds_is_returned_without_an_ipopt_run():
    g, values = _solved()
    start = _polished(g, values)
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX"))
    r = s.solve(g, warm_start=start, seed=1)
    assert r.feasible and r.iterations == 0 and r.status == START_HELD
    assert s.solves == 0                                   # no ipopt run
    for v, x in start.items():
        assert np.array_equal(r.values[v], np.asarray(x, float))


def test_a_start_that_misses_the_threshold_still_runs():
    g, values = _solved()
    start = {v: x + 1e-3 for v, x in _polished(g, values).items()}
    worst0, _ = max_violation(g.factor_instances, start, ARM_GEOM)
    assert worst0 > 1e-7                                   # above 0.1 * tolerance
    # (without the Gauss-Newton steps of a near start, test_nlp_projected_start.py)
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX", gauss_newton_steps=0))
    r = s.solve(g, warm_start=start, seed=1)
    assert r.feasible and r.status != START_HELD and s.solves >= 1


def test_without_a_monitor_ipopt_runs():
    g, values = _solved()
    start = _polished(g, values)
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX", early_stop=False))
    r = s.solve(g, warm_start=start, seed=1)
    assert r.feasible and r.status != START_HELD and s.solves == 1
