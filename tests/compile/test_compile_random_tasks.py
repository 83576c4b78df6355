"""Random SAS+ tasks (conditional effects, stratified axioms with negation, costs): Fast
Downward on our `.sas` (and, for a few, FD's translator on our PDDL) must find exactly the
optimum of a naive uniform-cost search over the same task."""
from __future__ import annotations

from hypothesis import HealthCheck, given, settings

from fd_oracle import require_fd, run_fd_on_sas, translate_pddl
from random_sas import tasks
from sas_semantics import optimal_cost, run_plan

from gnppdsl.compile.pddl import write_pddl
from gnppdsl.compile.sas_writer import write_sas


@settings(max_examples=40, deadline=None, suppress_health_check=list(HealthCheck))
@given(tasks())
def test_fd_optimum_equals_naive_search(task):
    require_fd()
    expected = optimal_cost(task)
    res = run_fd_on_sas(write_sas(task))
    assert res.solved == (expected is not None)
    if expected is not None:
        assert res.cost == expected
        assert task.goal.holds_in(run_plan(task, res.plan)[-1])


@settings(max_examples=6, deadline=None, suppress_health_check=list(HealthCheck))
@given(tasks())
def test_pddl_optimum_equals_naive_search(task):
    require_fd()
    expected = optimal_cost(task)
    out = write_pddl(task)
    try:
        sas = translate_pddl(out.domain, out.problem)
    except AssertionError as exc:
        # FD's translator proves some tasks unsolvable before search (exit 10)
        assert "exit 10" in str(exc) and expected is None
        return
    res = run_fd_on_sas(sas)
    assert res.solved == (expected is not None)
    if expected is not None:
        assert res.cost == expected
