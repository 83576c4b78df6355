"""Disjunctive goals (`goal { visited(p3) or visited(p4) }`, `(a and b) or c`): compiled to a
derived goal variable (SAS+ axioms), so clingo, Fast Downward and the plan validator read them.

Oracle: a Dijkstra search written here over (position, visited places) with the costs from the
scene's coordinates and the goal as a Python predicate, sharing nothing with the compiler; the
compiled task's optimum must equal it for clingo (`optimal_plan`), Fast Downward (A*, costs in
thousandths) and the naive SAS+ search of tests/compile/sas_semantics.py.
"""
from __future__ import annotations

import heapq
import math

import pytest

from delivery import PLACES, STEP, write
from fd_oracle import run_fd_on_sas
from sas_semantics import optimal_cost

from gnppdsl.compile.sas import COST_RESOLUTION
from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem
from gnppdsl.logic.planner import IncrementalPlanner
from gnppdsl.logic.validate import validate_plan


def _oracle(goal) -> float:
    """Cheapest sequence of moves from p0 whose end (position, visited set) satisfies `goal`."""
    start = ("p0", frozenset())
    best = {start: 0.0}
    queue = [(0.0, "p0", ())]
    while queue:
        d, at, visited = heapq.heappop(queue)
        if goal(at, set(visited)):
            return d
        for b in PLACES:
            if b == at:
                continue
            key = (b, frozenset(visited) | {b})
            nd = d + STEP + math.dist(PLACES[at], PLACES[b])
            if nd < best.get(key, math.inf) - 1e-12:
                best[key] = nd
                heapq.heappush(queue, (nd, b, tuple(sorted(key[1]))))
    raise AssertionError("no plan")


CASES = [
    ("visited(p3) or visited(p4)", lambda at, v: "p3" in v or "p4" in v),
    ("(visited(p1) and visited(p2)) or visited(p4)", lambda at, v: {"p1", "p2"} <= v or "p4" in v),
    ("visited(p2) or at(r) = p1, visited(p3)", lambda at, v: ("p2" in v or at == "p1") and "p3" in v),
    ("forall p: place . at(r) = p or not visited(p)", lambda at, v: all(p == at or p not in v for p in PLACES)),
]


@pytest.mark.parametrize("text, goal", CASES)
def test_disjunctive_goal_optimum_matches_direct_search(tmp_path, text, goal):
    task = build_task(load_problem(write(tmp_path, text)))
    expected = _oracle(goal)
    res = IncrementalPlanner(task).optimal_plan(4)
    assert res.plan.optimal and res.plan.cost == pytest.approx(expected, abs=2 / COST_RESOLUTION)
    check = validate_plan(task, res.plan.operators)
    assert check.valid
    assert optimal_cost(task) == pytest.approx(expected, abs=1e-9)
    fd = run_fd_on_sas(write_sas(task))
    assert fd.solved and abs(fd.cost - expected * COST_RESOLUTION) <= 2


def test_validator_rejects_a_plan_that_misses_every_disjunct(tmp_path):
    task = build_task(load_problem(write(tmp_path, "visited(p3) or visited(p4)")))
    names = [op.name for op in task.operators]
    ops = [names.index("move(r, p0, p1)"), names.index("move(r, p1, p2)")]
    res = validate_plan(task, ops)
    assert not res.valid and "goal" in res.error


def test_a_goal_that_can_never_hold_is_located_at_the_goal(tmp_path, capsys):
    """Contradictory goal facts: the compile error points at the goal (line 5 of the problem),
    not at the problem's first line."""
    from delivery import write

    from gnppdsl.cli.main import main
    path = write(tmp_path, "at(r) = p1  at(r) = p2")
    assert main(["compile", str(tmp_path / "domain.pntc"), str(path), "-o", str(tmp_path / "t.sas")]) == 2
    err = capsys.readouterr().err
    assert "tour.pntc:5:" in err and "the goal can never hold" in err
