"""Appendix B (SAS+ -> SAS+) against Proposition 7.1, and clingo against Fast Downward on the
compiled `.sas`: the shortest plan under conflicts has the same length for both planners."""
from __future__ import annotations

import itertools
import random
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from logic_fd import require_fd, run_fd  # noqa: E402

from gnppdsl.compile.sas import Effect, Operator, PartialState, SASTask, SASVariable  # noqa: E402
from gnppdsl.logic.generators import grid_task, random_conflicts, random_task, tower_task  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner, Status  # noqa: E402
from gnppdsl.logic.reformulation import forbid_sequence, forbid_sequences  # noqa: E402
from gnppdsl.logic.validate import validate_plan  # noqa: E402


def all_sequences(task: SASTask, max_len: int):
    for n in range(max_len + 1):
        yield from itertools.product(range(len(task.operators)), repeat=n)


def test_proposition_7_1_on_every_operator_sequence():
    """pi solves T' iff pi solves T and avoids every conflict (checked on all sequences <= 4)."""
    rng = random.Random(21)
    agree = {True: 0, False: 0}
    for _ in range(12):
        task = random_task(rng, n_ops=6)
        conflicts = random_conflicts(task, rng, rng.randint(1, 3), walk_length=5)
        compiled = forbid_sequences(task, conflicts)
        for seq in all_sequences(task, 4):
            original = validate_plan(task, seq, conflicts)
            new = validate_plan(compiled, seq)
            assert new.valid == original.valid, (seq, original.error, new.error)
            agree[original.valid] += 1
            if new.valid:   # the old variables evolve exactly as before
                assert [s[:len(task.variables)] for s in new.states] == original.states
    assert agree[True] > 20 and agree[False] > 1000


def test_overlapping_matches_are_found():
    """<X, X, Y> on X X X Y: the match starts at the second X (the paper's reset would miss it)."""
    v = [SASVariable("x", ("X", "Y"))]
    ops = [Operator("stay", (), ()), Operator("go", (), (Effect(0, 1),))]
    task = SASTask(v, (0,), PartialState(((0, 1),)), ops)
    X, Y = PartialState(((0, 0),)), PartialState(((0, 1),))
    compiled = forbid_sequence(task, [X, X, Y])
    assert not validate_plan(compiled, [0, 0, 1]).valid
    assert validate_plan(compiled, [1]).valid
    assert not validate_plan(compiled, [0, 1]).valid
    res = IncrementalPlanner(compiled).shortest_plan(max_horizon=5)
    assert res.plan.operators == (1,)
    twice = forbid_sequence(forbid_sequence(task, [X, Y]), [Y])   # forbid everything reaching Y
    assert twice.variables[-1].name != twice.variables[1].name     # fresh names per conflict
    assert IncrementalPlanner(twice).shortest_plan(max_horizon=4).status is Status.NO_PLAN


def fd_cases():
    rng = random.Random(8)
    for k in range(12):
        task = random_task(rng, n_vars=5, n_ops=10)
        yield f"random{k}", task, random_conflicts(task, rng, rng.randint(0, 3), walk_length=6)
    for k in range(10):
        task = grid_task(3, 2, 2, rng)
        yield f"grid{k}", task, random_conflicts(task, rng, rng.randint(1, 6), max_facts=2, walk_length=10)
    for n in (3, 4):
        task = tower_task(n)
        # forbid the first two states of the optimal plan (to be avoided by a detour)
        plan = IncrementalPlanner(task).shortest_plan().plan
        yield f"tower{n}", task, [tuple(PartialState(tuple(enumerate(plan.states[j]))) for j in (0, 1))]


@pytest.mark.parametrize("name,task,conflicts", list(fd_cases()), ids=lambda x: x if isinstance(x, str) else "")
def test_clingo_and_fast_downward_agree_on_the_compiled_task(name, task, conflicts):
    require_fd()
    H = 20
    compiled = forbid_sequences(task, conflicts)
    fd = run_fd(compiled)                          # unit costs: optimal = shortest
    planner = IncrementalPlanner(task)
    planner.add_conflicts(conflicts)
    res = planner.shortest_plan(max_horizon=H)
    if fd.solved:
        assert validate_plan(task, fd.operators, conflicts).valid
        assert validate_plan(compiled, fd.operators).valid
    if res.found:
        assert validate_plan(task, res.plan, conflicts).valid
        assert validate_plan(compiled, res.plan).valid
    fd_len = len(fd.operators) if fd.solved and len(fd.operators) <= H else None
    assert (len(res.plan) if res.found else None) == fd_len


def test_cost_optimal_plans_agree_with_fast_downward():
    require_fd()
    rng = random.Random(5)
    compared = 0
    for _ in range(10):
        task = random_task(rng, n_vars=5, n_ops=10)
        conflicts = random_conflicts(task, rng, 2, walk_length=6)
        compiled = forbid_sequences(task, conflicts)
        fd = run_fd(compiled, search="astar(blind())")            # real costs
        if not fd.solved:
            continue
        planner = IncrementalPlanner(task)
        planner.add_conflicts(conflicts)
        res = planner.optimal_plan(len(fd.operators) + 2)
        assert res.found and res.plan.optimal
        assert res.plan.cost == fd.cost == validate_plan(task, fd.operators).cost
        compared += 1
    assert compared >= 3
