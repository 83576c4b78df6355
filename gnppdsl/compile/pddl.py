"""Write a `SASTask` as a PDDL domain + problem.

Why from the grounded task and not from the lifted IR: the SAS+ task is the single source of
truth every planner in this project sees (ASP encoding, Appendix-B reformulation, `.sas`), so
the PDDL is guaranteed to describe the *same* transition system, including tasks that were
reformulated after conflicts. It stays readable because state variables keep their structure:
the SAS+ fact `parent(b1) = s1` becomes the atom `(parent b1 s1)`, the boolean `free(g)`
becomes `(free g)`. Actions are ground (no parameters) and named after the operator
(`pick(b1, g, s1)` -> `pick_b1_g_s1`); `PDDLOutput.action_names` maps them back. Used for tasks
reformulated with conflicts and `gnpp compile --emit pddl-ground`; the lifted domain as written
is `gnppdsl.compile.pddl_lifted`.

Encoding (sound and complete for SAS+ semantics):
- multi-valued variable v with value x: atom `(f args x)`; assigning x adds it and deletes the
  atoms of every other value of v.
- boolean variable (values false/true): atom `(f args)` true iff the value is "true"; testing
  "false" is a negative precondition.
- derived variable: a 0-ary derived predicate, one disjunct per axiom; testing value 0 is a
  negated derived atom (FD's translator and the `pddl` package both accept that);
  `:derived-predicates` is required only when the task has axioms.
- action costs through `total-cost`.
"""
from __future__ import annotations

import re
from dataclasses import dataclass

from gnppdsl.compile.sas import Fact, SASTask

__all__ = ["PDDLOutput", "write_pddl", "pddl_name"]

_RESERVED = {
    "and", "or", "not", "when", "forall", "exists", "imply", "either", "object", "define",
    "domain", "problem", "increase", "decrease", "assign", "minimize", "maximize",
    "total-cost", "number", "oneof", "scale-up", "scale-down",
}
_CALL = re.compile(r"^([A-Za-z_][A-Za-z0-9_.]*)\((.*)\)$")


def pddl_name(text: str) -> str:
    """A legal PDDL name (letter first, then letters, digits, `_`, `-`), lower case."""
    name = re.sub(r"[^a-z0-9_-]+", "_", text.lower()).strip("_")
    name = re.sub(r"__+", "_", name)
    if not name or not name[0].isalpha():
        name = "x" + ("_" + name if name else "")
    if name in _RESERVED:
        name = "x_" + name
    return name


class _Namer:
    """Injective map from our names to PDDL names within one namespace."""

    def __init__(self) -> None:
        self.forward: dict[object, str] = {}
        self.used: set[str] = set()

    def __call__(self, key: object, text: str) -> str:
        if key in self.forward:
            return self.forward[key]
        base = name = pddl_name(text)
        n = 1
        while name in self.used:
            n += 1
            name = f"{base}-{n}"
        self.used.add(name)
        self.forward[key] = name
        return name


@dataclass
class PDDLOutput:
    domain: str
    problem: str
    action_names: dict[str, str]     # PDDL action name -> operator name in DSL syntax


def _split_call(name: str) -> tuple[str, list[str]] | None:
    m = _CALL.match(name.strip())
    if not m:
        return (name, []) if re.match(r"^[A-Za-z_][A-Za-z0-9_.]*$", name.strip()) else None
    args = [a.strip() for a in m.group(2).split(",")] if m.group(2).strip() else []
    if any(not re.match(r"^[A-Za-z_][A-Za-z0-9_]*$", a) for a in args):
        return None
    return m.group(1), args


class _Encoder:
    def __init__(self, task: SASTask) -> None:
        self.task = task
        self.preds = _Namer()
        self.objects = _Namer()
        self.pred_arity: dict[str, int] = {}
        self.var_atom: dict[int, tuple[str, list[str], bool]] = {}   # var -> (pred, args, boolean)
        for i, var in enumerate(task.variables):
            boolean = var.values == ("false", "true")
            parts = None if var.is_derived else _split_call(var.name)
            if parts is None:
                fn, args = var.name, []
                key: object = ("var", i)
            else:
                fn, args = parts
                key = ("fn", fn, len(args), boolean)
            pred = self.preds(key, fn)
            arg_names = [self.objects(a, a) for a in args]
            self.pred_arity[pred] = len(args) + (0 if boolean else 1)
            self.var_atom[i] = (pred, arg_names, boolean)
            if not boolean:
                for val in var.values:
                    self.objects(val, val)

    def atom(self, var: int, value: int) -> tuple[str, bool]:
        """(atom text, positive) for a fact."""
        pred, args, boolean = self.var_atom[var]
        if boolean:
            return "(" + " ".join([pred, *args]) + ")", value == 1
        val = self.objects.forward[self.task.variables[var].values[value]]
        return "(" + " ".join([pred, *args, val]) + ")", True

    def literal(self, fact: Fact) -> str:
        text, positive = self.atom(*fact)
        return text if positive else f"(not {text})"

    def conjunction(self, facts) -> str:
        lits = [self.literal(f) for f in facts]
        if len(lits) == 1:
            return lits[0]
        return "(and " + " ".join(lits) + ")"

    def assignment(self, var: int, value: int) -> list[str]:
        pred, args, boolean = self.var_atom[var]
        if boolean:
            text, positive = self.atom(var, 1)
            return [text if value == 1 else f"(not {text})"]
        out = [self.atom(var, value)[0]]
        out += [f"(not {self.atom(var, w)[0]})"
                for w in range(len(self.task.variables[var].values)) if w != value]
        return out


def write_pddl(task: SASTask, name: str | None = None) -> PDDLOutput:
    enc = _Encoder(task)
    dname = pddl_name(name or task.name)
    actions = _Namer()
    action_names: dict[str, str] = {}

    body: list[str] = []
    # derived predicates: one disjunct per axiom
    by_head: dict[int, list[str]] = {}
    for ax in task.axioms:
        by_head.setdefault(ax.var, []).append(
            enc.conjunction(ax.conditions) if ax.conditions else "(and)")
    for var, disjuncts in sorted(by_head.items()):
        head = enc.atom(var, 1)[0]
        cond = disjuncts[0] if len(disjuncts) == 1 else "(or " + " ".join(disjuncts) + ")"
        body.append(f"  (:derived {head}\n    {cond})")

    scale = task.cost_scale()
    for i, op in enumerate(task.operators):
        aname = actions(i, op.name)
        action_names[aname] = op.name
        pre = enc.conjunction(op.pre) if op.pre else "(and)"
        effs: list[str] = []
        for eff in op.effects:
            parts = enc.assignment(eff.var, eff.value)
            if eff.conditions:
                effs.append(f"(when {enc.conjunction(eff.conditions)} (and {' '.join(parts)}))")
            else:
                effs.extend(parts)
        effs.append(f"(increase (total-cost) {task.integer_cost(op.cost, scale)})")
        body.append(f"  (:action {aname}\n    :parameters ()\n    :precondition {pre}\n"
                    f"    :effect (and {' '.join(effs)}))")

    preds = []
    for pred, arity in enc.pred_arity.items():
        preds.append("(" + " ".join([pred] + [f"?a{k}" for k in range(arity)]) + ")")
    constants = sorted(set(enc.objects.forward.values()))
    derived = " :derived-predicates" if task.axioms else ""
    head = [f"(define (domain {dname})",
            "  (:requirements :strips :negative-preconditions :disjunctive-preconditions "
            f":conditional-effects{derived} :action-costs)"]
    if constants:
        head.append("  (:constants " + " ".join(constants) + ")")
    head.append("  (:predicates " + " ".join(preds) + ")")
    head.append("  (:functions (total-cost) - number)")
    domain = "\n".join(head + body) + "\n)\n"

    init = []
    for i, var in enumerate(task.variables):
        if var.is_derived:
            continue
        text, positive = enc.atom(i, task.initial[i])
        if positive:
            init.append(text)
    init.append("(= (total-cost) 0)")
    goal = enc.conjunction(task.goal.facts) if task.goal.facts else "(and)"
    problem = (f"(define (problem {pddl_name(task.name + '-problem')})\n  (:domain {dname})\n"
               f"  (:init {' '.join(init)})\n  (:goal {goal})\n"
               f"  (:metric minimize (total-cost))\n)\n")
    return PDDLOutput(domain, problem, action_names)
