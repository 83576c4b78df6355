"""Brute-force plan enumeration from the SAS+ semantics (the validator's primitives): an oracle
for the ASP planner on tiny tasks that shares no code with the encoding."""
from __future__ import annotations

from typing import Sequence

from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.logic.validate import applicable, find_sequence, fired_effects, initial_state, plan_cost, successor


def all_plans(task: SASTask, max_len: int,
              conflicts: Sequence[Sequence[PartialState]] = ()) -> set[tuple[int, ...]]:
    """Every operator sequence of length <= max_len reaching the goal with no conflict."""
    out: set[tuple[int, ...]] = set()

    def dfs(ops: tuple[int, ...], states: list) -> None:
        if any(find_sequence(states[-len(c):], c) is not None for c in conflicts if len(c) <= len(states)):
            return      # a conflict ends at the last state (earlier ends were checked before)
        if task.goal.holds_in(states[-1]):
            out.add(ops)
        if len(ops) == max_len:
            return
        for o, op in enumerate(task.operators):
            if not applicable(op, states[-1]):
                continue
            try:
                fired_effects(op, states[-1])
            except ValueError:
                continue
            dfs(ops + (o,), states + [successor(task, states[-1], op)])

    dfs((), [initial_state(task)])
    return out


def shortest_length(plans: set[tuple[int, ...]]) -> int | None:
    return min((len(p) for p in plans), default=None)


def cheapest(task: SASTask, plans: set[tuple[int, ...]]) -> int | None:
    return min((plan_cost(task, p) for p in plans), default=None)
