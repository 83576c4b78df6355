"""The logic of a domain or problem: terms, literals, formulas, effects and actions over the
state variables and derived predicates (`model.StateLit`, `Compare`, `Effect`, `Action`, ...).

Separate because it is used with two owners: a `DomainResolver` while a domain is resolved
(derived predicates, actions, rule patterns), and a finished `Domain` (through
`resolve_problem._DomainView`) for a problem's init and goal. It reads only `state_vars`,
`derived`, `constants`, `is_subtype`, `typed_params` and `err` of its owner.
"""
from __future__ import annotations

from typing import Protocol

from gnppdsl.ir import model as M
from gnppdsl.ir.expr import Obj, Param
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import did_you_mean


class LogicOwner(Protocol):
    """What `LogicResolver` reads of its owner: a `resolve_domain.DomainResolver`, or a
    problem's view of a finished domain (`resolve_problem._DomainView`, which has no
    `typed_params`: a problem declares no actions). A protocol, not the resolver's class,
    because the domain resolver imports this module (no import cycle)."""

    state_vars: dict[str, M.StateVar]
    derived: dict[str, M.Derived]
    constants: dict[str, str]

    def err(self, span, msg, kind="error", hint=None) -> None: ...

    def is_subtype(self, sub: str, sup: str) -> bool: ...

    def typed_params(self, params: tuple[ast.Param, ...], what: str, allow_untyped: bool = False,
                     allow_union: bool = False) -> tuple[M.TypedParam, ...]: ...


_FLIP = {"=": "!=", "!=": "=", "<": ">=", ">=": "<", ">": "<=", "<=": ">"}


class LogicResolver:
    """Literals, formulas, effects and actions over a domain's state variables."""

    def __init__(self, dom: LogicOwner, objects: dict[str, str] | None = None) -> None:
        self.d = dom
        self.objects = dict(dom.constants) if objects is None else objects

    def err(self, span, msg, kind="logic", hint=None):
        self.d.err(span, msg, kind, hint)

    def term(self, t: ast.LTerm, scope: dict[str, tuple[str, ...]]) -> tuple[object, tuple[str, ...]] | None:
        if t.args is not None:
            self.err(t.span, f"expected an object or a variable, got '{t.text()}'", "logic",
                     "state values cannot be nested; introduce a parameter")
            return None
        n = t.name.value
        if n in scope:
            return Param(n, t.span), scope[n]
        if n in self.objects:
            return Obj(n, t.span), (self.objects[n],)
        if n in M.BUILTIN_VALUES:
            return Obj(n, t.span), (n,)
        self.err(t.span, f"unknown object or variable '{n}'", "unknown-name",
                 did_you_mean(n, list(scope) + list(self.objects) + list(M.BUILTIN_VALUES)))
        return None

    def is_atom_name(self, t: ast.LTerm, scope) -> bool:
        n = t.name.value
        if t.args is not None:
            return True
        return n not in scope and n not in self.objects and n not in M.BUILTIN_VALUES and (
            n in self.d.state_vars or n in self.d.derived)

    def args(self, t: ast.LTerm, params: tuple[M.TypedParam, ...], scope, what: str):
        args = t.args or ()
        if len(args) != len(params):
            self.err(t.span, f"{what} '{t.name.value}' takes {len(params)} argument"
                     f"{'s' * (len(params) != 1)}, got {len(args)}", "arity")
            return None
        out = []
        for a, p in zip(args, params):
            r = self.term(a, scope)
            if r is None:
                return None
            term, types = r
            if p.types and not self.fits(types, p.types):
                self.err(a.span, f"'{a.text()}' ({' | '.join(types)}) is not {article(' | '.join(p.types))}",
                         "type", f"{what} '{t.name.value}' expects {' | '.join(p.types)} for '{p.name}'")
                return None
            out.append(term)
        return tuple(out)

    def fits(self, have: tuple[str, ...], want: tuple[str, ...]) -> bool:
        if not have:
            return True
        return all(any(self.d.is_subtype(h, w) or h == w for w in want) for h in have)

    def atom(self, t: ast.LTerm, scope):
        """(kind, name, args) for a state variable or derived predicate reference."""
        n = t.name.value
        if n in self.d.state_vars:
            v = self.d.state_vars[n]
            a = self.args(t, v.params, scope, "state variable")
            return None if a is None else ("state", v, a)
        if n in self.d.derived:
            v = self.d.derived[n]
            a = self.args(t, v.params, scope, "derived predicate")
            return None if a is None else ("derived", v, a)
        self.err(t.name.span, f"unknown state variable or predicate '{n}'", "unknown-name",
                 did_you_mean(n, list(self.d.state_vars) + list(self.d.derived) + list(scope)))
        return None

    def value(self, v: M.StateVar, rhs: ast.LTerm, scope):
        r = self.term(rhs, scope)
        if r is None:
            return None
        term, types = r
        if v.is_bool:
            if not (isinstance(term, Obj) and term.name in (M.TRUE, M.FALSE)):
                self.err(rhs.span, f"'{v.name}' is boolean: its value is true or false", "type")
                return None
            return term
        if isinstance(term, Obj) and term.name in (M.TRUE, M.FALSE):
            self.err(rhs.span, f"'{v.name}' is not boolean", "type",
                     f"its values are {' | '.join(v.domain)}")
            return None
        if isinstance(term, Obj) and term.name == M.NONE:
            if not v.allows_none:
                self.err(rhs.span, f"'{v.name}' cannot be none", "type",
                         f"declare `state {v.name}(...) : {' | '.join(v.domain)} | none`")
                return None
            return term
        if not self.fits(types, v.value_types):
            self.err(rhs.span, f"'{rhs.text()}' ({' | '.join(types)}) is not a possible value of "
                     f"'{v.name}'", "type", f"its values are {' | '.join(v.domain)}")
            return None
        return term

    def literal(self, lit: ast.Lit, scope, negate: bool = False):
        """A literal -> StateLit / DerivedLit / Compare (or None after an error)."""
        if lit.kind in ("atom", "not"):
            neg = (lit.kind == "not") != negate
            if not self.is_atom_name(lit.lhs, scope):
                r = self.term(lit.lhs, scope) if lit.lhs.name.value not in self.d.state_vars else None
                if r is not None:
                    self.err(lit.span, f"'{lit.lhs.text()}' is not a condition", "logic",
                             "compare it, e.g. `x = y`")
                return None
            a = self.atom(lit.lhs, scope)
            if a is None:
                return None
            kind, v, args = a
            if kind == "derived":
                return M.DerivedLit(v.name, args, neg, lit.span)
            if not v.is_bool:
                self.err(lit.span, f"'{v.name}' is not boolean; compare its value",
                         "logic", f"e.g. `{lit.lhs.text()} = ...` (values: {' | '.join(v.domain)})")
                return None
            return M.StateLit(v.name, args, Obj(M.FALSE if neg else M.TRUE), False, lit.span)
        op = lit.op
        lhs, rhs = lit.lhs, lit.rhs
        if not self.is_atom_name(lhs, scope) and self.is_atom_name(rhs, scope):
            lhs, rhs = rhs, lhs
            op = {"<": ">", ">": "<", "<=": ">=", ">=": "<="}.get(op, op)
        if self.is_atom_name(lhs, scope):
            if op not in ("=", "!="):
                self.err(lit.span, f"'{op}' compares objects; a state variable is tested with = or !=",
                         "logic")
                return None
            a = self.atom(lhs, scope)
            if a is None:
                return None
            kind, v, args = a
            if kind == "derived":
                self.err(lhs.span, f"'{v.name}' is a derived predicate: write `{lhs.text()}` or "
                         f"`not {lhs.text()}`", "logic")
                return None
            val = self.value(v, rhs, scope)
            if val is None:
                return None
            neg = (op == "!=") != negate
            if v.is_bool and neg:
                val = Obj(M.FALSE if val.name == M.TRUE else M.TRUE, val.span)
                neg = False
            return M.StateLit(v.name, args, val, neg, lit.span)
        l, r = self.term(lhs, scope), self.term(rhs, scope)
        if l is None or r is None:
            return None
        return M.Compare(l[0], _FLIP[op] if negate else op, r[0], lit.span)

    def formula(self, f, scope, negate: bool = False):
        if isinstance(f, ast.Lit):
            return self.literal(f, scope, negate)
        if isinstance(f, ast.FNot):
            return self.formula(f.item, scope, not negate)
        if isinstance(f, (ast.FAnd, ast.FOr)):
            items = [self.formula(x, scope) for x in f.items]
            if any(i is None for i in items):
                return None
            node = (M.And if isinstance(f, ast.FAnd) else M.Or)(tuple(items), f.span)
            return M.Not(node, f.span) if negate else node
        if isinstance(f, ast.FExists):
            params = self.d.typed_params(f.params, "exists", allow_union=True)
            inner = dict(scope)
            for p in params:
                if p.name in scope:
                    self.err(p.span, f"'{p.name}' is already a variable here", "duplicate")
                inner[p.name] = p.types
            body = self.formula(f.body, inner)
            if body is None:
                return None
            node = M.Exists(params, body, f.span)
            return M.Not(node, f.span) if negate else node
        return None

    def conjunction(self, f, scope) -> list | None:
        """A condition that must be a conjunction of literals (effect conditions)."""
        if isinstance(f, ast.FAnd):
            out = []
            for x in f.items:
                r = self.conjunction(x, scope)
                if r is None:
                    return None
                out.extend(r)
            return out
        if isinstance(f, ast.Lit):
            lit = self.literal(f, scope)
            return None if lit is None else [lit]
        if isinstance(f, ast.FNot) and isinstance(f.item, ast.Lit):
            lit = self.literal(f.item, scope, negate=True)
            return None if lit is None else [lit]
        self.err(f.span, "a condition here must be a conjunction of literals", "logic",
                 "use a derived predicate for disjunctions and quantifiers")
        return None

    def effects(self, effs, scope, conds: tuple = ()) -> list[M.Effect]:
        out = []
        for e in effs:
            if isinstance(e, ast.EffWhen):
                c = self.conjunction(e.cond, scope)
                if c is None:
                    continue
                out.extend(self.effects(e.effects, scope, conds + tuple(c)))
                continue
            lhs = e.lhs
            if not self.is_atom_name(lhs, scope):
                self.err(lhs.span, f"'{lhs.text()}' is not a state variable", "logic")
                continue
            a = self.atom(lhs, scope)
            if a is None:
                continue
            kind, v, args = a
            if kind == "derived":
                self.err(lhs.span, f"'{v.name}' is derived: it cannot be assigned", "logic",
                         "assign the state variables it is derived from")
                continue
            if isinstance(e, ast.EffBool):
                if not v.is_bool:
                    self.err(e.span, f"'{v.name}' is not boolean; assign it with `:=`", "logic",
                             f"e.g. `{lhs.text()} := ...`")
                    continue
                val = Obj(M.TRUE if e.value else M.FALSE, e.span)
            else:
                val = self.value(v, e.rhs, scope)
                if val is None:
                    continue
            out.append(M.Effect(M.Assign(v.name, args, val, e.span), conds, e.span))
        return out

    def action(self, d: ast.ActionDecl) -> M.Action | None:
        params = self.d.typed_params(d.params, "an action")
        scope = {p.name: p.types for p in params}
        for dup in d.duplicates:
            self.err(dup.span, f"'{dup.value}' appears twice in action '{d.name.value}'", "duplicate",
                     "list all items after one keyword, separated by commas")
        pre = []
        for lit in d.pre:
            x = self.literal(lit, scope)
            if x is not None:
                pre.append(x)
        effs = self.effects(d.effects, scope)
        seen: dict = {}
        for e in effs:
            key = (e.assign.var, e.assign.args, e.conditions)
            if key in seen and seen[key] != e.assign.value:
                self.err(e.span, f"'{e.assign.var}' is assigned twice", "duplicate")
            seen[key] = e.assign.value
        # the cost (a number or an expression of the scene) is resolved once the continuous
        # declarations are known: gnppdsl.ir.resolve_costs
        return M.Action(d.name.value, params, tuple(pre), tuple(effs), 1, d.span)


def article(s: str) -> str:
    return ("an " if s[:1] in "aeiou" else "a ") + s
