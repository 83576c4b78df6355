"""Conflicts made visible to Fast Downward's heuristic: redundant preconditions (paper 000, App. B).

Why: Appendix B (`gnppdsl.logic.reformulation`) forbids a conflict <p_0 .. p_L> through a
derived variable b_L that every operator requires to be false. FD's FF heuristic relaxes that
negated derived precondition away (`axioms=approximate_negative`, the only setting that answers
on the Lab domain: see `fd_planner`), so the heuristic never sees a conflict; the search meets
it as dead ends after the fact and exhausts the plateau of forbidden plans. Measured on
clutter_6 with the conflicts of one end-to-end run (lazy greedy FF, CPU s of FD): 0, 1, 3, 6
conflicts 0.02, 0.10, 1.7, 4.8 s; 7 conflicts no plan within 200 s wall (26 s CPU).

What this adds, per operator o and conflict: the condition C on the state s in which o is
applied under which o's successor completes the conflict, i.e.
    [L >= 2: b_{L-2}(s) = 1] and p_{L-1} ⊆ s (L >= 1) and the facts of p_L that o leaves
    unchanged hold in s,
where o sets the other facts of p_L unconditionally (at least one). Such a successor is a dead
end of the compiled task (every operator and the goal require b_L = 0), so o is replaced by
copies that require "not C" as plain facts: one copy per fact (v, x) of C and value y != x of v,
with v = y added to its precondition (`C` empty: o is dropped). The set of plans is unchanged
(only transitions into dead ends go), Appendix B's variables stay and still decide validity; FF
now sees, e.g., that putting b1 on pad1 needs o1 moved first. Operators whose effects on p_L's
variables are conditional or whose p_L holds derived facts are left alone (the successor's
value is not known from s alone), as are copies beyond `MAX_COPIES` per original operator.
"""
from __future__ import annotations

import re
from dataclasses import replace
from typing import Sequence

from gnppdsl.compile.sas import Fact, Operator, PartialState, SASTask

MAX_COPIES = 64          # copies of one original operator before a conflict is left to App. B alone
_CONFLICT_VAR = re.compile(r"^forbid\d+_b(\d+)$")


def conflict_heads(task: SASTask, n_conflicts: int) -> list[int]:
    """The variable b_L of each conflict compiled into `task` (in the order they were added):
    the head of each Appendix-B axiom, read from the task so no index is kept elsewhere."""
    heads = [ax.var for ax in task.axioms if _CONFLICT_VAR.match(task.variables[ax.var].name)]
    if len(heads) != n_conflicts:
        raise AssertionError(f"{len(heads)} Appendix-B axioms for {n_conflicts} conflicts")
    return heads


def _condition(task: SASTask, op: Operator, seq: Sequence[PartialState], head: int | None) -> list[Fact] | None:
    """C for `op` and one conflict (facts on s, simplified by op's preconditions), or None when
    op cannot complete the conflict or its successor is not decided by s."""
    L = len(seq) - 1
    uncond = {e.var: e.value for e in op.effects if not e.conditions}
    conditional = {e.var for e in op.effects if e.conditions}
    cond: list[Fact] = []
    established = False
    for v, x in seq[L].facts:
        if task.variables[v].axiom_layer >= 0 or v in conditional:
            return None
        if v in uncond:
            if uncond[v] != x:
                return None
            established = True
        else:
            cond.append((v, x))
    if not established:
        return None
    if L >= 1:
        cond.extend(seq[L - 1].facts)
    if L >= 2:
        assert head is not None, "a conflict longer than 2 is compiled by Appendix B"
        cond.append((head - 2, 1))            # b_{L-2}: variables b_0 .. b_L are consecutive
    pre = dict(op.pre)
    out: list[Fact] = []
    for v, x in dict.fromkeys(cond):
        if v in pre:
            if pre[v] != x:
                return None                    # C never holds where op applies
            continue                           # implied by op's precondition
        out.append((v, x))
    values = {}
    for v, x in out:
        if values.setdefault(v, x) != x:
            return None                        # C asks v for two values: never holds
    return out


def guide(task: SASTask, conflicts: Sequence[Sequence[PartialState]],
          heads: Sequence[int | None] | None = None) -> tuple[SASTask, list[int]]:
    """`task` (conflicts already compiled in) with each operator split into copies that avoid
    the conflicts' dead ends by their preconditions; and for each operator of the new task the
    index of the operator of `task` it copies. `heads`: per conflict its Appendix-B variable b_L,
    or None for one compiled by `reformulation.forbid_transition` (L = 1: the condition C above
    is then exactly the derived precondition that forbids the transition); default: every
    conflict by Appendix B, heads read from the task."""
    if heads is None:
        heads = conflict_heads(task, len(conflicts))
    elif len(heads) != len(conflicts):
        raise AssertionError(f"{len(heads)} heads for {len(conflicts)} conflicts")
    ops: list[Operator] = []
    origin: list[int] = []
    for i, op in enumerate(task.operators):
        copies = [op]
        for seq, head in zip(conflicts, heads):
            cond = _condition(task, op, seq, head)
            if cond is None:
                continue
            split = []
            for c in copies:
                pre = dict(c.pre)
                if all(pre.get(v) == x for v, x in cond):
                    continue                    # this copy always completes the conflict
                if any(v in pre and pre[v] != x for v, x in cond):
                    split.append(c)             # this copy never does
                    continue
                for v, x in cond:
                    if v in pre:
                        continue
                    for y in range(len(task.variables[v].values)):
                        if y != x:
                            split.append(replace(c, pre=tuple(c.pre) + ((v, y),)))
            if len(split) > MAX_COPIES:
                continue                        # left to Appendix B's dead ends
            copies = split
        ops.extend(copies)
        origin.extend([i] * len(copies))
    return replace(task, operators=ops), origin
