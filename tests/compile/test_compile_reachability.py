"""Relaxed-reachability pruning (`gnppdsl.compile.reachability`) keeps every plan.

Oracles: the naive interpreter of tests/compile/sas_semantics.py (shares no code with the
compiler) explores the reachable state graph of the full and of the pruned task, read by names:
the two graphs must be identical (same states, same operator names on the same edges), so every
plan and every plan length is kept; Fast Downward on the pruned `.sas` finds the optimum of the
full task. On random tasks (hypothesis) and on every bundled example (states capped)."""
from __future__ import annotations

from collections import deque
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings

from fd_oracle import require_fd, run_fd_on_sas
from random_sas import tasks
from sas_semantics import initial, optimal_cost, successor

from gnppdsl.compile.reachability import prune_unreachable
from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem

ROOT = Path(__file__).resolve().parents[2]
EXAMPLES = sorted(str(p.relative_to(ROOT)) for d in ("planar", "lab", "mobile")
                  for p in (ROOT / "examples" / d).glob("*.pntc") if p.name != "domain.pntc")


def named(task, state):
    return tuple((v.name, v.values[x]) for v, x in zip(task.variables, state))


def state_graph(task, cap: int = 4000):
    """{named state: {(operator name, named successor)}} of the states reachable from s_0
    (breadth first, at most `cap` states), and whether the exploration was complete."""
    start = initial(task)
    graph: dict = {}
    queue = deque([start])
    seen = {start}
    while queue:
        s = queue.popleft()
        edges = set()
        for i, op in enumerate(task.operators):
            t = successor(task, s, i)
            if t is None:
                continue
            edges.add((op.name, named(task, t)))
            if t not in seen:
                if len(seen) >= cap:
                    return graph, False
                seen.add(t)
                queue.append(t)
        graph[named(task, s)] = edges
    return graph, True


@settings(max_examples=60, deadline=None, suppress_health_check=list(HealthCheck))
@given(tasks())
def test_pruning_keeps_the_reachable_state_graph_of_random_tasks(task):
    pruned = prune_unreachable(task)
    full_graph, complete = state_graph(task)
    assert complete
    assert state_graph(pruned) == (full_graph, True)
    assert optimal_cost(pruned) == optimal_cost(task)
    assert len(pruned.operators) <= len(task.operators)


@settings(max_examples=15, deadline=None, suppress_health_check=list(HealthCheck))
@given(tasks())
def test_fast_downward_on_the_pruned_task_finds_the_full_optimum(task):
    require_fd()
    expected = optimal_cost(task)
    res = run_fd_on_sas(write_sas(prune_unreachable(task)))
    assert res.solved == (expected is not None)
    if expected is not None:
        assert res.cost == expected


@pytest.mark.parametrize("path", EXAMPLES)
def test_pruned_examples_have_the_full_tasks_state_graph(path):
    problem = load_problem(ROOT / path)
    full = build_task(problem, prune=False)
    pruned = build_task(problem)
    assert [v.name for v in pruned.variables] == [v.name for v in full.variables]
    full_graph, complete = state_graph(full, cap=1500)
    pruned_graph, _ = state_graph(pruned, cap=1500)
    if complete:
        assert pruned_graph == full_graph
    else:       # same breadth-first order: the explored prefixes agree state by state
        common = set(full_graph) & set(pruned_graph)
        assert len(common) > 100
        assert all(full_graph[s] == pruned_graph[s] for s in common)


def test_pruning_is_linear_on_many_planar_blocks(tmp_path):
    """80 blocks on their own spots: a block only ever rests on its spot, a region or the
    gripper (4 values of 83), and only picks from those places remain (400 of 6720 operators)."""
    import sys

    sys.path.insert(0, str(ROOT / "benchmarks"))
    from planar_many import write_problem

    problem = load_problem(write_problem(80, tmp_path))
    full = build_task(problem, prune=False)
    pruned = build_task(problem)
    assert len(full.operators) == 80 * 82 + 80 * 2          # pick from any place, place in a region
    assert len(pruned.operators) == 80 * 3 + 80 * 2         # pick from its spot or a region
    parent = pruned.variables[pruned.var_index("parent(b7)")]
    assert parent.values == ("s7", "ra", "rb", "g")
