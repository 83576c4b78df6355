"""An independent plan validator for SAS+ tasks (with axioms, conditional effects and conflicts).

Why: every plan the ASP planner or Fast Downward returns is checked here against the plain
SAS+ semantics, written without clingo, so that a bug in the encoding cannot hide itself.
The SAS+ semantics (`derive`, `successor`, ...) are those of `gnppdsl.compile.semantics`;
`validate_plan` runs a whole plan, checks the goal and that no forbidden sequence of
partial states (a conflict, paper 000 Prop. 7.1) occurs at any offset.

Semantics (as Fast Downward's search component):
- derived variables are reset to their default value 0 in every state, then the axioms of each
  layer are applied to a fixpoint, layer by layer (negation = test for 0 on a lower layer);
- an operator is applicable if all of `pre` holds in the (derived) state;
- effect conditions are evaluated in the state before the operator; two firing effects that
  assign different values to one variable make the operator inapplicable (undefined in SAS+).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Sequence

from gnppdsl.compile.sas import PartialState, SASTask

# The SAS+ semantics live in the compile layer (below this one); re-exported for callers here.
from gnppdsl.compile.semantics import (
    State, applicable, derive, fired_effects, initial_state, successor,
)

__all__ = ["State", "derive", "initial_state", "applicable", "fired_effects", "successor",
           "plan_cost", "find_sequence", "ValidationResult", "validate_plan"]


def plan_cost(task: SASTask, ops: Sequence[int]) -> float:
    """Sum of operator costs plus the pair costs of consecutive operators (None before the first):
    an int when every cost is one, else a float in the user's units."""
    total = 0
    prev: int | None = None
    for o in ops:
        total += task.operators[o].cost + task.pair_costs.get((prev, o), 0)
        prev = o
    return total


def find_sequence(states: Sequence[Sequence[int]], seq: Sequence[PartialState]) -> int | None:
    """First offset i with p_l ⊆ s_{i+l} for all l, or None (paper 000, Prop. 7.1)."""
    L = len(seq)
    for i in range(len(states) - L + 1):
        if all(p.holds_in(states[i + l]) for l, p in enumerate(seq)):
            return i
    return None


@dataclass
class ValidationResult:
    valid: bool
    states: list[State] = field(default_factory=list)   # s_0 .. s_k (k = steps applied)
    cost: float = 0
    error: str = ""                                      # human-readable reason when not valid
    failed_step: int | None = None                       # 1-based step whose operator failed
    conflict: tuple[int, int] | None = None              # (conflict index, offset i) that occurs

    def __bool__(self) -> bool:
        return self.valid


def validate_plan(
    task: SASTask,
    plan: Iterable[int] | object,
    conflicts: Sequence[Sequence[PartialState]] = (),
) -> ValidationResult:
    """Check `plan` (operator indices, or any object with an `operators` attribute).

    Valid iff every operator is applicable in turn, the goal holds in the last state and no
    conflict <p_0 .. p_L> matches consecutive states s_i .. s_{i+L} at any offset i.
    """
    ops = list(getattr(plan, "operators", plan))
    state = initial_state(task)
    states = [state]
    for step, o in enumerate(ops, start=1):
        if not 0 <= o < len(task.operators):
            return ValidationResult(False, states, error=f"step {step}: no operator {o}",
                                    failed_step=step)
        op = task.operators[o]
        if not applicable(op, state):
            missing = [f for f in op.pre if state[f[0]] != f[1]]
            text = ", ".join(task.fact_str(f) for f in missing)
            return ValidationResult(False, states, error=f"step {step}: {op.name} is not "
                                    f"applicable: {text} does not hold", failed_step=step)
        try:
            state = successor(task, state, op)
        except ValueError as exc:
            return ValidationResult(False, states, error=f"step {step}: {exc}", failed_step=step)
        states.append(state)
    cost = plan_cost(task, ops)
    if not task.goal.holds_in(state):
        missing = PartialState(tuple(f for f in task.goal.facts if state[f[0]] != f[1]))
        return ValidationResult(False, states, cost, error="goal not reached: "
                                f"{task.partial_state_str(missing)} does not hold at the end")
    for k, seq in enumerate(conflicts):
        i = find_sequence(states, seq)
        if i is not None:
            text = ", ".join(task.partial_state_str(p) for p in seq)
            return ValidationResult(False, states, cost, conflict=(k, i),
                                    error=f"forbidden sequence <{text}> occurs at step {i}")
    return ValidationResult(True, states, cost)
