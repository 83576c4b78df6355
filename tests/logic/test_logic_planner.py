"""The incremental ASP planner against brute-force enumeration and the validator."""
from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from logic_brute import all_plans, cheapest, shortest_length  # noqa: E402

from gnppdsl.compile.sas import Axiom, Operator, Effect, PartialState, SASTask, SASVariable  # noqa: E402
from gnppdsl.errors import SolveFailure  # noqa: E402
from gnppdsl.logic.generators import (random_conflicts, random_task, reverse_tower_task,  # noqa: E402
                                      tower_task)
from gnppdsl.logic.planner import IncrementalPlanner, Status  # noqa: E402
from gnppdsl.logic.validate import validate_plan  # noqa: E402


def check(task, plan, conflicts=()):
    """The plan is valid, avoids the conflicts, and the model's states are the true states."""
    r = validate_plan(task, plan, conflicts)
    assert r.valid, r.error
    assert list(plan.states) == r.states
    assert plan.cost == r.cost
    assert list(plan.names) == [task.operators[o].name for o in plan.operators]


@pytest.mark.parametrize("n", [3, 5, 7])
def test_tower_lengths_are_optimal(n):
    for task, length in ((tower_task(n), 2 * (n - 1)), (reverse_tower_task(n), 2 * n)):
        res = IncrementalPlanner(task).shortest_plan()
        assert res.found and len(res.plan) == length and res.plan.shortest
        check(task, res.plan)


def random_cases(seed, count, **kw):
    rng = random.Random(seed)
    for _ in range(count):
        task = random_task(rng, **kw)
        yield rng, task, random_conflicts(task, rng, rng.randint(1, 4), walk_length=6)


def enumerate_all(planner, max_len):
    plans = []
    while True:
        res = planner.next_plan(max_horizon=max_len)
        if not res.found:
            assert res.status is Status.NO_PLAN and f"horizon {max_len}" in res.message
            return plans
        plans.append(res.plan)


def test_enumeration_is_complete_ordered_and_without_duplicates():
    checked = 0
    for rng, task, conflicts in random_cases(11, 25):
        H = 4
        expected = all_plans(task, H, conflicts)
        planner = IncrementalPlanner(task)
        planner.add_conflicts(conflicts)
        plans = enumerate_all(planner, H)
        ops = [p.operators for p in plans]
        assert len(ops) == len(set(ops))
        assert set(ops) == expected
        assert [len(o) for o in ops] == sorted(len(o) for o in ops)
        for p in plans:
            check(task, p, conflicts)
        checked += len(plans)
    assert checked > 200    # the random tasks do have plans


def test_enumeration_respects_conflicts_and_blocks_added_midway():
    """Plans cached from one solve call are re-checked against later conflicts and blocks."""
    seen = 0
    for rng, task, conflicts in random_cases(13, 15):
        H = 4
        planner = IncrementalPlanner(task)
        first = [planner.next_plan(max_horizon=H) for _ in range(3)]
        first = [r.plan.operators for r in first if r.found]
        remaining = sorted(all_plans(task, H) - set(first))
        if len(remaining) < 2:
            continue
        blocked = remaining[-1]
        planner.block_plan(blocked)
        planner.add_conflicts(conflicts)
        rest = [p.operators for p in enumerate_all(planner, H)]
        assert len(rest) == len(set(rest))
        assert set(rest) == all_plans(task, H, conflicts) - set(first) - {blocked}
        seen += len(rest)
    assert seen > 100


def test_conflicts_added_after_grounding_constrain_existing_and_future_steps():
    for rng, task, conflicts in random_cases(5, 10):
        H = 4
        expected = all_plans(task, H, conflicts)
        late = IncrementalPlanner(task)
        late.optimal_plan(2)                     # steps 1..2 grounded before any conflict
        assert late.horizon == 2
        half = len(conflicts) // 2
        late.add_conflicts(conflicts[:half])
        late.optimal_plan(3)                     # step 3 grounded between conflicts
        late.add_conflicts(conflicts[half:])
        got = {p.operators for p in enumerate_all(late, H)}
        assert got == expected


def test_shortest_plan_under_conflicts_matches_brute_force():
    lengths = []
    for rng, task, conflicts in random_cases(7, 15, n_vars=5, n_ops=10):
        expected = shortest_length(all_plans(task, 5, conflicts))
        planner = IncrementalPlanner(task)
        res = planner.shortest_plan(max_horizon=5)   # before conflicts
        planner.add_conflicts(conflicts)
        res = planner.shortest_plan(max_horizon=5)
        if expected is None:
            assert res.status is Status.NO_PLAN and res.plan is None
            with pytest.raises(SolveFailure, match="no plan up to horizon 5"):
                res.unwrap()
        else:
            assert res.found and len(res.plan) == expected
            check(task, res.plan, conflicts)
        lengths.append(expected)
    assert len({x for x in lengths if x}) >= 2          # plans of several lengths were checked


def test_block_plan_blocks_exactly_one_plan():
    task = tower_task(3)
    planner = IncrementalPlanner(task)
    first = planner.shortest_plan().plan
    assert planner.shortest_plan().plan.operators == first.operators   # not blocked by itself
    assert planner.block_plan(first) and not planner.block_plan(first)
    second = planner.shortest_plan().plan
    assert second.operators != first.operators and len(second) >= len(first)
    expected = all_plans(task, 6)                 # the plan of length 4 and those of length 6
    assert len(expected) == 8
    planner2 = IncrementalPlanner(task)
    got = [planner2.next_plan(max_horizon=6) for _ in range(len(expected) + 1)]
    assert {r.plan.operators for r in got[:-1]} == expected
    assert got[-1].status is Status.NO_PLAN
    check(task, second)


def test_optimal_plan_with_operator_and_pair_costs():
    solved = 0
    for rng, task, conflicts in random_cases(3, 12):
        ops = len(task.operators)
        task.pair_costs = {(rng.choice([None, *range(ops)]), rng.randrange(ops)): rng.randint(1, 6)
                           for _ in range(10)}
        H = 4
        plans = all_plans(task, H, conflicts)
        planner = IncrementalPlanner(task)
        planner.add_conflicts(conflicts)
        res = planner.optimal_plan(H)
        if not plans:
            assert res.status is Status.NO_PLAN
            continue
        assert res.found and res.plan.optimal
        assert res.plan.cost == cheapest(task, plans)
        solved += 1
        check(task, res.plan, conflicts)
        # cheapest among the shortest plans
        short = shortest_length(plans)
        res = planner.shortest_plan(max_horizon=H, minimize_cost=True)
        assert len(res.plan) == short and res.plan.optimal
        assert res.plan.cost == cheapest(task, {p for p in plans if len(p) == short})
        check(task, res.plan, conflicts)
    assert solved >= 4


def test_cost_bound_admits_exactly_the_plans_brute_force_finds_under_it():
    """`optimal_plan(H, cost_bound=B)`: no plan iff every plan of length <= H costs more than B
    (the anytime search's proof of optimality), else the cheapest; repeated with each answer
    blocked it hands out plans in order of cost, as the brute-force list sorted by cost."""
    checked = proofs = 0
    for rng, task, conflicts in random_cases(11, 12):
        for o, op in enumerate(task.operators):
            task.operators[o] = Operator(op.name, op.pre, op.effects, rng.randint(1, 5))
        H = 4
        plans = all_plans(task, H, conflicts)
        costs = sorted(cheapest(task, {p}) for p in plans)
        planner = IncrementalPlanner(task)
        planner.add_conflicts(conflicts)
        for bound in (0, 2, 4, 7):
            res = planner.optimal_plan(H, cost_bound=bound)
            if not costs or costs[0] > bound:
                assert res.status is Status.NO_PLAN and "cost <= " in res.message
                proofs += 1
            else:
                assert res.found and res.plan.cost == costs[0] and res.plan.optimal
                check(task, res.plan, conflicts)
            checked += 1
        seen = []
        while True:                                  # the anytime order: cheapest, blocked, next
            res = planner.optimal_plan(H, cost_bound=max(costs, default=0))
            if not res.found:
                break
            seen.append(res.plan.cost)
            planner.block_plan(res.plan)
        assert seen == costs[:len(seen)] and len(seen) == len(costs)
    assert checked >= 40 and proofs >= 5


def test_blocked_plans_stay_blocked_in_cheapest_plan_mode():
    task = tower_task(3)
    planner = IncrementalPlanner(task)
    best = planner.optimal_plan(6).plan
    planner.block_plan(best)
    again = planner.optimal_plan(6).plan
    assert again.operators != best.operators and again.cost >= best.cost
    check(task, again)


def test_adding_conflicts_never_regrounds_the_base():
    rng = random.Random(4)
    task = random_task(rng, n_vars=5, n_ops=10)
    planner = IncrementalPlanner(task)
    planner.optimal_plan(5)                              # steps 1..5 grounded
    added = []
    for seq in random_conflicts(task, rng, 8, walk_length=6):
        calls = planner.stats.ground_calls
        assert planner.add_conflict(seq)
        assert planner.stats.ground_calls == calls + 1      # one call for all existing steps
        assert not planner.add_conflict(seq)                # duplicate: nothing to do
        assert planner.stats.ground_calls == calls + 1
        added.append(seq)
        res = planner.shortest_plan(max_horizon=5)
        assert (len(res.plan) if res.found else None) == shortest_length(all_plans(task, 5, added))
        if res.found:
            check(task, res.plan, added)
    planner.shortest_plan(max_horizon=7)
    assert planner.horizon == 7
    assert planner.stats.count("base") == 1
    assert planner.stats.count("step") == planner.horizon
    assert planner.stats.count("conflict_0") == planner.horizon + 1   # t = 0 .. 7, each once
    assert len(set(planner.stats.grounded_parts)) == len(planner.stats.grounded_parts)


def pigeons(n: int) -> SASTask:
    """n + 1 pigeons, n holes: unsolvable, and hard for clause learning at horizon n + 1."""
    holes = range(n)
    V = [SASVariable(f"at(p{p})", ("none", *[f"h{h}" for h in holes])) for p in range(n + 1)]
    full = len(V)
    V += [SASVariable(f"full(h{h})", ("false", "true"), 0) for h in holes]
    placed = len(V)
    V += [SASVariable(f"placed(p{p})", ("false", "true"), 0) for p in range(n + 1)]
    ops = [Operator(f"put(p{p}, h{h})", ((p, 0), (full + h, 0)), (Effect(p, h + 1),))
           for p in range(n + 1) for h in holes]
    ax = [Axiom(((p, h + 1),), full + h) for p in range(n + 1) for h in holes]
    ax += [Axiom(((p, h + 1),), placed + p) for p in range(n + 1) for h in holes]
    goal = PartialState(tuple((placed + p, 1) for p in range(n + 1)))
    return SASTask(V, (0,) * len(V), goal, ops, ax, name="pigeons")


def test_time_limit_is_honoured_and_the_planner_stays_usable():
    planner = IncrementalPlanner(pigeons(8))
    res = planner.shortest_plan(max_horizon=20, time_limit=0.3)
    assert res.status is Status.TIMEOUT and res.plan is None
    assert "time limit" in res.message
    with pytest.raises(SolveFailure):
        res.unwrap()
    # the interrupted solve was cleaned up: the same control answers the next query
    res2 = planner.optimal_plan(3, time_limit=30)
    assert res2.status is Status.NO_PLAN


def test_empty_plan_and_bad_input():
    task = tower_task(2)
    task.goal = PartialState()
    planner = IncrementalPlanner(task)
    res = planner.shortest_plan()
    assert res.found and len(res.plan) == 0 and res.plan
    with pytest.raises(ValueError):
        planner.add_conflict([])
    with pytest.raises(ValueError):
        planner.add_conflict([PartialState(((0, 99),))])
    # a conflict on the initial state forbids everything
    planner.add_conflict([PartialState(((0, task.initial[0]),))])
    assert planner.shortest_plan(max_horizon=3).status is Status.NO_PLAN


def test_blocking_a_plan_before_its_steps_are_grounded():
    task = tower_task(3)
    plan = IncrementalPlanner(task).shortest_plan().plan        # the unique plan of length 4
    fresh = IncrementalPlanner(task)
    assert fresh.horizon == 0 and fresh.block_plan(plan)
    res = fresh.shortest_plan()
    assert len(res.plan) == 6
    check(task, res.plan)
    best = fresh.optimal_plan(8).plan                            # idle steps after the plan
    assert best.operators != plan.operators and best.cost == 6
