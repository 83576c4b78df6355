"""ASP encoding of a compiled SAS+ task for clingo's multi-shot incremental solving.

Why generated: the encoding is the task's facts (variables, operators, axioms, goal, costs as
integers) plus one domain-independent set of rules, so no domain is ever hand-encoded. The rules
follow clingo's `incmode` layout (`base`, `step(t)`, `check(t)`, `#external query(t)`), so the
text written by `gnpp compile --emit asp` also runs stand-alone with `clingo FILE`.

Atoms
- `holds(V,X,T)`: variable V has value X in state s_T (derived variables included);
- `occurs(O,T)`: operator O is the T-th action (T = 1..n), exactly one per non-idle step;
- `idle(T)`: step T does nothing (only a suffix of steps; used for "cheapest plan up to H"
  and to cut a horizon shorter than the grounded one). Idle needs `allow_idle` or `after(T)`,
  both externals that are false unless the planner sets them, so the stand-alone program
  is the plain sequential encoding.
- costs: `#minimize` over `cost(O,C)` and pair costs, active only with external `minimize_cost`.

Conflicts (paper 000, Prop. 7.1) are separate step-parameterised programs (`conflict_program`):
a constraint over the step parameter t must be grounded for every existing and every future
step, because a rule grounded once does not see atoms of later steps. (Blocked plans refer to
fixed steps only; the planner adds them as nogoods through clingo's backend.)
"""
from __future__ import annotations

from typing import Sequence

from gnppdsl.compile.sas import PartialState, SASTask

_RULES_BASE = """\
#program base.
% predicates a task may leave empty
#defined svar/1. #defined dvar/1. #defined goal/2. #defined op/1. #defined cost/2. #defined pre/3.
#defined eff/3. #defined ceff/4. #defined cond/3. #defined clash/2. #defined uclash/1.
#defined pcost/3. #defined pcost0/2. #defined axiom/3. #defined acond/3.
#defined mutex/4. #defined unreachable/2.
#external allow_idle.
#external minimize_cost.
holds(V,X,0) :- init(V,X).
"""

_RULES_STEP = """\
#program step(t).
#external after(t).
{ idle(t) } :- allow_idle.
idle(t) :- after(t).
idle(t) :- idle(t-1).
1 { occurs(O,t) : op(O) } 1 :- not idle(t).
:- occurs(O,t), pre(O,V,X), not holds(V,X,t-1).
holds(V,X,t) :- occurs(O,t), eff(O,V,X).
changed(V,t) :- occurs(O,t), eff(O,V,_).
fires(E,t) :- occurs(O,t), ceff(E,O,_,_), holds(C,Y,t-1) : cond(E,C,Y).
holds(V,X,t) :- fires(E,t), ceff(E,_,V,X).
changed(V,t) :- fires(E,t), ceff(E,_,V,_).
:- fires(E,t), fires(F,t), clash(E,F).
:- fires(E,t), uclash(E).
holds(V,X,t) :- holds(V,X,t-1), svar(V), not changed(V,t).
:- mutex(V,X,W,Y), holds(V,X,t), holds(W,Y,t).
:- unreachable(V,X), holds(V,X,t).
#minimize { C@0,t,op : occurs(O,t), cost(O,C), minimize_cost }.
#minimize { C@0,t,pair : occurs(P,t-1), occurs(O,t), pcost(P,O,C), minimize_cost }.
#minimize { C@0,t,first : occurs(O,t), pcost0(O,C), t = 1, minimize_cost }.
"""

_RULES_CHECK = """\
#program check(t).
#external query(t).
:- query(t), goal(V,X), not holds(V,X,t).
"""

# derived variables: default value 0, axioms set other values (value 1 for booleans)
_RULES_AXIOMS = """\
holds(D,X,{T}) :- axiom(A,D,X), holds(V,Y,{T}) : acond(A,V,Y).
holds(D,0,{T}) :- dvar(D), not holds(D,1,{T}).
"""

SHOW = "#show occurs/2.\n#show holds/3.\n#show idle/1.\n"


def task_facts(task: SASTask) -> str:
    """The task as ASP facts over integer indices (comments keep the names)."""
    out: list[str] = []
    add = out.append
    add("% variables")
    for i, var in enumerate(task.variables):
        kind = "dvar" if var.is_derived else "svar"
        add(f"{kind}({i}).  % {var.name}: {', '.join(f'{x}={n}' for x, n in enumerate(var.values))}")
    add("% initial state (state variables) and goal")
    for i, x in enumerate(task.initial):
        if not task.variables[i].is_derived:
            add(f"init({i},{x}).")
    for v, x in task.goal.facts:
        add(f"goal({v},{x}).")
    add("% operators")
    eid = 0
    scale = task.cost_scale()
    for o, op in enumerate(task.operators):
        uncond = {e.var: e.value for e in op.effects if not e.conditions}
        clash_uncond = any(
            e.var in uncond and uncond[e.var] != e.value for e in op.effects if not e.conditions
        )
        if clash_uncond:
            add(f"% {o}: {op.name} never applicable (contradictory effects)")
            continue
        add(f"op({o}).  % {op.name}")
        if task.integer_cost(op.cost, scale):
            add(f"cost({o},{task.integer_cost(op.cost, scale)}).")
        for v, x in op.pre:
            add(f"pre({o},{v},{x}).")
        cond_ids: list[tuple[int, int, int]] = []
        for e in op.effects:
            if not e.conditions:
                add(f"eff({o},{e.var},{e.value}).")
                continue
            add(f"ceff({eid},{o},{e.var},{e.value}).")
            for v, x in e.conditions:
                add(f"cond({eid},{v},{x}).")
            if e.var in uncond and uncond[e.var] != e.value:
                add(f"uclash({eid}).")
            for other, var, val in cond_ids:
                if var == e.var and val != e.value:
                    add(f"clash({other},{eid}).")
            cond_ids.append((eid, e.var, e.value))
            eid += 1
    if task.pair_costs:
        add("% costs of consecutive operator pairs")
        for (prev, o), c in sorted(task.pair_costs.items(), key=lambda kv: (kv[0][0] is not None, kv[0])):
            if c:
                c *= scale
                add(f"pcost0({o},{c})." if prev is None else f"pcost({prev},{o},{c}).")
    if task.axioms:
        add("% axioms")
        for a, ax in enumerate(task.axioms):
            if ax.value != 1:
                raise ValueError(f"axiom {a} must set {task.variables[ax.var].name} to 1 (true)")
            add(f"axiom({a},{ax.var},{ax.value}).")
            for v, x in ax.conditions:
                add(f"acond({a},{v},{x}).")
    return "\n".join(out) + "\n"


def mutex_facts(task: SASTask) -> str:
    """h^2 state invariants as facts (see `gnppdsl.logic.mutex`): they only cut unreachable
    states, but make proofs of "no plan of length n" much faster."""
    from gnppdsl.logic.mutex import mutexes

    unreachable, pairs = mutexes(task)
    out = ["% h^2 invariants: facts never reached, pairs of facts never true together"]
    out += [f"unreachable({v},{x})." for v, x in unreachable]
    out += [f"mutex({v},{x},{w},{y})." for (v, x), (w, y) in pairs]
    return "\n".join(out) + "\n"


def encode_task(task: SASTask, standalone: bool = False, invariants: bool = True) -> str:
    """The complete ASP program for `task` (facts + generic incremental rules).

    With `standalone=True` the text starts with `#include <incmode>.` (the clingo binary then
    finds a shortest plan by itself). `invariants` adds the h^2 mutexes.
    """
    _check_task(task)
    parts = []
    if standalone:
        parts.append(f"% {task.name}: run with `clingo FILE` (incremental mode)\n#include <incmode>.\n")
    parts.append(_RULES_BASE)
    parts.append(task_facts(task))
    parts.append(mutex_facts(task) if invariants else "% (no invariants)\n")
    parts.append(_RULES_AXIOMS.format(T=0))
    parts.append(_RULES_STEP)
    parts.append(_RULES_AXIOMS.format(T="t"))
    parts.append(_RULES_CHECK)
    parts.append(SHOW)
    return "\n".join(parts)


def conflict_program(name: str, seq: Sequence[PartialState]) -> str:
    """`#program NAME(t).` forbidding s_{t-L} ⊇ p_0, ..., s_t ⊇ p_L (ground it for every t).

    The match must end at a real (non-idle) state; `t >= L` keeps empty partial states sound.
    """
    L = len(seq) - 1
    if L < 0:
        raise ValueError("a conflict needs at least one partial state")
    body = []
    for l, p in enumerate(seq):
        off = L - l
        tt = "t" if off == 0 else f"t-{off}"
        body.extend(f"holds({v},{x},{tt})" for v, x in p.facts)
    body.extend(["not idle(t)", f"t >= {L}"])
    return f"#program {name}(t).\n:- {', '.join(body)}.\n"


def lifted_conflict_program(name: str, seqs: Sequence[Sequence[PartialState]]) -> tuple[str, str]:
    """One parameterised constraint for the instances of a lifted conflict (all of length L+1):
    (facts, step program). The facts `NAME_k(V1,X1,...,Vm,Xm)` list the instances, one relation
    per shape k (number of facts per partial state); the step program `#program NAME(t).` has one
    constraint per shape that joins a listed instance with the states s_{t-L} .. s_t, with the
    conditions of `conflict_program`. Ground the facts once and the step program for every t.

    Why a table and not one program per instance: the conflict is one piece of knowledge (the
    same infeasible NLP up to renaming symmetric objects, `gnppdsl.conflicts.lifting`); clingo
    grounds the join per step exactly as it would the separate constraints, and the program
    stays one rule per shape however many objects the conflict covers.
    """
    seqs = [tuple(s) for s in seqs]
    if not seqs or any(len(s) != len(seqs[0]) for s in seqs):
        raise ValueError("a lifted conflict needs instances of one length")
    L = len(seqs[0]) - 1
    if L < 0:
        raise ValueError("a conflict needs at least one partial state")
    shapes: dict[tuple[int, ...], list[tuple[PartialState, ...]]] = {}
    for s in seqs:
        shapes.setdefault(tuple(len(p.facts) for p in s), []).append(s)
    facts, rules = [], []
    for k, (shape, group) in enumerate(sorted(shapes.items())):
        rel = f"{name}_{k}"
        for s in group:
            args = [str(a) for p in s for f in p.facts for a in f]
            facts.append(f"{rel}({','.join(args)})." if args else f"{rel}.")
        head, body, j = [], [], 0
        for l, count in enumerate(shape):
            off = L - l
            tt = "t" if off == 0 else f"t-{off}"
            for _ in range(count):
                head += [f"V{j}", f"X{j}"]
                body.append(f"holds(V{j},X{j},{tt})")
                j += 1
        atom = f"{rel}({','.join(head)})" if head else rel
        rules.append(f":- {', '.join([atom] + body + ['not idle(t)', f't >= {L}'])}.")
    return "\n".join(facts) + "\n", f"#program {name}(t).\n" + "\n".join(rules) + "\n"


def _check_task(task: SASTask) -> None:
    """Reject tasks the encoding (and SAS+) cannot mean: wrong indices or derived defaults."""
    nvars = len(task.variables)
    if len(task.initial) != nvars:
        raise ValueError(f"initial state has {len(task.initial)} values for {nvars} variables")

    def ok(f) -> bool:
        v, x = f
        return 0 <= v < nvars and 0 <= x < len(task.variables[v].values)

    for i, x in enumerate(task.initial):
        if not ok((i, x)):
            raise ValueError(f"initial value {x} out of range for {task.variables[i].name}")
    bad = [f for f in task.goal.facts if not ok(f)]
    for op in task.operators:
        bad += [f for f in op.pre if not ok(f)]
        for e in op.effects:
            bad += [f for f in e.conditions if not ok(f)]
            bad += [] if ok((e.var, e.value)) else [(e.var, e.value)]
            if task.variables[e.var].is_derived:
                raise ValueError(f"operator {op.name} assigns derived variable {task.variables[e.var].name}")
    for ax in task.axioms:
        bad += [f for f in ax.conditions if not ok(f)]
        if not task.variables[ax.var].is_derived:
            raise ValueError(f"axiom sets state variable {task.variables[ax.var].name}")
    if bad:
        raise ValueError(f"facts out of range: {bad[:5]}")
