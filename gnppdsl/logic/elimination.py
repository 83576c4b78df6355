"""Action elimination: shorten a plan by dropping operators it does not need (issue 19).

Why: Fast Downward's greedy search (`fd_planner`, the `fd` and `auto` modes) returns plans
with detours: on lab5_paper 18-20 steps where the shortest plan under the same conflicts has
16. Every extra step is another keyframe in each graph-NLP the loop builds from the plan
(lab5_paper spends most of its time in NLPs), so a shorter plan is cheaper to evaluate.

Greedy action elimination (Fink & Yang 1992; Nakhost & Mueller 2010, "Action elimination and
plan neighborhood graph search"): for each step i, drop operator a_i, replay the rest on the
SAS+ semantics and drop as well every later operator that is no longer applicable (or whose
effects clash); keep the shorter sequence if it is a plan -- goal reached, no learned conflict
occurs in its states (Proposition 7.1, checked on the full state sequence, not just the
operators) and it is not a blocked plan -- and retry from the same step, else go on with i + 1;
passes repeat until one drops nothing (a fixpoint: no single step can be dropped any more).
The result is validated by `validate.validate_plan` like any plan of the planner; it is never
longer than the input, and every plan it returns is a subsequence of the input that the task,
the conflicts and the blocked plans all allow. It does not make a plan shortest (a detour that
uses other operators stays); only the sequential mode proves that.

Cost: a pass is at most L replays of L steps, one pass per accepted removal at worst: O(L^3) successor computations
in the worst case, a few milliseconds on the Lab problems (L <= 30).
"""
from __future__ import annotations

from typing import Collection, Sequence

from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.logic.validate import applicable, initial_state, successor, validate_plan


def _replay_without(task: SASTask, ops: Sequence[int], drop: int) -> list[int]:
    """`ops` without step `drop` and without every later operator that then does not apply."""
    state = initial_state(task)
    kept: list[int] = []
    for j, o in enumerate(ops):
        if j == drop:
            continue
        op = task.operators[o]
        if not applicable(op, state):
            if j < drop:     # cannot happen for a valid plan; keep the input unchanged
                return list(ops)
            continue
        try:
            state = successor(task, state, op)
        except ValueError:   # clashing effects: inapplicable in SAS+
            if j < drop:
                return list(ops)
            continue
        kept.append(o)
    return kept


def eliminate_actions(task: SASTask, ops: Sequence[int],
                      conflicts: Sequence[Sequence[PartialState]] = (),
                      blocked: Collection[tuple[int, ...]] = ()) -> tuple[int, ...]:
    """Greedy action elimination of the plan `ops` (see the module docstring): a subsequence
    of `ops`, no longer, that is a plan of `task` avoiding every conflict and not in `blocked`.
    `ops` itself must be such a plan (it is returned unchanged when nothing can be dropped)."""
    plan = list(ops)
    blocked = set(blocked)
    changed = True
    while changed:            # passes until none drops a step (a later drop can free an earlier step)
        changed = False
        i = 0
        while i < len(plan):
            cand = _replay_without(task, plan, i)
            if len(cand) < len(plan) and tuple(cand) not in blocked and validate_plan(task, cand, conflicts).valid:
                plan, changed = cand, True
                continue      # step i now holds the next operator: try it
            i += 1
    return tuple(plan)
