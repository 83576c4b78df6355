"""The plan-length bound raised by learned conflicts (`lower_bound.LengthBound.under`) and the
`auto` planner's Fast Downward probe at a raised bound (`modes.AutoPlanner._probe`)."""
from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from logic_brute import all_plans, shortest_length  # noqa: E402

from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.logic.generators import random_conflicts, random_task  # noqa: E402
from gnppdsl.logic.lower_bound import LengthBound, plan_length_bound  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner, Status  # noqa: E402
from gnppdsl.logic.validate import initial_state, validate_plan  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def _end_conflicts(task, rng, count):
    """Conflicts of one partial state: some goal facts and 1-2 facts of the initial state off the
    goal (a goal that needs something moved away, as an obstacle covering a goal pad)."""
    s0 = initial_state(task)
    goal = dict(task.goal.facts)
    others = [(v, s0[v]) for v in range(len(task.variables))
              if not task.variables[v].is_derived and v not in goal]
    state_goal = [f for f in task.goal.facts if not task.variables[f[0]].is_derived]
    out = []
    for _ in range(count):
        if not others:
            break
        facts = rng.sample(state_goal, rng.randint(0, min(2, len(state_goal))))
        facts += rng.sample(others, rng.randint(1, min(2, len(others))))
        out.append((PartialState(tuple(sorted(facts))),))
    return out


def test_raised_bound_never_exceeds_the_shortest_plan_brute_force():
    """Random tasks (conditional effects, axioms) with end conflicts and random conflicts: the
    raised bound is at most the brute-force shortest plan under the conflicts, and it rises
    above the task's own bound on a good share of them (the test would see a bound that
    ignores the conflicts)."""
    raised = checked = 0
    for seed in range(500):
        rng = random.Random(7000 + seed)
        task = random_task(rng, n_vars=rng.randint(4, 6), n_ops=rng.randint(6, 12))
        conflicts = _end_conflicts(task, rng, rng.randint(1, 2))
        if rng.random() < 0.5:
            conflicts += random_conflicts(task, rng, rng.randint(1, 2), walk_length=5)
        if not conflicts:
            continue
        shortest = shortest_length(all_plans(task, 6, conflicts))
        bound = LengthBound(task)
        under = bound.under(conflicts)
        if shortest is None or bound.bound is None:
            continue
        checked += 1
        assert under is not None and bound.bound <= under <= shortest, (seed, bound.bound, under, shortest)
        raised += under > bound.bound
    assert checked > 50 and raised > 0.1 * checked, (checked, raised)


def test_raised_bound_grows_with_the_conflicts_learned():
    """Conflicts given one by one (the list only grows): never below the bound of all at once
    (it only rises), never above the brute-force shortest plan."""
    rises = 0
    for seed in range(80):
        rng = random.Random(9100 + seed)
        task = random_task(rng)
        conflicts = _end_conflicts(task, rng, 3)
        step = LengthBound(task)
        seen = []
        for k in range(1, len(conflicts) + 1):
            seen.append(step.under(conflicts[:k]))
        at_once = LengthBound(task).under(conflicts)
        assert seen == sorted(seen, key=lambda b: -1 if b is None else b) and seen[-1] >= at_once
        shortest = shortest_length(all_plans(task, 6, conflicts))
        if shortest is not None:
            assert seen[-1] <= shortest, (seed, seen, shortest)
        rises += seen[-1] > seen[0]
    assert rises > 0


def _lab5():
    from gnppdsl.compile.task import build_task
    from gnppdsl.ir import load_problem

    task = build_task(load_problem(ROOT / "examples" / "scalability" / "lab5_paper.pntc"))
    names = {v.name: i for i, v in enumerate(task.variables)}

    def fact(var, value):
        v = names[var]
        return v, task.variables[v].values.index(value)

    def covered(pad, obstacle):
        return [(PartialState(tuple(sorted([fact(f"parent(b{b})", pad), fact(f"parent({obstacle})", "table"),
                                            fact(f"moved({obstacle})", "false")]))),) for b in range(1, 7)]
    def reach(block, arm):     # the arm cannot pick the block from the table (lab5_paper's first conflict)
        return (PartialState(tuple(sorted([fact(f"parent({block})", "table"), fact(f"moved({block})", "false")]))),
                PartialState((fact(f"parent({block})", arm),)))
    covered.reach = reach
    return task, covered


def test_covered_pads_raise_lab5_paper_bound_and_the_plans_agree():
    """lab5_paper (N0 = 12): its goal pads covered by obstacles (the conflicts its solves learn)
    need each obstacle picked and set down: 14 with one covered pad, 16 with both; the
    sequential planner's shortest plans have exactly those lengths (the base bound stays 12)."""
    task, covered = _lab5()
    assert plan_length_bound(task) == 12
    planner = IncrementalPlanner(task)
    planner.add_lifted(covered("pad_r", "o2"))
    assert planner.no_plan_below == 14
    res = planner.shortest_plan(max_horizon=22)
    assert res.found and len(res.plan) == 14 and res.plan.shortest
    planner.add_lifted(covered("pad_l", "o1"))
    assert planner.no_plan_below == 16
    res = planner.shortest_plan(max_horizon=22)
    assert res.found and len(res.plan) == 16
    assert validate_plan(task, res.plan.operators, planner.conflicts).valid


def test_auto_probes_fast_downward_at_a_raised_bound(monkeypatch):
    """`auto` at a bound the conflicts raised: clingo gets PROBE_CONFLICTS clasp conflicts, then
    Fast Downward, whose plan reaching the bound is proven shortest (and the search stays with
    it); before, clingo spent its whole switch budget first (lab5_paper: 2 s CPU)."""
    from gnppdsl.logic import modes
    from gnppdsl.logic.fd_planner import downward_binary

    if downward_binary() is None:
        pytest.skip("external: Fast Downward (up-fast-downward) is not installed")
    monkeypatch.setattr(modes, "PROBE_CONFLICTS", 1)
    task, covered = _lab5()
    planner = modes.AutoPlanner(task, max_horizon=22)
    first = planner.shortest_plan()
    assert first.found and len(first.plan) == 12 and planner.mode == "sequential"
    # the conflicts of lab5_paper's solves before its third plan
    planner.add_lifted([covered.reach("b2", "right_arm"), covered.reach("b4", "left_arm"),
                        covered.reach("b5", "left_arm")])
    assert planner.shortest_plan().plan.shortest and planner.mode == "sequential"
    planner.add_lifted(covered("pad_r", "o2"))
    planner.add_lifted(covered("pad_l", "o1"))
    before = planner.sequential.stats.conflicts
    res = planner.shortest_plan()
    assert res.found and len(res.plan) == 16 and res.plan.shortest
    assert planner.mode == "fd" and planner.sequential.stats.conflicts - before < 1000
    assert validate_plan(task, res.plan.operators, planner.conflicts).valid
