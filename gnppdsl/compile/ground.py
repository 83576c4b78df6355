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
    "substitute", "ground_rules", "error_at", "MARKER", "FINAL", "RuleMatcher",
]

MARKER = m.RESERVED_LOGIC_NAMES[0]
"""Name of the marker variable (values false/true, true only in s_0) used by `initial` rules."""
FINAL = m.RESERVED_LOGIC_NAMES[1]
"""Name of the derived variable (true iff the goal holds: only in s_n) used by `final` rules."""
_MARKERS = {"initial": MARKER, "final": FINAL}
_KINDS = ("state", "transition", "always", "initial", "final")


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


def operator_name(action: str, params: Sequence[m.TypedParam], binding: Binding) -> str:
    """The ground operator's name, `pick(b1, g, s1)`: what the planners, plans and conflicts
    show, and how a later pass (`costs.ground_travel_costs`) finds an operator's binding."""
    return f"{action}({', '.join(binding[q.name] for q in params)})"


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
        if rule.kind not in _KINDS:
            raise error_at(rule.span, f"unknown rule kind '{rule.kind}'")
        pre_lits = rule.pre
        if rule.kind in _MARKERS and _MARKERS[rule.kind] not in look.index:
            raise error_at(rule.span, f"task has no `{rule.kind}` marker variable")
        for binding in bindings(problem, rule.params, rule.where):
            pre = look.partial_state(pre_lits, binding)
            if pre is None:
                continue
            if rule.kind in _MARKERS:
                pre = pre.union(PartialState.of([(look.index[_MARKERS[rule.kind]], 1)]))
            post = None
            if rule.kind == "transition":
                post = look.partial_state(rule.post, binding)
                if post is None:
                    continue
            calls = tuple(substitute(c, binding) for c in rule.calls)
            out.append(GroundRule(rule, tuple(binding.items()), pre, post, calls))
    return out


# --------------------------------------------------------------------------------------------
# Rules grounded on demand
# --------------------------------------------------------------------------------------------
class RuleMatcher:
    """The ground rules whose patterns hold at a step, grounded on demand from the states.

    Why not `ground_rules` up front: a rule over several objects is grounded for every binding
    although a graph-NLP only ever needs those whose pattern holds in the plan's states. On a
    planar problem with 80 blocks the kinematic-switch rule `parent(o) = p -> parent(o) = p2`
    alone has 80 * 83 * 82 = 544k bindings: eager grounding took 16 s and 700 MB before the
    first plan, for a two-action goal that uses one of them. Here a rule's parameters are bound
    by matching its pattern literals against s_i (and s_{i+1}): a literal whose arguments are
    bound reads its value from the state (binding a value parameter), one with unbound
    arguments enumerates them (objects of their types, linear). Only `always` rules without a
    pattern enumerate all their bindings, once.

    Same result as `ground_rules` filtered by `pre ⊆ s_i` (and `post ⊆ s_{i+1}`), in the same
    order (rules in declaration order, bindings in object order): tested against it. Each
    ground rule is made once and kept (`key` identifies it across steps and plans)."""

    def __init__(self, problem: m.Problem, task: SASTask) -> None:
        self.problem = problem
        self.look = _FactLookup(task)
        self.task = task
        self.rules = list(problem.domain.rules)
        self.domains = [{p.name: problem.objects_of(p.types) for p in r.params} for r in self.rules]
        self.position = [{p.name: {o: k for k, o in enumerate(d[p.name])} for p in r.params}
                         for r, d in zip(self.rules, self.domains)]
        self._ground: dict[tuple, GroundRule | None] = {}
        self._static: dict[int, list[tuple]] = {}        # rule -> bindings of pattern-free rules
        for rule in self.rules:
            if rule.kind not in _KINDS:
                raise error_at(rule.span, f"unknown rule kind '{rule.kind}'")
            if rule.kind in _MARKERS and _MARKERS[rule.kind] not in self.look.index:
                raise error_at(rule.span, f"task has no `{rule.kind}` marker variable")
            for lit in tuple(rule.pre) + tuple(rule.post):
                if isinstance(lit, m.StateLit) and lit.negated:
                    raise error_at(lit.span, "rule patterns are conjunctions of "
                                            "`var = value` facts; '!=' is not allowed here")

    def matching(self, states: Sequence[Sequence[int]], i: int) -> list[tuple[tuple, GroundRule]]:
        """(key, ground rule) for every ground rule whose pattern holds at step i of the full
        states (derived values included): p ⊆ s_i, and p' ⊆ s_{i+1} for transition rules
        (none at the last step)."""
        n = len(states) - 1
        out: list[tuple[tuple, GroundRule]] = []
        for r, rule in enumerate(self.rules):
            if rule.kind == "transition" and i == n:
                continue
            if rule.kind in _MARKERS and states[i][self.look.index[_MARKERS[rule.kind]]] != 1:
                continue
            nxt = states[i + 1] if rule.kind == "transition" else None
            for key in self._bindings(r, states[i], nxt):
                gr = self._rule(r, key)
                if gr is not None and gr.pre.holds_in(states[i]) and (
                        gr.post is None or gr.post.holds_in(states[i + 1])):
                    out.append((key, gr))
        return out

    def _rule(self, r: int, key: tuple) -> GroundRule | None:
        if key in self._ground:
            return self._ground[key]
        rule = self.rules[r]
        binding = dict(key[1])
        gr = None
        pre = self.look.partial_state(rule.pre, binding)
        if pre is not None:
            if rule.kind in _MARKERS:
                pre = pre.union(PartialState.of([(self.look.index[_MARKERS[rule.kind]], 1)]))
            post = None
            if rule.kind == "transition":
                post = self.look.partial_state(rule.post, binding)
            if rule.kind != "transition" or post is not None:
                gr = GroundRule(rule, key[1], pre, post, tuple(substitute(c, binding) for c in rule.calls))
        self._ground[key] = gr
        return gr

    def _bindings(self, r: int, s0: Sequence[int], s1: Sequence[int] | None) -> list[tuple]:
        """Keys (r, binding items in parameter order) of the bindings that satisfy the pattern
        in (s0, s1) and the `where` guards, sorted as `bindings` enumerates them."""
        rule = self.rules[r]
        lits = [(lit, s0) for lit in rule.pre] + [(lit, s1) for lit in rule.post if s1 is not None]
        if not lits:
            if r not in self._static:
                self._static[r] = [(r, tuple(b.items()))
                                   for b in bindings(self.problem, rule.params, rule.where)]
            return self._static[r]
        partial: list[dict[str, str]] = [{}]
        for lit, state in lits:
            partial = [b2 for b in partial for b2 in self._extend(r, lit, state, b)]
            if not partial:
                return []
        names = [p.name for p in rule.params]
        full: list[dict[str, str]] = []
        for b in partial:
            free = [n for n in names if n not in b]
            for combo in product(*(self.domains[r][n] for n in free)):
                full.append({**b, **dict(zip(free, combo))})
        pos = self.position[r]
        full = [b for b in full if all(compare_holds(self.problem, g, b) for g in rule.where)]
        full.sort(key=lambda b: tuple(pos[n][b[n]] for n in names))
        return [(r, tuple((n, b[n]) for n in names)) for b in full]

    def _extend(self, r: int, lit, state: Sequence[int], b: dict[str, str]) -> Iterator[dict[str, str]]:
        """Extensions of the partial binding `b` under which `lit` holds in `state`."""
        args = lit.args
        free = list(dict.fromkeys(a.name for a in args if isinstance(a, Param) and a.name not in b))
        for combo in product(*(self.domains[r][n] for n in free)):
            b2 = {**b, **dict(zip(free, combo))} if free else b
            name = var_name(lit.var if isinstance(lit, m.StateLit) else lit.pred,
                            [term_name(a, b2) for a in args])
            v = self.look.index.get(name)
            if v is None:
                continue
            if isinstance(lit, m.DerivedLit):
                if state[v] == (0 if lit.negated else 1):
                    yield b2
                continue
            value = self.task.variables[v].values[state[v]]
            t = lit.value
            if isinstance(t, Param) and t.name not in b2:
                if value in self.position[r][t.name]:
                    yield {**b2, t.name: value}
            elif term_name(t, b2) == value:
                yield b2
