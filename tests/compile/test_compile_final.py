"""`: final => ...` rules: they apply at the plan's last state only, which the compiler makes the
state after one compiled `final()` step (cost 0, the goal as its precondition; nothing after it).

Oracles: the naive SAS+ search of tests/compile/sas_semantics.py (the optimum is unchanged, every
plan ends with `final()`), Fast Downward on the `.sas`, and the factory's factors checked
against the plan's step count.
"""
from __future__ import annotations

import shutil
from pathlib import Path

from fd_oracle import run_fd_on_sas
from sas_semantics import initial, optimal_cost, run_plan, successor

from gnppdsl.compile.factory import GraphNLPFactory
from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
RULE = "\nrule back(g: gripper) : final => planar.ref(q(g), home(g)) tags robot\n"


def _problem(tmp_path, rule: str = RULE):
    for f in ("domain.pntc", "p3_occupied.pntc", "p3_occupied.yaml"):
        shutil.copy(PLANAR / f, tmp_path / f)
    with open(tmp_path / "domain.pntc", "a") as fh:
        fh.write(rule)
    return load_problem(tmp_path / "p3_occupied.pntc")


def test_final_rule_applies_at_the_last_step_only(tmp_path):
    problem = _problem(tmp_path)
    task = build_task(problem)
    plan = "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target); final()"
    states = plan_states(task, parse_plan(task, plan))
    back = [f for f in GraphNLPFactory(problem, task).factors(states) if f.rule == "back"]
    assert [f.step for f in back] == [5]
    final = task.var_index("final")
    assert (final, 1) in back[0].generator[0].facts
    assert [s[final] for s in states] == [0, 0, 0, 0, 0, 1]


def test_plans_end_with_the_final_step_and_nothing_after(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    with_final = build_task(_problem(tmp_path / "a"))
    without = build_task(_problem(tmp_path / "b", rule=""))
    assert optimal_cost(with_final) == optimal_cost(without)      # final() costs 0
    fd = run_fd_on_sas(write_sas(with_final))
    assert fd.solved and fd.plan[-1] == "final()" and "final()" not in fd.plan[:-1]
    last = run_plan(with_final, fd.plan)[-1]
    assert with_final.goal.holds_in(last)
    assert all(successor(with_final, last, i) is None for i in range(len(with_final.operators)))
    assert not with_final.goal.holds_in(initial(with_final))
