"""A tiny, deliberately naive SAS+ interpreter used only by the tests.

It shares no code with `gnppdsl.compile` on purpose: plans found by Fast Downward and the states
our compiler produces are checked against this independent reading of the semantics
(stratified axioms to a fixpoint, all effect conditions evaluated in the old state).
"""
from __future__ import annotations

import heapq

from gnppdsl.compile.sas import SASTask


def with_axioms(task: SASTask, state: tuple[int, ...]) -> tuple[int, ...]:
    s = list(state)
    layers = sorted({v.axiom_layer for v in task.variables if v.axiom_layer >= 0})
    for i, v in enumerate(task.variables):
        if v.axiom_layer >= 0:
            s[i] = 0
    for layer in layers:
        changed = True
        while changed:
            changed = False
            for ax in task.axioms:
                if task.variables[ax.var].axiom_layer != layer or s[ax.var] == ax.value:
                    continue
                if all(s[v] == val for v, val in ax.conditions):
                    s[ax.var] = ax.value
                    changed = True
    return tuple(s)


def initial(task: SASTask) -> tuple[int, ...]:
    return with_axioms(task, tuple(task.initial))


def successor(task: SASTask, state, op_index: int):
    op = task.operators[op_index]
    if not all(state[v] == val for v, val in op.pre):
        return None
    s = list(state)
    for eff in op.effects:
        if all(state[v] == val for v, val in eff.conditions):
            s[eff.var] = eff.value
    return with_axioms(task, tuple(s))


def is_goal(task: SASTask, state) -> bool:
    return all(state[v] == val for v, val in task.goal.facts)


def optimal_cost(task: SASTask, limit: int = 200000) -> int | None:
    """Uniform-cost search over the reachable states (small tasks only)."""
    start = initial(task)
    dist = {start: 0}
    queue = [(0, start)]
    while queue:
        d, s = heapq.heappop(queue)
        if d > dist[s]:
            continue
        if is_goal(task, s):
            return d
        for i, op in enumerate(task.operators):
            t = successor(task, s, i)
            if t is not None and d + op.cost < dist.get(t, 1 << 60):
                dist[t] = d + op.cost
                heapq.heappush(queue, (d + op.cost, t))
        if len(dist) > limit:
            raise RuntimeError("state space too large for the test oracle")
    return None


def run_plan(task: SASTask, names: list[str]):
    """Apply operators by name; returns the list of states or raises AssertionError."""
    by_name = {op.name: i for i, op in enumerate(task.operators)}
    states = [initial(task)]
    for name in names:
        assert name in by_name, f"unknown operator {name!r}"
        t = successor(task, states[-1], by_name[name])
        assert t is not None, f"{name} not applicable in {task.state_str(states[-1])}"
        states.append(t)
    return states
