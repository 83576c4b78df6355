"""Lifted PDDL (`gnppdsl.compile.pddl_lifted`) on every bundled problem, with two planners that
share no code with us as oracles:
- Fast Downward's translator + A* (blind) on the lifted PDDL finds the same optimal plan length
  as FD on our `.sas` (and both match examples/*/expected.yaml), with derived predicates kept
  and inlined; FD's plan, mapped back to our action names, is valid for our SAS+ task;
- Unified Planning's `PDDLReader` reads it (inlined derived predicates: UP 1.3 has none);
  where UP's optimal FD engine supports the problem's features it finds the same length, else
  UP's plan validator accepts the optimal `.sas` plan and UP's satisficing plan is valid for us.
"""
from __future__ import annotations

import re
import warnings

import pytest

from fd_oracle import run_fd_on_sas, translate_pddl
from test_compile_examples import _cases, _load

from gnppdsl.compile.pddl_lifted import write_lifted_pddl
from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.task import build_task
from gnppdsl.logic.validate import validate_plan


def _ops(task, plan: list[str]) -> list[int]:
    """FD / UP plan lines `pick b1 g s1` or `pick(b1, g, s1)` -> our operator indices."""
    index = {tuple(re.sub(r"[(),]", " ", op.name).split()): k for k, op in enumerate(task.operators)}
    return [index[tuple(re.sub(r"[(),]", " ", a).lower().split())] for a in plan]


@pytest.mark.parametrize("path,n0", _cases())
@pytest.mark.parametrize("derived", ["keep", "inline"])
def test_fd_on_lifted_pddl_finds_the_sas_optimum(path, n0, derived):
    problem = _load(path)
    task = build_task(problem)
    ref = run_fd_on_sas(write_sas(task))
    out = write_lifted_pddl(problem, derived)
    assert ("(:derived" in out.domain) == (derived == "keep" and bool(problem.domain.derived))
    assert (":derived-predicates" in out.domain) == ("(:derived" in out.domain)
    assert ":parameters ()" not in out.domain or not problem.domain.actions   # lifted
    res = run_fd_on_sas(translate_pddl(out.domain, out.problem))
    assert res.solved == ref.solved
    assert res.cost == ref.cost == n0
    assert validate_plan(task, _ops(task, res.plan)).valid


def _up():
    pytest.importorskip("unified_planning")
    from unified_planning.shortcuts import get_environment
    get_environment().credits_stream = None


@pytest.mark.parametrize("path,n0", _cases())
def test_unified_planning_reads_and_agrees(path, n0):
    _up()
    from unified_planning.engines import PlanGenerationResultStatus as S
    from unified_planning.io import PDDLReader
    from unified_planning.plans import ActionInstance, SequentialPlan
    from unified_planning.shortcuts import OneshotPlanner, PlanValidator

    problem = _load(path)
    task = build_task(problem)
    out = write_lifted_pddl(problem, "inline")
    up_problem = PDDLReader().parse_problem_string(out.domain, out.problem)
    assert {a.name for a in up_problem.actions} == set(out.action_names)
    ref = run_fd_on_sas(write_sas(task))
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        with OneshotPlanner(name="fast-downward-opt") as planner:
            opt = planner.solve(up_problem) if planner.supports(up_problem.kind) else None
        if opt is not None:
            assert opt.status == S.SOLVED_OPTIMALLY and len(opt.plan.actions) == ref.cost == n0
        else:
            # UP's own semantics accept our optimal plan ...
            acts = []
            for line in ref.plan:
                name, *args = re.sub(r"[(),]", " ", task.operators[_ops(task, [line])[0]].name).split()
                acts.append(ActionInstance(up_problem.action(out_pddl_name(out, name)),
                                           [up_problem.object(a) for a in args]))
            with PlanValidator(problem_kind=up_problem.kind) as validator:
                assert validator.validate(up_problem, SequentialPlan(acts)).status.name == "VALID"
            # ... and UP's satisficing plan is valid for our task
            with OneshotPlanner(name="fast-downward") as planner:
                sat = planner.solve(up_problem)
            plan = [f"{a.action.name} {' '.join(str(p) for p in a.actual_parameters)}" for a in sat.plan.actions]
            assert len(plan) >= n0 and validate_plan(task, _ops(task, plan)).valid


def out_pddl_name(out, action: str) -> str:
    return next(k for k, v in out.action_names.items() if v == action)
