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
in the worst case, a few milliseconds on the Lab problems (L <= 30); each candidate is replayed
once, from the state before its dropped step (`eliminate_actions`).
"""
from __future__ import annotations

from typing import Collection, Sequence

from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.logic.validate import State, applicable, find_sequence, initial_state, successor


def _states(task: SASTask, ops: Sequence[int]) -> list[State] | None:
    """s_0 .. s_L of `ops` (every operator applicable, no clashing effects), else None."""
    state = initial_state(task)
    states = [state]
    for o in ops:
        op = task.operators[o]
        if not applicable(op, state):
            return None
        try:
            state = successor(task, state, op)
        except ValueError:
            return None
        states.append(state)
    return states


def _replay_without(task: SASTask, ops: Sequence[int], states: Sequence[State], drop: int
                    ) -> tuple[list[int], list[State]]:
    """`ops` without step `drop` and without every later operator that then does not apply,
    with its states. `states` are those of `ops` (`_states`): the steps before `drop` are kept
    as they are, so the replay starts at s_drop."""
    kept = list(ops[:drop])
    out = list(states[:drop + 1])
    state = out[-1]
    for o in ops[drop + 1:]:
        op = task.operators[o]
        if not applicable(op, state):
            continue
        try:
            state = successor(task, state, op)
        except ValueError:   # clashing effects: inapplicable in SAS+
            continue
        kept.append(o)
        out.append(state)
    return kept, out


def _allowed(task: SASTask, states: Sequence[State], conflicts: Sequence[Sequence[PartialState]]) -> bool:
    """Do the states of an applicable operator sequence end in the goal and meet no conflict
    (what `validate_plan` checks besides applicability)?"""
    return task.goal.holds_in(states[-1]) and all(find_sequence(states, seq) is None for seq in conflicts)


def eliminate_actions(task: SASTask, ops: Sequence[int],
                      conflicts: Sequence[Sequence[PartialState]] = (),
                      blocked: Collection[tuple[int, ...]] = ()) -> tuple[int, ...]:
    """Greedy action elimination of the plan `ops` (see the module docstring): a subsequence
    of `ops`, no longer, that is a plan of `task` avoiding every conflict and not in `blocked`.
    `ops` itself must be such a plan (it is returned unchanged when nothing can be dropped).

    Each candidate is replayed once, from the state before its dropped step (the steps before
    it are the current plan's, so are their states), and its states are checked for the goal
    and the conflicts as `validate_plan` would. Why: stack_32's 32-step plans went through 64
    candidates per plan, each replayed from s_0 and then replayed again by `validate_plan`:
    ~4000 successor states (each re-deriving the axioms), 22.7 s of a 606 s profile; now about a
    quarter of those."""
    plan = list(ops)
    states = _states(task, plan)
    if states is None:        # not a plan: returned unchanged
        return tuple(ops)
    blocked = set(blocked)
    changed = True
    while changed:            # passes until none drops a step (a later drop can free an earlier step)
        changed = False
        i = 0
        while i < len(plan):
            cand, cand_states = _replay_without(task, plan, states, i)
            if len(cand) < len(plan) and tuple(cand) not in blocked and _allowed(task, cand_states, conflicts):
                plan, states, changed = cand, cand_states, True
                continue      # step i now holds the next operator: try it
            i += 1
    return tuple(plan)
