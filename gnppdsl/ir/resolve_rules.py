"""Rules (`rule r(...) : pattern -> pattern' { template calls }`) -> `model.Rule`: parameter
type inference, partial-state patterns, `where` comparisons, template calls and their arguments.

Separate because a rule links the two halves of a domain: its patterns are logic (through
`LogicResolver`), its calls are the continuous side (templates, checked expressions); this
module only reads what `DomainResolver` has already collected.
"""
from __future__ import annotations

from typing import Protocol

from gnppdsl.ir import model as M
from gnppdsl.ir.expr import Param
from gnppdsl.ir.modules import ModuleEnv, ModuleLibrary
from gnppdsl.ir.resolve_logic import LogicOwner, LogicResolver, article
from gnppdsl.ir.typecheck import INT, OBJ, VAL, Checker, Scope, Ty, compatible
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter


class RuleOwner(LogicOwner, Protocol):
    """What `RuleResolver` reads of the `resolve_domain.DomainResolver` that owns it (a
    protocol because that module imports this one: no import cycle)."""

    r: Reporter
    ws: ModuleLibrary
    types: dict[str, M.Type]
    tags_seen: set[str]
    template_asts: dict[str, tuple[ast.TemplateDecl, ModuleEnv | None]]

    def lookup_template(self, c: ast.TCall, report: bool = True) -> str | None: ...

    def scope(self, module: ModuleEnv | None = None, **kw) -> Scope: ...


class RuleResolver:
    """Rules of one domain, over what its `DomainResolver` collected and its `LogicResolver`."""

    def __init__(self, dom: RuleOwner, logic: LogicResolver) -> None:
        self.d = dom
        self.logic = logic

    def err(self, span, msg, kind="rule", hint=None):
        self.d.err(span, msg, kind, hint)

    def infer(self, params: list[M.TypedParam], lits) -> list[M.TypedParam]:
        """Untyped rule parameters take the types of their first use in the pattern."""
        untyped = {p.name for p in params if not p.types}
        found: dict[str, tuple[str, ...]] = {}
        for lit in lits:
            terms = []
            if lit.kind != "cmp" and lit.lhs.args is not None:
                terms.append((lit.lhs, None))
            if lit.kind == "cmp":
                terms.append((lit.lhs, lit.rhs))
            for lhs, rhs in terms:
                name = lhs.name.value
                decl = self.d.state_vars.get(name) or self.d.derived.get(name)
                if decl is None or lhs.args is None:
                    continue
                for a, p in zip(lhs.args, decl.params):
                    if a.args is None and a.name.value in untyped and a.name.value not in found:
                        found[a.name.value] = p.types
                if rhs is not None and rhs.args is None and rhs.name.value in untyped \
                        and isinstance(decl, M.StateVar) and rhs.name.value not in found:
                    found[rhs.name.value] = decl.value_types or (M.ROOT_TYPE,)
        out = []
        for p in params:
            if p.types:
                out.append(p)
            elif p.name in found:
                out.append(M.TypedParam(p.name, found[p.name], p.span))
            else:
                self.err(p.span, f"cannot infer the type of '{p.name}'", "missing-type",
                         f"write `{p.name}: TYPE` (it does not appear in the rule's pattern)")
                out.append(M.TypedParam(p.name, (M.ROOT_TYPE,), p.span))
        return out

    def pattern(self, lits, scope) -> tuple | None:
        out = []
        ok = True
        for lit in lits:
            x = self.logic.literal(lit, scope)
            if x is None:
                ok = False
                continue
            if isinstance(x, M.Compare):
                self.err(lit.span, "a pattern holds state facts; put comparisons in `where`", "pattern",
                         f"e.g. `rule r(...) where {lit.lhs.text()} {lit.op} {lit.rhs.text()} : ...`")
                ok = False
                continue
            if isinstance(x, M.StateLit) and x.negated:
                self.err(lit.span, "a pattern is a partial state: '!=' cannot be matched", "pattern",
                         "bind the value to a parameter and add `where P != value`")
                ok = False
                continue
            out.append(x)
        vars_ = [(l.var, l.args) for l in out if isinstance(l, M.StateLit)]
        for i, k in enumerate(vars_):
            if k in vars_[:i]:
                self.err(lits[i].span if i < len(lits) else None,
                         f"'{k[0]}' appears twice in one partial state", "pattern")
                ok = False
        return tuple(out) if ok else None

    def rule(self, d: ast.RuleDecl) -> M.Rule | None:
        params = list(self.d.typed_params(d.params, "a rule", allow_untyped=True, allow_union=True))
        params = self.infer(params, d.pre + d.post)
        scope = {p.name: p.types for p in params}
        used = _names_in((d.where, d.pre, d.post, d.calls))
        for p in params:
            if p.name not in used:
                self.d.r.warning(p.span, f"parameter '{p.name}' of rule '{d.name.value}' is not used: "
                                 "the rule is instantiated once per object of its type", "unused")
        where = []
        for lit in d.where:
            x = self.logic.literal(lit, scope)
            if x is None:
                continue
            if not isinstance(x, M.Compare):
                self.err(lit.span, "`where` compares parameters (`a != b`, `a < b`); "
                         "state facts belong in the pattern", "where")
                continue
            where.append(x)
        pre = self.pattern(d.pre, scope)
        post = self.pattern(d.post, scope)
        tags = frozenset(t.value for t in d.tags)
        self.d.tags_seen |= tags
        two_step = d.kind == "transition"
        calls = []
        for c in d.calls:
            q = self.d.lookup_template(c)
            if q is None:
                continue
            tpl_ast, module = self.d.template_asts[q]
            sig = self.d.ws._signature(tpl_ast.params, None) if module is not None else \
                self.d.ws._signature(tpl_ast.params, None)
            tpl_tags = frozenset(t.value for t in tpl_ast.tags)
            call = self.call(c, q, sig, scope, two_step, d)
            if call is None:
                continue
            uses_prime = _template_uses_prime(tpl_ast)
            if uses_prime and not two_step:
                self.err(c.span, f"template '{q}' relates steps i and i+1 (it uses '), but rule "
                         f"'{d.name.value}' matches a single state", "prime",
                         "write the pattern as `p -> p'`, or `always -> always` for every transition")
                continue
            calls.append(M.TemplateCall(q, call, tpl_tags | tags, c.span))
        if pre is None or post is None:
            return None
        return M.Rule(d.name.value, tuple(params), d.kind, pre, post, tuple(calls), tuple(where),
                      tags, d.span)

    def call(self, c: ast.TCall, q: str, sig: tuple[M.Signature, ...], scope, two_step: bool,
             d: ast.RuleDecl):
        if len(c.args) != len(sig):
            self.err(c.span, f"template '{q}' takes {len(sig)} argument{'s' * (len(sig) != 1)}, "
                     f"got {len(c.args)}", "arity",
                     "parameters: " + ", ".join(f"{p.name}: {p.type or p.space or 'value'}"
                                                if p.kind != "any" else f"{p.name}: value" for p in sig))
            return None
        sc = self.d.scope(params={n: (Param(n), OBJ(t)) for n, t in scope.items()},
                          allow_prime=two_step,
                          prime_context=f"in rule '{d.name.value}': it matches a single state "
                                        "(write `p -> p'` to relate two steps)")
        ch = Checker(sc, self.d.r)
        out = []
        any_ty: Ty | None = None
        ok = True
        for a, p in zip(c.args, sig):
            x, t = ch.expr(a)
            if t.kind == "error":
                ok = False
                continue
            if p.kind == "object":
                if t.kind != "object":
                    self.err(a.span, f"argument '{p.name}' of '{q}' is an object ({p.type}), got "
                             f"{article(str(t))}", "type")
                    ok = False
                elif p.type and p.type in self.d.types and not self.logic.fits(t.types, (p.type,)):
                    self.err(a.span, f"argument '{p.name}' of '{q}' must be {article(p.type)}, "
                             f"got {t}", "type")
                    ok = False
            elif p.kind == "string":
                if t.kind != "string":
                    self.err(a.span, f"argument '{p.name}' of '{q}' must be a string", "type")
                    ok = False
            else:
                if t.kind in ("object", "traj", "string"):
                    hint = "pass world(...) for a pose" if t.kind == "object" else None
                    self.err(a.span, f"argument '{p.name}' of '{q}' is a value, got "
                             f"{'an object' if t.kind == 'object' else str(t)}", "type", hint)
                    ok = False
                elif p.kind == "any":
                    if any_ty is not None and not compatible(any_ty, t):
                        self.err(a.span, f"argument '{p.name}' of '{q}' must have the same space as "
                                 f"the other 'value' arguments ({any_ty}), got {t}", "dimension")
                        ok = False
                    elif any_ty is None or any_ty.kind == "any":
                        any_ty = t
                else:
                    want = INT if p.space.kind == "int" else VAL(p.space)
                    if not compatible(want, t):
                        self.err(a.span, f"argument '{p.name}' of '{q}' must be {p.space}, got {t}",
                                 "dimension")
                        ok = False
            out.append(x)
        return tuple(out) if ok else None


def _names_in(x, out: set | None = None) -> set:
    """Every identifier written in an AST fragment."""
    out = set() if out is None else out
    if isinstance(x, ast.Name):
        out.add(x.value)
    elif isinstance(x, tuple):
        for i in x:
            _names_in(i, out)
    elif hasattr(x, "__dataclass_fields__"):
        for f in x.__dataclass_fields__:
            if f != "span":
                _names_in(getattr(x, f), out)
    return out


def _template_uses_prime(d: ast.TemplateDecl) -> bool:
    def walk(x) -> bool:
        if isinstance(x, ast.EPrime):
            return True
        if isinstance(x, tuple):
            return any(walk(i) for i in x)
        if hasattr(x, "__dataclass_fields__"):
            return any(walk(getattr(x, f)) for f in x.__dataclass_fields__ if f != "span")
        return False
    return walk(d.body)
