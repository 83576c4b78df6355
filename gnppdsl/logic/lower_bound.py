"""An admissible lower bound on the length of any plan of a SAS+ task (issue 19).

Why: the sequential clingo planner returns shortest plans by proving every shorter horizon
empty, one solve call per horizon. Those proofs are most of its cost on the first call
(lab5_paper: horizons 0..11 took 0.7 of the 0.9 s to its first plan, the plan at horizon 12
itself 0.2 s), and they prove what a cheap relaxation already knows: each of the six blocks
must be picked and then put down, 12 steps. Starting the search at such a bound skips those
solve calls and keeps every guarantee: no plan of the task is shorter than the bound, and
conflicts and blocked plans only remove plans, so no plan under them is shorter either.

The bound: atomic projections (one state variable each, its domain transition graph) with
cost partitioning (Katz & Domshlak 2008; Seipp & Helmert's "Additive abstraction heuristics").
The projection onto variable v keeps v's value and drops every other variable; an operator
that assigns v (unconditionally or under conditions) is an edge x -> y for every value x it can
meet: its precondition or effect condition on v, else every value that h^2 (`logic.mutex`)
reaches together with its other preconditions (blocks world's place(b, x) tests only
holding = b, which h^2 knows implies on(b) = hand). Every plan of the task maps to a path from
s0[v] in the projection, and the goal's value of v must be reached. An operator
costs one step in total: it is split among the chosen variables it can change (cost
partitioning: the sum of its shares is at most 1), so the sum over the chosen variables of the
cheapest path to the goal value is at most the number of steps of any plan. Two partitionings
are tried, the larger bound kept: goal variables no two of which any operator changes together
(each gets the whole step: on the Lab domain the parent(b) variables, 2 steps per moved block),
and all goal variables with each operator's step split evenly. Derived variables and goal facts
on them are left out (a weaker bound, still sound). A goal value unreachable in its projection
means no plan at all: the bound is then `None`.

Cost: one Dijkstra per goal variable on its domain (a few hundred edges on the Lab problems),
milliseconds.
"""
from __future__ import annotations

import heapq
import math
from fractions import Fraction

from gnppdsl.compile.sas import SASTask


def _edges(task: SASTask) -> dict[int, list[tuple[int, frozenset[int], int]]]:
    """Per state variable: (operator, source values, target value) of every assignment an
    operator can make to it in a reachable state. The sources are the values of the variable
    that h^2 (`mutex.h2_matrix`) reaches together with each of the operator's state
    preconditions, effect conditions and the state facts its derived preconditions imply (a
    value mutex with one of them never holds when the operator applies), restricted to the
    precondition or condition on the variable itself when there is one."""
    from gnppdsl.logic.mutex import axioms_by_var, derived_consequences, h2_matrix

    inv, _, R = h2_matrix(task)
    index = {f: i for i, f in enumerate(inv)}
    reached = R.diagonal()
    by_var = axioms_by_var(task)
    out: dict[int, list[tuple[int, frozenset[int], int]]] = {}
    for o, op in enumerate(task.operators):
        derived = tuple(sorted(f for f in op.pre if task.variables[f[0]].is_derived))
        implied, excluded = derived_consequences(task, derived, by_var)
        pre = {(v, x) for v, x in op.pre if not task.variables[v].is_derived} | implied
        if len({v for v, _ in pre}) != len(pre) or pre & excluded:
            continue                                      # contradictory: never applicable
        for e in op.effects:
            if task.variables[e.var].is_derived:
                continue
            need = {f for f in pre | {c for c in e.conditions if not task.variables[c[0]].is_derived}}
            fixed = {x for v, x in need if v == e.var}
            if len(fixed) > 1:
                continue                                  # never fires
            others = [index[f] for f in need if f[0] != e.var]
            if not all(reached[i] for i in others) or not reached[index[(e.var, e.value)]]:
                continue
            sources = frozenset(
                x for x in (fixed or range(len(task.variables[e.var].values)))
                if x != e.value and (e.var, x) not in excluded and reached[index[(e.var, x)]]
                and all(R[index[(e.var, x)], i] for i in others))
            if sources:
                out.setdefault(e.var, []).append((o, sources, e.value))
    return out


def _distance(task: SASTask, var: int, edges: list[tuple[int, frozenset[int], int]],
              cost: dict[int, Fraction]) -> Fraction | None:
    """Cheapest path from s0[var] to the goal's value of `var` in its projection (operator o
    costs cost[o]); None when the goal value is unreachable."""
    goal = dict(task.goal.facts)[var]
    start = task.initial[var]
    if start == goal:
        return Fraction(0)
    n = len(task.variables[var].values)
    best: list[Fraction | None] = [None] * n
    best[start] = Fraction(0)
    queue = [(Fraction(0), start)]
    while queue:
        d, x = heapq.heappop(queue)
        if d != best[x]:
            continue
        if x == goal:
            return d
        for o, src, y in edges:
            if x not in src:
                continue
            nd = d + cost[o]
            if best[y] is None or nd < best[y]:
                best[y] = nd
                heapq.heappush(queue, (nd, y))
    return None


def plan_length_bound(task: SASTask) -> int | None:
    """A number of steps no plan of `task` is shorter than (see the module docstring); None
    when the task has no plan at all (a goal value unreachable in its projection)."""
    edges = _edges(task)
    goal_vars = [v for v, _ in task.goal.facts if not task.variables[v].is_derived]
    changers = {v: {o for o, _, _ in edges.get(v, ())} for v in goal_vars}
    whole = {o: Fraction(1) for o in range(len(task.operators))}
    unit = {}
    for v in goal_vars:
        d = _distance(task, v, edges.get(v, []), whole)
        if d is None:
            return None
        unit[v] = d
    # 1. goal variables no operator changes two of (greedy, longest distance first)
    chosen: list[int] = []
    used: set[int] = set()
    for v in sorted(goal_vars, key=lambda v: (-unit[v], v)):
        if unit[v] > 0 and not changers[v] & used:
            chosen.append(v)
            used |= changers[v]
    disjoint = sum((unit[v] for v in chosen), Fraction(0))
    # 2. every goal variable, each operator's step split evenly among those it changes
    share: dict[int, int] = {}
    for v in goal_vars:
        for o in changers[v]:
            share[o] = share.get(o, 0) + 1
    even_cost = {o: Fraction(1, share[o]) if o in share else Fraction(1) for o in range(len(task.operators))}
    even = Fraction(0)
    for v in goal_vars:
        d = _distance(task, v, edges.get(v, []), even_cost)
        if d is None:
            return None
        even += d
    return math.ceil(max(disjoint, even))
