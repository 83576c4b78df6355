"""`always -> always`: a transition rule with empty partial states, at every i -> i+1."""
from __future__ import annotations

import shutil
from pathlib import Path

from gnppdsl.compile.factory import GraphNLPFactory
from gnppdsl.compile.sas import PartialState
from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"


def test_always_transition_rule_applies_at_every_step_with_empty_generators(tmp_path):
    for f in ("domain.pntc", "p3_occupied.pntc", "p3_occupied.yaml"):
        shutil.copy(PLANAR / f, tmp_path / f)
    with open(tmp_path / "domain.pntc", "a") as fh:
        fh.write("\nrule steady(g: gripper) : always -> always => planar.same(q(g), q(g)')\n")
    problem = load_problem(tmp_path / "p3_occupied.pntc")
    (rule,) = [r for r in problem.domain.rules if r.name == "steady"]
    assert (rule.kind, rule.pre, rule.post) == ("transition", (), ())
    task = build_task(problem)
    plan = "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)"
    states = plan_states(task, parse_plan(task, plan))
    steady = [f for f in GraphNLPFactory(problem, task).factors(states) if f.rule == "steady"]
    assert [f.step for f in steady] == [0, 1, 2, 3]          # every transition, none after s_4
    empty = PartialState.of([])
    for f in steady:
        assert f.span == 2 and f.generator == (empty, empty)
        assert [(v.key, v.step) for v in f.variables] == [("q(g)", f.step), ("q(g)", f.step + 1)]
