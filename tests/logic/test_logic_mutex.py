"""h^2 invariants: never violated by a reachable state (explicit search), and strong enough to
contain the invariants the Lab/blocks domains rely on."""
import random
from collections import deque

from gnppdsl.logic.generators import grid_task, random_task, tower_task
from gnppdsl.logic.mutex import mutexes
from gnppdsl.logic.planner import IncrementalPlanner
from gnppdsl.logic.validate import applicable, fired_effects, initial_state, successor


def reachable_states(task, limit=20000):
    start = initial_state(task)
    seen = {start}
    todo = deque([start])
    while todo:
        s = todo.popleft()
        for op in task.operators:
            if not applicable(op, s):
                continue
            try:
                fired_effects(op, s)
            except ValueError:
                continue
            t = successor(task, s, op)
            if t not in seen:
                seen.add(t)
                todo.append(t)
                assert len(seen) < limit
    return seen


def test_mutexes_hold_in_every_reachable_state():
    rng = random.Random(3)
    tasks = [random_task(rng, n_vars=5, n_ops=10) for _ in range(15)]
    tasks += [tower_task(4), grid_task(3, 2, 2, rng)]
    total = 0
    for task in tasks:
        unreachable, pairs = mutexes(task)
        total += len(pairs)
        for s in reachable_states(task):
            assert not any(s[v] == x for v, x in unreachable)
            for (v, x), (w, y) in pairs:
                assert not (s[v] == x and s[w] == y), (task.fact_str((v, x)), task.fact_str((w, y)))
    assert total > 100


def test_mutexes_know_the_gripper_and_support_invariants():
    task = tower_task(3)
    _, pairs = mutexes(task)
    pairs = {tuple(sorted(p)) for p in pairs}
    f = task.fact
    assert tuple(sorted((f("on(b1)", "hand"), f("holding", "none")))) in pairs
    assert tuple(sorted((f("on(b1)", "b2"), f("on(b3)", "b2")))) in pairs   # via derived covered(b2)


def test_invariants_do_not_change_the_answers():
    rng = random.Random(9)
    for _ in range(10):
        task = random_task(rng, n_vars=5, n_ops=10)
        with_inv = IncrementalPlanner(task).optimal_plan(5)
        without = IncrementalPlanner(task, invariants=False).optimal_plan(5)
        assert with_inv.status == without.status
        if with_inv.found:
            assert with_inv.plan.cost == without.plan.cost
