"""Batch-learned conflicts (issue 19): a conflict's renamings that lifting cannot accept, each
decided by its own NLP.

Why: lifting (`gnppdsl.conflicts.lifting`) accepts a renamed conflict only when the renamed
subgraph is the same NLP as the infeasible one M, so objects at other places (blocks on a row,
pads, arms with other bases) are never lifted. On stack_32 the reach conflicts then came one
per block: `{parent(b2) = table, not moved(b2)} -> {parent(b2) = right_arm}`, then b4, b6, ...,
each a whole loop iteration (a logical plan, its graph-NLP, Alg. 1's search). Such a renamed
subgraph is small (typically one keyframe), so deciding it directly is far cheaper than
waiting for the planner to propose a plan that contains it.

What: for a conflict found on a plan, the candidate renamings π are single renamings of one
of its objects onto another object of the same declared type or of a subtype (any geometry:
lab5_paper's reach conflict about block b2 renamed onto obstacle o1), then pairs of
them (e.g. the block and the arm), objects of the plan first, at most `budget` NLPs per
conflict. For each, the factory builds π(M) (`Lifter.image`: the factors of the renamed plan
window with M's rules, templates and renamed bindings; the same construction as lifting,
without the isomorphism test). The caller solves π(M) by the standard of the loop's own
conflicts -- the solver's restarts, as `Run.infeasible` decides a minimised conflict --
and learns `to_partial_states(π(M))` only when it stays infeasible.

Soundness (Prop. 7.1): π(M) is a set of factors the factory builds where their generators
hold, so by factor time-invariance (Property 4.2) every plan containing its partial states
contains π(M); π(M) was found infeasible by an NLP, as every conflict of the loop is. Nothing is
assumed about symmetry: a renaming onto a reachable block, a free pad or the other arm gives a
feasible NLP, and is not learned (its verdict is cached, so the next conflict does not solve
it again; a feasible verdict is also recorded in the subgraph database with switch g).

Screen: a renaming often gives partial states no plan reaches -- on field4, renaming o1 onto o2
gives `{parent(o2) = site_a, not moved(o2)}` although o2 starts at station_s, and renaming the
place gives `{parent(o1) = station_n, not moved(o1)}`. Learning such a conflict forbids nothing,
yet each cost an NLP (140 of field4's 218 candidates). `Reachable` drops a candidate one of
whose partial states holds a fact or a pair of facts that h^2 (`gnppdsl.logic.mutex`) never
reaches: no NLP, nothing learned (learning less never breaks Prop. 7.1).
"""
from __future__ import annotations

import itertools
import re
from dataclasses import dataclass, field
from typing import Callable, Iterator, Sequence

import numpy as np

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.conflicts.lifting import Lifter, State, parse_name
from gnppdsl.conflicts.mapping import to_partial_states

Conflict = tuple[PartialState, ...]

BUDGET = 64
"""Default NLPs per learned conflict spent on renamed candidates (`SolveOptions.batch_conflicts`)."""

EAGER_SHARE = 0.5
"""Lazy batch: a conflict's first candidates are still decided at once, for at most this share
of the CPU time its plan's attempt has cost; the rest are queued (`Batcher.pending`). Why: where
a loop iteration is dear and candidates cheap (lab5_paper: 5-8 s per plan, 0.05-0.1 s per
candidate) the eager batch saved plans; where candidates cost as much as a plan (field2:
0.25-0.4 s each with restarts, ~1 s per plan) it only added NLPs."""

FACTORY_FACTOR = 4
"""Renamings built with the factory per conflict, at most FACTORY_FACTOR * budget (a renaming
that is cached, known or has no image costs no NLP but still a factory call)."""


@dataclass
class BatchStats:
    candidates: int = 0          # renamed subgraphs solved (one NLP each, with restarts)
    learned: int = 0             # ... of which infeasible: learned with the conflict
    cached: int = 0              # renamed subgraphs decided without an NLP (cache, database)
    unreachable: int = 0         # renamed subgraphs no plan reaches (`Reachable`): dropped
    time: float = 0.0            # seconds building and solving them


@dataclass(frozen=True)
class Candidate:
    mapping: tuple[tuple[str, str], ...]          # the renaming π (sources -> targets)
    factors: tuple[FactorInstance, ...]           # π(M), steps from 0
    states: tuple[tuple[int, ...], ...]           # the renamed plan window π(M) was built on
    conflict: Conflict                            # to_partial_states(π(M))
    key: tuple                                    # identity of π(M) for the cache
    subtype: bool = False                         # π renames an object onto one of a subtype


class Reachable:
    """Can a plan's states hold these partial states? False when one of them holds a fact or a
    pair of facts that h^2 never reaches (`gnppdsl.logic.mutex.h2_matrix`, an over-approximation
    of the reachable states: True is no promise). Derived facts are not tested."""

    def __init__(self, task: SASTask) -> None:
        from gnppdsl.logic.mutex import h2_matrix

        facts, _, self.R = h2_matrix(task)
        self.index = {f: i for i, f in enumerate(facts)}

    def state(self, p: PartialState) -> bool:
        idx = [self.index[f] for f in p.facts if f in self.index]
        return bool(self.R[np.ix_(idx, idx)].all()) if idx else True

    def __call__(self, seq: Sequence[PartialState]) -> bool:
        return all(self.state(p) for p in seq)


@dataclass
class Batcher:
    """The renamed candidates of conflicts in one compiled problem (see the module docstring)."""

    lifter: Lifter
    budget: int = BUDGET
    stats: BatchStats = field(default_factory=BatchStats)
    verdicts: dict = field(default_factory=dict)  # Candidate.key -> feasible (bool)
    reachable: Reachable | None = None            # the screen (None: every candidate is solved)
    lazy: bool = False                            # queue candidates until a plan holds one (`pending`)
    pending: list = field(default_factory=list)   # lazy: (origin, Candidate), not decided yet
    origins: int = 0                              # lazy: conflicts whose candidates were queued
    deferred: Candidate | None = None             # lazy: taken from the iterator, not decided (`Run.batch`)
    subtype: Callable[[str, str], bool] | None = None   # (type, type) -> is the first a subtype of the
                                                  # second (`Domain.is_subtype`); None: same types only

    def queue(self, cands: Iterator[Candidate], known: Sequence[Conflict]) -> int:
        """Lazy batch: keep up to `budget` undecided candidates of one conflict (not cached, not
        subsumed by a known conflict) in `pending`, under a new origin; their number."""
        self.origins += 1
        n = 0
        for cand in cands:
            if n >= self.budget:
                break
            if cand.key in self.verdicts or subsumed(cand.conflict, known):
                continue
            self.pending.append((self.origins, cand))
            n += 1
        return n

    def hits(self, states: Sequence[State], shapes=None, lifted=None
             ) -> Iterator[tuple[int, Candidate, tuple[FactorInstance, ...] | None]]:
        """Lazy batch: the pending candidates the plan with these states holds, as (origin,
        candidate, factors), each taken out of `pending` when yielded; `factors` are the
        plan's own factors that the candidate's verdict decides (steps of the plan): the
        candidate's, where the plan holds its partial states. With `lifted` (candidate,
        states -> the factors, in the plan's steps, of a symmetric instance of the candidate
        the plan holds, or None) a candidate is also yielded when the plan holds such an
        instance, with those factors. With `shapes` (candidate -> further sequences its
        learning forbids, e.g. its interleaved instances) a candidate is also yielded, with
        factors None, when the plan holds one of them."""
        from gnppdsl.logic.validate import find_sequence

        for item in list(self.pending):
            origin, cand = item
            factors = None
            offset = find_sequence(states, cand.conflict)
            if offset is not None:
                factors = tuple(f.shifted(offset) for f in cand.factors)
            elif lifted is not None and (factors := lifted(cand, states)) is not None:
                pass
            elif not (shapes is not None and any(find_sequence(states, seq) is not None for seq in shapes(cand))):
                continue
            self.pending.remove(item)
            yield origin, cand, factors

    def siblings(self, origin: int) -> list[Candidate]:
        """Lazy batch: take out of `pending` the candidates queued with `origin`."""
        out = [c for o, c in self.pending if o == origin]
        self.pending = [(o, c) for o, c in self.pending if o != origin]
        return out

    def candidates(self, states: Sequence[State], factors: Sequence[FactorInstance],
                   plan_names: Sequence[str] = (), lifted: dict | None = None) -> Iterator[Candidate]:
        """The renamed subgraphs of the conflict of `factors` (found on the plan with full states
        `states` and action names `plan_names`), in order: single renamings before pairs,
        renamings onto objects that play the renamed object's role in the plan (an argument
        position of an action: the blocks it picks, not those it stacks onto) first, then onto
        other objects of the plan, then the rest, each by name. Each with an image (`Lifter.image`) and facts; at most
        FACTORY_FACTOR * budget factory calls. Renamings onto objects of a subtype come after
        all the others (`Candidate.subtype`). `lifted`: object -> the objects lifting renamed
        it onto (`Lifter.renamable`); an object lifted onto every other object of its type is
        not renamed (the caller lifts each learned candidate, which covers those renamings)."""
        window, shifted = self.lifter.window(states, factors)
        types = self.lifter.object_types
        lifted = lifted or {}
        sub = self.subtype or (lambda a, b: a == b)
        # onto objects of its type or of a subtype: every rule that takes o takes them (an
        # obstacle is a block); a rule of the subtype alone adds factors outside π(M), which
        # stays a subgraph of every plan holding its partial states
        kin = {o: [c for c in types if c != o and (types[c] == types[o] or sub(types[c], types[o]))]
               for o in self.lifter.objects(factors)}
        objs = [o for o, cs in kin.items() if not set(cs) <= set(lifted.get(o, ()))]
        roles: dict[str, set] = {}
        for name in plan_names:
            head, args = parse_name(name)
            for i, a in enumerate(args):
                roles.setdefault(a, set()).add((head, i))

        def rank(o: str, c: str) -> int:
            return 0 if roles.get(o, set()) & roles.get(c, set()) else 1 if c in roles else 2

        choices = {o: sorted(kin[o], key=lambda c: (rank(o, c), _natural(c))) for o in objs}
        singles = [((o, c),) for o in objs for c in choices[o]]
        pairs = [((o1, c1), (o2, c2)) for o1, o2 in itertools.combinations(objs, 2)
                 for c1 in choices[o1] for c2 in choices[o2] if c1 != c2 and c1 != o2 and c2 != o1]
        pairs.sort(key=lambda m: (sum(rank(o, c) for o, c in m), [_natural(c) for _, c in m]))
        # renamings onto a subtype after all others (the lazy batch queues them: `Run.batch`)
        onto_sub = lambda m: any(types[c] != types[o] for o, c in m)      # noqa: E731
        calls = 0
        for mapping in itertools.chain([m for m in singles if not onto_sub(m)], [m for m in pairs if not onto_sub(m)],
                                       [m for m in singles if onto_sub(m)], [m for m in pairs if onto_sub(m)]):
            if calls >= FACTORY_FACTOR * self.budget:
                return
            calls += 1
            built = self.lifter.image(dict(mapping), window, shifted)
            if built is None:
                continue
            image, renamed = built
            seq = to_partial_states(image)
            if not any(p.facts for p in seq):
                continue                          # a sweeping claim: never from a batch
            if self.reachable is not None and not self.reachable(seq):
                self.stats.unreachable += 1
                continue                          # no plan holds it: nothing to learn
            key = (seq, frozenset((f.rule, f.template, f.bindings, f.step) for f in image))
            yield Candidate(mapping, tuple(image), tuple(renamed), seq, key, onto_sub(mapping))


def subsumed(seq: Conflict, known: Sequence[Conflict]) -> bool:
    """Does a known conflict K occur inside `seq` (K_j ⊆ seq_{i+j} for some offset i)? Then
    every plan containing `seq` contains K and is forbidden already: nothing to learn (and no
    NLP to solve)."""
    facts = [set(p.facts) for p in seq]
    for k in known:
        if len(k) > len(seq):
            continue
        for i in range(len(seq) - len(k) + 1):
            if all(set(p.facts) <= facts[i + j] for j, p in enumerate(k)):
                return True
    return False


def _natural(name: str) -> tuple:
    """b2 < b10: digits compared as numbers."""
    return tuple((0, int(t), "") if t.isdigit() else (1, 0, t) for t in re.split(r"(\d+)", name) if t)
