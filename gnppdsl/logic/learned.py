"""What the logic planners learn from the continuous level: conflicts and blocked plans.

Why one base class: the clingo planner (`IncrementalPlanner`) and the Fast Downward planner
(`FastDownwardPlanner`) keep the same bookkeeping -- which conflicts <p_0 .. p_L> and which
operator sequences are forbidden, each once, with their facts checked against the task -- and
differ only in how a constraint enters the search (a clingo step program, an Appendix-B
reformulation of the .sas). `LearnedConstraints` holds the former; a planner implements
`_forbid_conflict` and `_forbid_plan` for the latter.

A *lifted* conflict (`add_lifted`) is one piece of knowledge that holds for several symmetric
instances (`gnppdsl.conflicts.lifting`: the same infeasible NLP up to renaming objects of equal
geometry and scene data). It is learned once: `learned` counts it once, the clingo planner
encodes it as one parameterised constraint over a table of instances, Fast Downward receives
its ground instances. `conflicts` always lists every ground instance, so a plan is checked
against exactly what is forbidden (Proposition 7.1 per instance).
"""
from __future__ import annotations

from typing import Iterable, Sequence

from gnppdsl.compile.sas import PartialState, SASTask

Conflict = tuple[PartialState, ...]


class LearnedConstraints:
    """Conflicts (ground instances, and the lifted groups they were learned in) and blocked
    plans of one planner, each stored once. Subclasses set `task` before calling
    `__init__` of this class and implement `_forbid_conflict` / `_forbid_plan`."""

    task: SASTask

    def __init__(self) -> None:
        self.conflicts: list[Conflict] = []          # every ground instance forbidden
        self.learned: list[tuple[Conflict, ...]] = []   # one entry per conflict learned (lifted: all its instances)
        self.blocked: list[tuple[int, ...]] = []
        self._conflict_set: set[Conflict] = set()
        self._blocked_set: set[tuple[int, ...]] = set()

    # ---- what a backend implements -----------------------------------------------------
    def _forbid_conflict(self, seqs: Sequence[Conflict]) -> None:
        """Make the search avoid every plan containing any of `seqs` (one learned conflict:
        a single sequence, or the new instances of a lifted one, all of the same length)."""
        raise NotImplementedError

    def _forbid_plan(self, ops: tuple[int, ...]) -> None:
        """Make the search avoid exactly the operator sequence `ops`."""
        raise NotImplementedError

    # ---- the planner interface ---------------------------------------------------------
    def add_conflict(self, seq: Sequence[PartialState]) -> bool:
        """Forbid every plan whose states contain s_i ⊇ p_0, ..., s_{i+L} ⊇ p_L (any i).

        Returns False if the same conflict was added before (nothing to do).
        """
        return self.add_lifted([seq]) > 0

    def add_conflicts(self, seqs: Iterable[Sequence[PartialState]]) -> int:
        return sum(self.add_conflict(s) for s in seqs)

    def add_lifted(self, seqs: Iterable[Sequence[PartialState]]) -> int:
        """Learn one conflict with several instances (each forbidden as by `add_conflict`);
        instances known before are left out. Returns the number of new instances (0: the
        conflict adds nothing and is not counted in `learned`)."""
        new: list[Conflict] = []
        for seq in seqs:
            seq = tuple(seq)
            self._check_partial_states(seq)
            if seq not in self._conflict_set and seq not in new:
                new.append(seq)
        if not new:
            return 0
        by_length: dict[int, list[Conflict]] = {}
        for seq in new:
            by_length.setdefault(len(seq), []).append(seq)
        for group in by_length.values():
            self._forbid_conflict(group)
            # `conflicts` in the order the instances were compiled: fd_guidance pairs the i-th
            # conflict with the i-th Appendix-B head (in `new`'s order a mixed-length group paired
            # heads wrongly and the guided task lost valid plans)
            self.conflicts.extend(group)
        self._conflict_set.update(new)
        self.learned.append(tuple(new))
        return len(new)

    def block_plan(self, plan: Sequence[int]) -> bool:
        """Forbid exactly this plan (its operator sequence); False if known."""
        ops = tuple(getattr(plan, "operators", plan))
        if ops in self._blocked_set:
            return False
        if any(not 0 <= o < len(self.task.operators) for o in ops):
            raise ValueError(f"plan refers to unknown operators: {ops}")
        self._forbid_plan(ops)
        self.blocked.append(ops)
        self._blocked_set.add(ops)
        return True

    def _check_partial_states(self, seq: Sequence[PartialState]) -> None:
        if not seq:
            raise ValueError("a conflict needs at least one partial state")
        for p in seq:
            for v, x in p.facts:
                if not (0 <= v < len(self.task.variables) and 0 <= x < len(self.task.variables[v].values)):
                    raise ValueError(f"fact ({v}, {x}) is not a fact of task {self.task.name}")

    def _under(self) -> str:
        """` under N conflicts and M blocked plans` for messages ('' when nothing is learned)."""
        extra = []
        if self.conflicts:
            lifted = len(self.learned) != len(self.conflicts)
            extra.append(f"{len(self.learned)} conflicts" + (f" ({len(self.conflicts)} instances)" if lifted else ""))
        if self.blocked:
            extra.append(f"{len(self.blocked)} blocked plans")
        return f" under {' and '.join(extra)}" if extra else ""
