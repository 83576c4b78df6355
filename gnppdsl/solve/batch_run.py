"""The batch of renamed conflicts inside a solve (`gnppdsl.conflicts.batch`): when a conflict is
learned, its renamings onto other objects and arms (the candidates) are decided by one NLP each and
the infeasible ones forbidden with it. The lazy batch (option batch_lazy) decides only the likeliest
candidates at once and queues the rest; a later plan that holds a queued candidate is decided by
that candidate's NLP alone (`batch_hit`), without building its graph-NLP.

Separate from `run.Run` (which derives from `BatchLearning`) because it is one idea with its own
state (`Run.batcher`, `batch_origin`, `batch_shapes_memo`, `batch_lifted_memo`) and kept `run.py` under the solve
package's module size.
"""
from __future__ import annotations

import itertools
import time
from typing import TYPE_CHECKING, Iterable, Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.conflicts.batch import EAGER_SHARE, Batcher, subsumed
from gnppdsl.conflicts.database import SubgraphDatabase, names_of
from gnppdsl.conflicts.lifting import Lifter
from gnppdsl.conflicts.mapping import conflict_str
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.result import Conflict, Stats

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.compile.sas import SASTask
    from gnppdsl.logic.planner import Plan


class BatchLearning:
    """The batch part of a solve (`run.Run` derives from it; `add_conflict`, `infeasible`,
    `new_solver`, `interleaved` and `say` are Run's)."""

    options: SolveOptions
    stats: Stats
    task: SASTask
    batcher: Batcher | None
    lifter: Lifter | None
    db: SubgraphDatabase | None
    batch_origin: int | None
    batch_shapes_memo: dict
    batch_lifted_memo: dict
    attempt_cpu: float
    conflicts: list[Conflict]
    images: dict
    windows: dict

    def batch(self, plan: Plan, sub_factors: Sequence[FactorInstance], instances: Sequence) -> list:
        """The conflict's renamed candidates that are infeasible (`gnppdsl.conflicts.batch`),
        each decided by `decide`, at most `batch_conflicts` NLPs per conflict. Lazy batch
        (option batch_lazy): none is decided now; they are queued for `batch_hit`, and only the
        candidates queued with the conflict a hit came from (`batch_origin`) are decided now."""
        assert self.batcher is not None
        t0 = time.perf_counter()
        known = [*self.planner.conflicts, *instances]
        lifted = self.lifter.renamable if self.lifter is not None else None
        cands = self.batcher.candidates(plan.states, sub_factors, list(plan.names), lifted)
        try:
            if not self.batcher.lazy:
                return self.decide_candidates(cands, known)
            out = []
            if self.batch_origin is not None:     # the planner tries these renamings: decide them
                out = self.decide_candidates(iter(self.batcher.siblings(self.batch_origin)), known)
            # the first candidates (the likeliest: `Batcher.candidates` order) decided now, for
            # at most EAGER_SHARE of the CPU the plan that gave the conflict has cost so far
            spent = time.process_time() - self.attempt_cpu
            self.batcher.deferred = None
            out += self.decide_candidates(cands, known, cpu_limit=EAGER_SHARE * spent)
            deferred = self.batcher.deferred
            self.batcher.queue(cands if deferred is None else itertools.chain([deferred], cands), known)
            return out
        finally:
            self.batcher.stats.time += time.perf_counter() - t0
            self.stats.batch_time = self.batcher.stats.time

    def decide_candidates(self, cands: Iterable, known: list, cpu_limit: float | None = None) -> list:
        """The infeasible candidates among `cands` (at most `batch_conflicts` NLPs), each with
        its symmetric instances (`Lifter`: the same NLP, no solve); `known` grows by them.
        `cpu_limit`: stop after the candidate that reaches that many CPU seconds, or at the first
        renaming onto a subtype (`Candidate.subtype`; the others stay in the iterator)."""
        stats, out, solved = self.batcher.stats, [], 0
        cpu0 = time.process_time()
        for cand in cands:
            if cpu_limit is not None and (cand.subtype or time.process_time() - cpu0 >= cpu_limit):
                # (a renaming onto a subtype is only queued: on lab4_paper deciding them at once
                # cost 21 more candidate NLPs and saved no plan)
                self.batcher.deferred = cand      # not decided: queued by the caller
                break
            if subsumed(cand.conflict, known):
                continue                   # forbidden already: nothing to learn
            if cand.key not in self.batcher.verdicts:
                if solved >= self.batcher.budget:
                    break
                solved += 1
            if self.decide(cand):
                continue
            found = [cand.conflict]
            self.images.setdefault(cand.conflict, cand.factors)
            self.windows.setdefault(cand.conflict, cand.states)
            if self.lifter is not None:
                found = self.lifter.instances(cand.states, cand.factors)
                for k, v in self.lifter.images.items():
                    self.images.setdefault(k, v)
                for k, v in self.lifter.windows.items():
                    self.windows.setdefault(k, v)
            for seq in found:
                if not subsumed(seq, known):
                    out.append(seq)
                    known.append(seq)
        stats.learned += len(out)
        self.stats.batch_learned = stats.learned
        return out

    def decide(self, cand) -> bool:
        """Is a renamed candidate feasible? From the cache of earlier candidates, the subgraph
        database (switch g), or one NLP with the solver's restarts (`infeasible`, as a minimised
        conflict's subgraph is decided)."""
        from gnppdsl.nlp.graph import GraphNLP

        stats = self.batcher.stats
        feasible = self.batcher.verdicts.get(cand.key)
        graph = None
        if feasible is None and self.db is not None:
            graph = GraphNLP(list(cand.factors))
            answer = self.db.lookup(graph)
            feasible = None if answer is None else bool(answer)
        if feasible is not None:
            stats.cached += 1
        else:
            stats.candidates += 1
            feasible = not self.infeasible(self.new_solver(), cand.factors, self.options.seed)
            if self.db is not None:
                self.db.add(graph or GraphNLP(list(cand.factors)), feasible,
                            None if feasible else names_of(self.task, cand.conflict))
        self.batcher.verdicts[cand.key] = feasible
        self.stats.batch_candidates, self.stats.batch_cached = stats.candidates, stats.cached
        self.stats.batch_unreachable = stats.unreachable
        return feasible

    def batch_hit(self, plan: Plan) -> bool:
        """Lazy batch: decide the queued candidates this plan holds (or holds a symmetric
        instance of, `lifted_hit`, or an interleaved instance of); the first infeasible one is
        the plan's conflict (no graph-NLP), learned with the other candidates of its origin.
        Sound as the eager batch: the same candidates, decided by the same NLP, learned with
        the same instances (a symmetric one is the lifter's: the same NLP up to renaming)."""
        if self.batcher is None or not self.batcher.lazy or not self.batcher.pending:
            return False
        t0 = time.perf_counter()
        lifted = self.lifted_hit if self.lifter is not None else None
        try:
            for origin, cand, factors in self.batcher.hits(plan.states, self.batch_shapes, lifted):
                if self.decide(cand):
                    continue
                self.batch_origin = origin
                self.batcher.stats.time += time.perf_counter() - t0
                t0 = time.perf_counter()
                try:
                    if factors is not None:
                        self.add_conflict(plan, factors, "batch", "")
                    else:
                        self.learn_interleaved_hit(plan, cand)
                finally:
                    self.batch_origin = None
                return True
            return False
        finally:
            self.batcher.stats.time += time.perf_counter() - t0
            self.stats.batch_time = self.batcher.stats.time

    def lifted_hit(self, cand, states) -> tuple[FactorInstance, ...] | None:
        """The factors, in the plan's steps, of a symmetric instance of a queued candidate that
        the plan with these states holds, or None. A plan is tested with the lifter (its
        factory and isomorphism test, memoised per candidate) only when it holds one of the
        candidate's renamings fact by fact (`Lifter.renamings`, memoised too): the lifter's
        instances are the ones `decide_candidates` learns with the candidate, and its image
        of M is the same NLP as the candidate's, so the candidate's verdict is the image's."""
        from gnppdsl.logic.validate import find_sequence

        assert self.lifter is not None
        memo = self.batch_lifted_memo
        if cand.key not in memo:
            memo[cand.key] = [self.lifter.renamings(cand.conflict), None]
        renamings, images = memo[cand.key]
        facts = {(v, x) for s in states for v, x in enumerate(s)}
        if not any(all(f in facts for p in seq for f in p.facts) and find_sequence(states, seq) is not None
                   for seq in renamings):
            return None
        if images is None:             # the lifter's instances and their factors π(M)
            t0 = time.perf_counter()
            instances = self.lifter.instances(cand.states, cand.factors)
            images = memo[cand.key][1] = {s: self.lifter.images[s] for s in instances[1:]}
            self.stats.lift_time += time.perf_counter() - t0
        for seq, image in images.items():
            offset = find_sequence(states, seq)
            if offset is not None:
                return tuple(f.shifted(offset - min(g.step for g in image)) for f in image)
        return None

    def batch_shapes(self, cand) -> list:
        """The interleaved instances of a queued candidate (`interleaved`, memoised per candidate)."""
        if not self.options.interleave_conflicts:
            return []
        memo = self.batch_shapes_memo
        if cand.key not in memo:
            from gnppdsl.conflicts.interleave import stretched

            memo[cand.key] = stretched(cand.factors, self.options.max_horizon + 1,
                                       preorder=bool(self.options.stretch_conflicts),
                                       stutter=self.stutter(cand.states))[1:]
        return memo[cand.key]

    def learn_interleaved_hit(self, plan: Plan, cand) -> None:
        """A plan holds an interleaved instance of an infeasible queued candidate: learn the
        candidate (with its symmetric and interleaved instances, and its origin's other
        candidates, as `add_conflict` does for one the plan holds itself)."""
        from gnppdsl.logic.validate import find_sequence

        known = list(self.planner.conflicts)
        found = self.decide_candidates(iter([cand]), known)      # its verdict is cached: no NLP
        found += self.decide_candidates(iter(self.batcher.siblings(self.batch_origin)), known)
        interleaved = self.interleaved(found)
        new = self.planner.add_lifted(found + interleaved)
        if not new or not any(find_sequence(plan.states, s) is not None for s in found + interleaved):
            self.planner.block_plan(plan)       # it holds an infeasible instance: never again
        seq = cand.conflict
        c = Conflict(seq, conflict_str(self.task, seq), tuple(f.label for f in cand.factors), "batch",
                     "", self.stats.plans, 0, named=names_of(self.task, seq),
                     instances=tuple(conflict_str(self.task, s) for s in found[1:]), subgraph=cand.factors,
                     batched=(), interleaved=tuple(conflict_str(self.task, s) for s in interleaved))
        self.conflicts.append(c)
        self.stats.conflicts += 1
        self.stats.conflict_instances += new
        self.stats.interleaved_instances += len(interleaved)
        self.say(f"  conflict (batch, interleaved in the plan): {c.text} (+{len(found) - 1} instances)"
                 f" (+{len(interleaved)} interleaved)")
