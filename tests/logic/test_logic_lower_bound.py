"""The admissible plan-length bound (`logic.lower_bound`) and the sequential planner starting at it."""
from __future__ import annotations

import random
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from logic_brute import all_plans, shortest_length  # noqa: E402

from gnppdsl.compile.sas import Effect, Operator, PartialState, SASTask, SASVariable  # noqa: E402
from gnppdsl.logic.generators import random_conflicts, random_task, reverse_tower_task, tower_task  # noqa: E402
from gnppdsl.logic.lower_bound import plan_length_bound  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner, Status  # noqa: E402


def test_bound_never_exceeds_the_shortest_plan_brute_force():
    """Random tasks with conditional effects and two axiom layers: the bound is at most the
    brute-force shortest plan, and mostly equal to it (not a trivial 0)."""
    tight = solvable = 0
    for seed in range(400):
        rng = random.Random(seed)
        task = random_task(rng, n_vars=rng.randint(2, 5), n_ops=rng.randint(3, 10))
        bound = plan_length_bound(task)
        shortest = shortest_length(all_plans(task, 5))
        if shortest is None:
            continue
        solvable += 1
        assert bound is not None and bound <= shortest, (seed, bound, shortest)
        tight += bound == shortest
    assert solvable > 300 and tight > 0.8 * solvable


def test_bound_on_towers_uses_mutexes():
    """place(b, x) has no precondition on on(b); h^2 (holding = b implies on(b) = hand) restores
    the two steps per moved block: exactly the shortest lengths."""
    for n in (2, 3, 5):
        assert plan_length_bound(tower_task(n)) == 2 * (n - 1)
        assert plan_length_bound(reverse_tower_task(n)) == 2 * n


def test_unreachable_goal_has_no_bound():
    v = SASVariable("v", ("a", "b", "c"))
    task = SASTask([v], (0,), PartialState(((0, 2),)), [Operator("ab", ((0, 0),), (Effect(0, 1),))], [],
                   name="dead")
    assert plan_length_bound(task) is None
    planner = IncrementalPlanner(task, max_horizon=5)
    res = planner.shortest_plan()
    assert res.status is Status.NO_PLAN and planner.stats.solve_calls == 0


def test_cheap_horizons_below_the_bound_keep_the_first_plan(monkeypatch):
    """Horizons below the bound that cost at most CHEAP_CONFLICTS are still solved (the same
    nogoods, so the same first plan as without the bound); the first that costs more jumps to
    the bound (the base proved every horizon: 2n - 1 solve calls before the plan)."""
    from gnppdsl.logic import planner as planner_mod

    task = tower_task(5)
    plain = IncrementalPlanner(task, lower_bound=False)
    first = plain.shortest_plan().plan
    assert len(first) == 8 and plain.stats.solve_calls == 9
    cheap = IncrementalPlanner(task)
    assert cheap.shortest_plan().plan == first
    monkeypatch.setattr(planner_mod, "CHEAP_CONFLICTS", 0)
    jump = IncrementalPlanner(task)
    res = jump.shortest_plan()
    assert res.found and len(res.plan) == 8 and res.plan.shortest
    assert jump.stats.solve_calls < 9 and jump.no_plan_below == 8


def test_shortest_under_conflicts_matches_brute_force():
    """With conflicts (which the bound ignores: they only remove plans) the planner starting at
    the bound still returns a shortest plan, as brute force says."""
    checked = 0
    for seed in range(60):
        rng = random.Random(1000 + seed)
        task = random_task(rng)
        conflicts = random_conflicts(task, rng, rng.randint(1, 4), walk_length=6)
        expected = shortest_length(all_plans(task, 5, conflicts))
        planner = IncrementalPlanner(task)
        planner.add_conflicts(conflicts)
        res = planner.shortest_plan(max_horizon=5)
        if expected is None:
            assert res.status is Status.NO_PLAN
        else:
            assert res.found and len(res.plan) == expected
            checked += 1
    assert checked > 20
