"""Appendix B of paper 000: forbid a sequence of partial states by a SAS+ -> SAS+ compilation.
(`forbid_transition`: an exact, cheaper form for conflicts of two partial states; `forbid_plan`:
a blocked plan)

Why: with the conflicts compiled into the task itself, any SAS+ planner (Fast Downward on the
written `.sas`) plans under them; the tests use this as an independent oracle for the ASP
planner, and `gnpp compile --conflicts FILE --emit sas` writes it.

The construction (for one conflict <p_0 .. p_L>, new variables b_0 .. b_L):
- b_l (l < L) is a state variable with b_l = 1 in s_k iff p_0 ⊆ s_{k-1-l}, ..., p_l ⊆ s_{k-1},
  i.e. the first l+1 elements match ending at the *previous* state. Every operator updates them
  with conditional effects evaluated, as SAS+ prescribes, in the state it is applied in:
      b_0 := 1 if p_0 holds,                  b_0 := 0 if some fact of p_0 does not hold;
      b_l := 1 if b_{l-1} = 1 and p_l holds,  b_l := 0 if b_{l-1} = 0 or a fact of p_l fails.
  ("a fact (v, x) fails" is one condition v = y per other value y, so no disjunctions.)
- b_L is a derived variable (axiom: b_{L-1} = 1 and p_L ⇒ b_L), i.e. the whole sequence ends
  at the current state. Every operator gets the precondition b_L = 0 and the goal gets b_L = 0.

So a plan is valid for the new task iff it is valid for the old one and no s_i ⊇ p_0, ...,
s_{i+L} ⊇ p_L occurs (Proposition 7.1). This is the paper's compilation shifted by one state:
the paper's b_l "becomes true when a makes p_l true" needs p_l evaluated in the successor state,
which a SAS+ condition cannot see when p_l mentions a derived variable or a variable under a
conditional effect; the paper's reset b_{l-1} := 0 also loses overlapping matches
(e.g. <X, X, Y> on X X X Y). Evaluating p_l in the current state (with axioms) avoids both.
"""
from __future__ import annotations

from dataclasses import replace
from typing import Iterable, Sequence

from gnppdsl.compile.sas import Axiom, Effect, Fact, PartialState, SASTask, SASVariable

BOOL = ("false", "true")


def _fails(task: SASTask, p: PartialState) -> list[Fact]:
    """Facts each of which alone makes `p` false: (v, y) for (v, x) in p and every y != x."""
    return [(v, y) for v, x in p.facts for y in range(len(task.variables[v].values)) if y != x]


def _fresh_prefix(task: SASTask) -> str:
    names = {v.name for v in task.variables}
    k = 0
    while any(n.startswith(f"forbid{k}_") for n in names):
        k += 1
    return f"forbid{k}"


def forbid_sequence(task: SASTask, seq: Sequence[PartialState], prefix: str | None = None) -> SASTask:
    """A new task whose plans are those of `task` in which <p_0 .. p_L> never occurs."""
    seq = tuple(seq)
    if not seq:
        raise ValueError("a conflict needs at least one partial state")
    for p in seq:
        for v, x in p.facts:
            if not (0 <= v < len(task.variables) and 0 <= x < len(task.variables[v].values)):
                raise ValueError(f"fact ({v}, {x}) is not a fact of task {task.name}")
    prefix = prefix or _fresh_prefix(task)
    L = len(seq) - 1
    n = len(task.variables)
    b = [n + l for l in range(L + 1)]                # indices of b_0 .. b_L
    layer = 1 + max((task.variables[v].axiom_layer for p in seq for v, _ in p.facts), default=-1)
    layer = max(layer, 0)
    variables = list(task.variables)
    variables += [SASVariable(f"{prefix}_b{l}", BOOL) for l in range(L)]
    variables.append(SASVariable(f"{prefix}_b{L}", BOOL, axiom_layer=layer))

    extra: list[Effect] = []
    for l in range(L):
        p = seq[l]
        guard = () if l == 0 else ((b[l - 1], 1),)
        extra.append(Effect(b[l], 1, guard + p.facts))
        if l > 0:
            extra.append(Effect(b[l], 0, ((b[l - 1], 0),)))
        extra.extend(Effect(b[l], 0, (f,)) for f in _fails(task, p))
    guard = () if L == 0 else ((b[L - 1], 1),)
    axiom = Axiom(guard + seq[L].facts, b[L], 1)

    operators = [
        replace(op, pre=tuple(op.pre) + ((b[L], 0),), effects=tuple(op.effects) + tuple(extra))
        for op in task.operators
    ]
    return SASTask(
        variables=variables,
        initial=tuple(task.initial) + (0,) * (L + 1),
        goal=task.goal.union(PartialState(((b[L], 0),))),
        operators=operators,
        axioms=list(task.axioms) + [axiom],
        pair_costs=dict(task.pair_costs),
        name=task.name,
    )


def forbid_sequences(task: SASTask, seqs: Iterable[Sequence[PartialState]]) -> SASTask:
    """Forbid several conflicts by iterated reformulation (paper: "iterative reformulation")."""
    for seq in seqs:
        task = forbid_sequence(task, seq)       # fresh variable names per conflict
    return task


def transition_conditions(task: SASTask, seq: Sequence[PartialState]) -> list[tuple[Fact, ...] | None] | None:
    """For a conflict <p_0, p_1> (L = 1): per operator o, the condition C_o on a state s under
    which applying o in s completes the conflict (p_0 ⊆ s and p_1 ⊆ s[o]), or None where o never
    does. C_o is p_0 plus the facts of p_1 that o does not set (o must set p_1's other
    variables to p_1's values: an unconditional effect to another value means "never").
    None for the whole conflict when s alone does not decide it: L != 1, a derived fact in p_1
    (its successor value depends on axioms) or a conditional effect on a variable of p_1."""
    if len(seq) != 2:
        return None
    p0, p1 = seq
    if any(task.variables[v].axiom_layer >= 0 for v, _ in p1.facts):
        return None
    out: list[tuple[Fact, ...] | None] = []
    for op in task.operators:
        uncond = {e.var: e.value for e in op.effects if not e.conditions}
        if any(e.conditions and e.var in p1.as_dict() for e in op.effects):
            return None
        cond: dict[int, int] = dict(p0.facts)
        never = False
        for v, x in p1.facts:
            if v in uncond:
                never |= uncond[v] != x
            elif cond.setdefault(v, x) != x:
                never = True
        pre = dict(op.pre)
        never = never or any(v in pre and pre[v] != x for v, x in cond.items())
        out.append(None if never else tuple(sorted(cond.items())))
    return out


def forbid_transition(task: SASTask, seq: Sequence[PartialState], prefix: str | None = None) -> SASTask | None:
    """A new task whose plans are those of `task` in which <p_0, p_1> never occurs, for a
    conflict of length 2 that `transition_conditions` decides (else None: use `forbid_sequence`).

    Why: a match of <p_0, p_1> at s_i, s_{i+1} is one transition, the operator a_{i+1} applied in
    s_i, and whether it completes the conflict is a condition C_o on s_i alone
    (`transition_conditions`). So each operator o gets the precondition d_C = 0 for a derived
    variable d_C := C_o (one per distinct C, shared by the operators with that condition), and
    nothing else changes: no state variables and no conditional effects. Appendix B's b_0 needs
    1 + sum(|dom(v)| - 1) conditional effects on *every* operator to follow p_0; Fast Downward's
    FF evaluates them all in every state (lab5_paper with 7 such conflicts: 88 effects per
    operator, 3 ms per evaluated state, 10 s per search). The last state needs no check (no
    transition leaves it), so the goal is unchanged. Exactly the plans of Proposition 7.1 remain.
    """
    seq = tuple(seq)
    conds = transition_conditions(task, seq)
    if conds is None:
        return None
    prefix = prefix or _fresh_prefix(task)
    variables, axioms = list(task.variables), list(task.axioms)
    heads: dict[tuple[Fact, ...], int] = {}
    operators = []
    for op, cond in zip(task.operators, conds):
        if cond is not None:
            if cond not in heads:
                heads[cond] = len(variables)
                layer = max(0, 1 + max((task.variables[v].axiom_layer for v, _ in cond), default=-1))
                variables.append(SASVariable(f"{prefix}_t{len(heads) - 1}", BOOL, axiom_layer=layer))
                axioms.append(Axiom(cond, heads[cond], 1))
            op = replace(op, pre=tuple(op.pre) + ((heads[cond], 0),))
        operators.append(op)
    return SASTask(
        variables=variables,
        initial=tuple(task.initial) + (0,) * len(heads),
        goal=task.goal,
        operators=operators,
        axioms=axioms,
        pair_costs=dict(task.pair_costs),
        name=task.name,
    )


def forbid_compact(task: SASTask, seqs: Iterable[Sequence[PartialState]]) -> tuple[SASTask, list[int | None]]:
    """Forbid several conflicts, each by `forbid_transition` where it applies, else by Appendix B
    (`forbid_sequence`); and per conflict the variable b_L of its Appendix-B compilation (None
    for a transition), which `fd_guidance` needs."""
    heads: list[int | None] = []
    for seq in seqs:
        compiled = forbid_transition(task, seq)
        if compiled is None:
            compiled = forbid_sequence(task, seq)
            heads.append(len(compiled.variables) - 1)
        else:
            heads.append(None)
        task = compiled
    return task, heads


def forbid_plan(task: SASTask, ops: Sequence[int], prefix: str | None = None) -> SASTask:
    """A new task whose plans are those of `task` except exactly the operator sequence `ops`.

    Why: a blocked plan (the One-way baseline, or a plan the loop gives up without a conflict)
    forbids one operator sequence, not a sequence of partial states, so Appendix B does not
    express it; Fast Downward needs it inside the task. A state variable m in {0 .. n, off}
    follows how much of `ops` = <a_1 .. a_n> the plan has executed: operator o sets m := i + 1
    where m = i and o = a_{i+1}, and m := off otherwise (one conditional effect per value).
    A derived variable (axiom: m = n) must be false in the goal, so a plan is forbidden iff it
    is exactly `ops`; a longer plan starting with `ops` moves m to off and stays allowed.
    """
    ops = tuple(ops)
    if any(not 0 <= o < len(task.operators) for o in ops):
        raise ValueError(f"plan refers to unknown operators: {ops}")
    prefix = prefix or _fresh_prefix(task)
    n = len(ops)
    m, done = len(task.variables), len(task.variables) + 1
    off = n + 1
    variables = list(task.variables)
    variables.append(SASVariable(f"{prefix}_m", tuple(str(i) for i in range(n + 1)) + ("off",)))
    variables.append(SASVariable(f"{prefix}_done", BOOL, axiom_layer=0))
    operators = []
    for o, op in enumerate(task.operators):
        extra = []
        for i in range(n + 1):
            nxt = i + 1 if i < n and ops[i] == o else off
            extra.append(Effect(m, nxt, ((m, i),)))
        operators.append(replace(op, effects=tuple(op.effects) + tuple(extra)))
    return SASTask(
        variables=variables,
        initial=tuple(task.initial) + (0, 0),
        goal=task.goal.union(PartialState(((done, 0),))),
        operators=operators,
        axioms=list(task.axioms) + [Axiom(((m, n),), done, 1)],
        pair_costs=dict(task.pair_costs),
        name=task.name,
    )
