"""SAS+ semantics on a `SASTask`: derived values, applicability, successor states, plans.

Why here: the graph-NLP factory and `gnpp compile --emit factors --plan ...` must turn a plan into
its sequence of full symbolic states, and the compile layer may not import the logic layer above
it; the logic layer's validator (`gnppdsl.logic.validate`) builds on these same functions, which
are written without clingo, so a bug in the ASP encoding still cannot hide itself.

Semantics (Fast Downward's): derived variables are reset to their default 0 and recomputed
layer by layer to a fixpoint; an operator applies if all its preconditions hold; every effect
whose conditions hold in the *old* state fires.
"""
from __future__ import annotations

import re
from typing import Sequence

from gnppdsl.compile.sas import Operator, SASTask
from gnppdsl.errors import UserError

State = tuple[int, ...]

__all__ = ["derive", "initial_state", "applicable", "fired_effects", "successor", "parse_plan",
           "plan_states"]


def derive(task: SASTask, state: Sequence[int]) -> State:
    """The state with every derived variable recomputed from the state variables."""
    s = list(state)
    by_layer: dict[int, list] = {}
    for ax in task.axioms:
        by_layer.setdefault(task.variables[ax.var].axiom_layer, []).append(ax)
    for i, var in enumerate(task.variables):
        if var.is_derived:
            s[i] = 0
    for layer in sorted(by_layer):
        pending = by_layer[layer]
        changed = True
        while changed:
            changed = False
            rest = []
            for ax in pending:
                if all(s[v] == val for v, val in ax.conditions):
                    if s[ax.var] != ax.value:
                        s[ax.var] = ax.value
                        changed = True
                else:
                    rest.append(ax)
            pending = rest
    return tuple(s)


def initial_state(task: SASTask) -> State:
    return derive(task, task.initial)


def applicable(op: Operator, state: Sequence[int]) -> bool:
    return all(state[v] == val for v, val in op.pre)


def fired_effects(op: Operator, state: Sequence[int]) -> dict[int, int]:
    """Assignments of the effects of `op` whose conditions hold in `state` (the old state).

    Raises ValueError if two firing effects assign different values to one variable (undefined
    in SAS+; can only arise from conditional effects)."""
    out: dict[int, int] = {}
    for e in op.effects:
        if all(state[v] == x for v, x in e.conditions):
            if out.get(e.var, e.value) != e.value:
                raise ValueError(f"effects of {op.name} assign two values to variable {e.var}")
            out[e.var] = e.value
    return out


def successor(task: SASTask, state: Sequence[int], op: Operator) -> State:
    """s[a]: apply `op` (assumed applicable) and re-derive."""
    s = list(state)
    for v, x in fired_effects(op, state).items():
        s[v] = x
    return derive(task, s)


def _norm(name: str) -> str:
    return re.sub(r"\s+", "", name)


def parse_plan(task: SASTask, text: str) -> list[int]:
    """Operator indices of a plan written `pick(b1, g, s1); place(b1, g, right)` (separators:
    `;`, newlines or commas between actions; `#` comments and FD's `(...)` lines accepted)."""
    by_name = {_norm(op.name): i for i, op in enumerate(task.operators)}
    actions: list[str] = []
    for line in text.splitlines():
        line = line.split("#", 1)[0]
        if line.lstrip().startswith(";"):
            continue                      # Fast Downward's `; cost = ...` trailer
        depth, cur = 0, ""
        for ch in line:
            if ch == "(":
                depth += 1
            elif ch == ")":
                depth -= 1
            if depth == 0 and ch in ";,":
                actions.append(cur)
                cur = ""
            else:
                cur += ch
        actions.append(cur)
    out = []
    for a in actions:
        a = a.strip()
        if not a:
            continue
        if a.startswith("(") and a.endswith(")") and _norm(a[1:-1]) in by_name:
            a = a[1:-1]                   # Fast Downward plan files: `(pick(b1, g, s1))`
        key = _norm(a)
        if key not in by_name:
            known = ", ".join(sorted({op.action for op in task.operators}))
            raise UserError(f"unknown or statically inapplicable action '{a}' "
                            f"(actions of this problem: {known})")
        out.append(by_name[key])
    return out


def plan_states(task: SASTask, ops: Sequence[int]) -> list[State]:
    """The states s_0 .. s_n visited by a plan; UserError at the first inapplicable action."""
    states = [initial_state(task)]
    for k, i in enumerate(ops):
        op = task.operators[i]
        if not applicable(op, states[-1]):
            missing = [f for f in op.pre if states[-1][f[0]] != f[1]]
            raise UserError(f"action {k + 1}, {op.name}, is not applicable in "
                            f"{task.state_str(states[-1])}: needs "
                            f"{', '.join(task.fact_str(f) for f in missing)}")
        try:
            states.append(successor(task, states[-1], op))
        except ValueError as err:
            raise UserError(f"action {k + 1}, {op.name}: {err}") from None
    return states
