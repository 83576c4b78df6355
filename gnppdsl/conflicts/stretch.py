"""Stretched conflicts: a conflict whose partial states repeat (<p, B, B, B, q>: a robot holds the
stick with the block on its tip for three steps while another arm does something else) also
forbids the same sequence with the repeated state held for any other number of steps
(<p, B, q>, <p, B, B, q>, ...), when the conflict's subgraph M ties the repeated steps together by
equalities or other reflexive and transitive relations only.

Why: the conflicts of a plan name its interleaving. On the Workshop problems the planner
learned that the south arm cannot push b1 to where the east arm takes it off the stick's end
with one, then two, then three unrelated actions in between (Work_3, seed 0: three of its seven
conflicts, each a plan, its graph-NLP and Alg. 1's search); with four arms and several blocks
the interleavings grow with the plan.

Soundness (the argument of Prop. 7.1, with one more step). Let the conflict <p_0 .. p_L> come
from M and let p_j = ... = p_k = B (k > j) be a run of equal non-empty partial states such that
(a) no variable of M is a trajectory, (b) every factor of M has its variables and generator
within two consecutive steps, and (c) every factor of M whose variables or generator touch two
steps of the run is a chain equality `x[s] == x'[s]` between one variable at consecutive steps (`conflicts.interleave.chain_equality`)
(`same(pose(o), pose(o)')`) or a transition template tagged PREORDER over the same variable keys
at both steps (reflexive and transitive: `tools.push_motion`). Take a plan whose states contain <p_0 .. p_{j-1}, B x m,
p_{k+1} .. p_L> for some m >= 1, and map M's run steps monotonically onto the m copies, first
to first and last to last. Every factor of M outside the run, at its borders or at one run
step has a generator that holds at the image steps, so the factory builds it there (Property
4.2) and a solution y of the plan's graph-NLP satisfies it at those steps. A factor between
two run steps is an equality or a preorder: mapped to one copy (m < n) it holds by
reflexivity; mapped to copies c < c' it holds by transitivity, since its generator (a part
of (B, B)) holds at every pair of consecutive copies and the factory builds the same factor there. So y read at the
image steps solves M, and M is infeasible: the plan's graph-NLP is infeasible too.
"""
from __future__ import annotations

from itertools import product
from typing import Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts.interleave import chain_equality
from gnppdsl.conflicts.mapping import step_range

MAX_VARIANTS = 64
"""Stretched sequences learned per conflict instance at most (all lengths of one run fit:
a run in a plan of at most `max_horizon` steps)."""


PREORDER = "preorder"
"""The tag of a transition template whose body, read as a relation between the values of one
step and of the next, is reflexive and transitive (a preorder: `tools.push_motion`, a push
forward along the block's own +y axis, at its height, without turning it). The template's
author asserts it; tests/conflicts/test_conflicts_stretch.py checks the standard library's."""


def _preorder(f: FactorInstance) -> bool:
    """Is f a transition factor of a template tagged PREORDER over the same variable keys at
    both of its steps (so that its copies along a run chain)?"""
    if PREORDER not in f.tags or f.span != 2:
        return False
    keys = {s: sorted(v.key for v in f.variables if v.step == s) for s in (f.step, f.step + 1)}
    return len(keys) == 2 and keys[f.step] == keys[f.step + 1] and len(f.variables) == 2 * len(keys[f.step])


def stretchable_runs(factors: Sequence[FactorInstance], seq: Sequence[PartialState]) -> list[tuple[int, int]]:
    """(j, k), relative to the conflict's first step, of every maximal run of equal non-empty
    partial states of `seq` (= `to_partial_states(factors)`) that may take any length >= 1
    (module docstring: conditions (a)-(c)); [] when there is none."""
    factors = list(factors)
    if not factors or any(v.waypoints for f in factors for v in f.variables):
        return []                                           # (a)
    first, _ = step_range(factors)
    spans = []
    for f in factors:
        steps = {v.step - first for v in f.variables} | {f.step - first + i for i in range(len(f.generator))}
        if max(steps) - min(steps) > 1:
            return []                                       # (b)
        spans.append((f, steps))
    runs, j = [], 0
    while j < len(seq):
        k = j
        while k + 1 < len(seq) and seq[k + 1] == seq[j]:
            k += 1
        if k > j and seq[j].facts:
            inside = range(j, k + 1)
            if all(chain_equality(f) or _preorder(f) for f, steps in spans if len(steps) == 2 and steps <= set(inside)):
                runs.append((j, k))                         # (c)
        j = k + 1
    return runs


def stretched(seq: Sequence[PartialState], runs: Sequence[tuple[int, int]], max_length: int) -> list[tuple]:
    """The sequences `seq` with each run of `runs` held for 1 .. any number of steps instead,
    at most `max_length` partial states long (a longer one matches no plan), `seq` itself left
    out, at most MAX_VARIANTS; [] when a run of `runs` is not a run of equal states in `seq`
    (an instance whose renaming broke it)."""
    seq = tuple(seq)
    if any(len(set(seq[j:k + 1])) != 1 for j, k in runs):
        return []
    fixed = len(seq) - sum(k - j + 1 for j, k in runs)
    room = max_length - fixed
    out = []
    for lengths in product(*(range(1, room + 1) for _ in runs)):
        if sum(lengths) > room or all(n == k - j + 1 for n, (j, k) in zip(lengths, runs)):
            continue
        parts, at = [], 0
        for n, (j, k) in zip(lengths, runs):
            parts += list(seq[at:j]) + [seq[j]] * n
            at = k + 1
        out.append(tuple(parts + list(seq[at:])))
        if len(out) >= MAX_VARIANTS:
            break
    return out


__all__ = ["stretchable_runs", "stretched", "MAX_VARIANTS", "PREORDER"]
