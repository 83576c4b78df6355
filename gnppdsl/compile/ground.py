"""Grounding: bind the parameters of actions, derived predicates and rules to problem objects.

Why a module of its own: the SAS+ task builder (`gnppdsl.compile.task`) and the graph-NLP
factory (`gnppdsl.compile.factory`) both need the same notion of "all bindings of these typed
parameters satisfying these static guards", and the same substitution of `Param` by `Obj`.
Rules (the map Π) are grounded here into `GroundRule`s whose patterns are partial states of a
given `SASTask`, so the factory only has to test `p ⊆ s_i` per step.
"""
from __future__ import annotations

from dataclasses import dataclass, fields, is_dataclass, replace
from itertools import product
from typing import Iterator, Sequence

from gnppdsl.compile.sas import Fact, PartialState, SASTask
from gnppdsl.errors import UserError
from gnppdsl.ir import model as m
from gnppdsl.ir.expr import Obj, Param, Span

Binding = dict[str, str]

__all__ = [
    "Binding", "GroundRule", "bindings", "term_name", "var_name", "compare_holds",
    "substitute", "ground_rules", "error_at", "MARKER",
]

MARKER = "initial"
"""Name of the marker variable (values false/true, true only in s_0) used by `initial` rules."""


def error_at(span: Span | None, message: str) -> UserError:
    """A user error located at `span`: a `DiagnosticError` (file:line:col, the source line and
    a caret) when the span is known, else a plain `UserError`."""
    if span is None:
        return UserError(message)
    from gnppdsl.lang.diagnostics import Diagnostic, DiagnosticError

    return DiagnosticError([Diagnostic(message, span, kind="compile")])


def var_name(name: str, args: Sequence[str]) -> str:
    """The SAS+ variable name of a ground state variable or derived atom: `parent(b1)`."""
    return f"{name}({', '.join(args)})" if args else name


def term_name(term, binding: Binding) -> str:
    """The object (or builtin value) a logic term denotes under `binding`."""
    if isinstance(term, Obj):
        return term.name
    if isinstance(term, Param):
        if term.name not in binding:
            raise error_at(term.span, f"unbound variable '{term.name}'")
        return binding[term.name]
    raise error_at(getattr(term, "span", None), f"not a logic term: {term!r}")


def compare_holds(problem: m.Problem, cmp: m.Compare, binding: Binding) -> bool:
    """Evaluate a static comparison. Ordering uses declaration order (symmetry breaking)."""
    a, b = term_name(cmp.lhs, binding), term_name(cmp.rhs, binding)
    if cmp.op == "=":
        return a == b
    if cmp.op == "!=":
        return a != b
    try:
        ia, ib = problem.object_index(a), problem.object_index(b)
    except ValueError:
        raise error_at(cmp.span, f"'{cmp.op}' compares objects, got '{a}' and '{b}'")
    return {"<": ia < ib, "<=": ia <= ib, ">": ia > ib, ">=": ia >= ib}[cmp.op]


def bindings(problem: m.Problem, params: Sequence[m.TypedParam],
             guards: Sequence[m.Compare] = ()) -> Iterator[Binding]:
    """Every assignment of objects (of the allowed types) to `params` satisfying `guards`,
    in declaration order of the objects (deterministic)."""
    names = [p.name for p in params]
    domains = [problem.objects_of(p.types) for p in params]
    for combo in product(*domains):
        binding = dict(zip(names, combo))
        if all(compare_holds(problem, g, binding) for g in guards):
            yield binding


def substitute(node, binding: Binding):
    """Replace every bound `Param` by `Obj` inside a (frozen dataclass) IR tree.

    Unbound parameters (template parameters, `exists` variables, forall indices) stay."""
    if isinstance(node, Param):
        return Obj(binding[node.name], span=node.span) if node.name in binding else node
    if isinstance(node, tuple):
        return tuple(substitute(x, binding) for x in node)
    if is_dataclass(node) and not isinstance(node, type):
        changes = {}
        for f in fields(node):
            if f.name == "span":
                continue
            old = getattr(node, f.name)
            if isinstance(old, (tuple,)) or is_dataclass(old):
                new = substitute(old, binding)
                if new is not old:
                    changes[f.name] = new
        return replace(node, **changes) if changes else node
    return node


# --------------------------------------------------------------------------------------------
# Rules
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class GroundRule:
    """One binding of a rule: its pattern p (and p') as partial states of the task, and its
    template calls with the rule parameters substituted (stage-1 expressions over `Obj`)."""

    rule: m.Rule
    binding: tuple[tuple[str, str], ...]
    pre: PartialState
    post: PartialState | None           # None unless the rule is a transition rule
    calls: tuple[m.TemplateCall, ...]

    @property
    def name(self) -> str:
        return self.rule.name

    @property
    def span(self) -> int:
        return 2 if self.rule.kind == "transition" else 1


class _FactLookup:
    def __init__(self, task: SASTask) -> None:
        self.task = task
        self.index = {v.name: i for i, v in enumerate(task.variables)}

    def fact(self, lit, binding: Binding) -> Fact | None:
        """The fact of a positive pattern literal, None if it can never hold."""
        if isinstance(lit, m.DerivedLit):
            name = var_name(lit.pred, [term_name(a, binding) for a in lit.args])
            i = self.index.get(name)
            return None if i is None else (i, 0 if lit.negated else 1)
        if isinstance(lit, m.StateLit):
            if lit.negated:
                raise error_at(lit.span, "rule patterns are conjunctions of "
                                        "`var = value` facts; '!=' is not allowed here")
            name = var_name(lit.var, [term_name(a, binding) for a in lit.args])
            i = self.index.get(name)
            if i is None:
                return None
            value = term_name(lit.value, binding)
            values = self.task.variables[i].values
            return (i, values.index(value)) if value in values else None
        raise error_at(getattr(lit, "span", None), f"unsupported pattern literal {lit!r}")

    def partial_state(self, lits, binding: Binding) -> PartialState | None:
        facts: dict[int, int] = {}
        for lit in lits:
            f = self.fact(lit, binding)
            if f is None or facts.get(f[0], f[1]) != f[1]:
                return None
            facts[f[0]] = f[1]
        return PartialState.of(facts)


def ground_rules(problem: m.Problem, task: SASTask) -> list[GroundRule]:
    """All ground rules whose patterns can hold (type-compatible values, consistent facts)."""
    look = _FactLookup(task)
    out: list[GroundRule] = []
    for rule in problem.domain.rules:
        if rule.kind not in ("state", "transition", "always", "initial"):
            raise error_at(rule.span, f"unknown rule kind '{rule.kind}'")
        pre_lits = rule.pre
        if rule.kind == "initial":
            if MARKER not in look.index:
                raise error_at(rule.span, "task has no `initial` marker variable")
        for binding in bindings(problem, rule.params, rule.where):
            pre = look.partial_state(pre_lits, binding)
            if pre is None:
                continue
            if rule.kind == "initial":
                pre = pre.union(PartialState.of([(look.index[MARKER], 1)]))
            post = None
            if rule.kind == "transition":
                post = look.partial_state(rule.post, binding)
                if post is None:
                    continue
            calls = tuple(substitute(c, binding) for c in rule.calls)
            out.append(GroundRule(rule, tuple(binding.items()), pre, post, calls))
    return out
