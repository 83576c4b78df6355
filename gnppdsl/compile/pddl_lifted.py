"""Write a problem's logic as *lifted* PDDL: types, parameterised actions, derived predicates.

Why a second writer next to `gnppdsl.compile.pddl` (which writes the ground SAS+ task): a
person or another planner wants the domain as it was written -- `pick(?o - block ?g - gripper
?from - place)`, not one action per binding -- and Unified Planning's `PDDLReader` and Fast
Downward's translator ground it themselves. It is written from the resolved IR
(`gnppdsl.ir.model`), so it describes the domain *before* conflicts were learned; a task
reformulated with conflicts (Appendix B) stays with the ground writer (`gnpp compile --emit pddl
--conflicts ...`). Tests check both directions against independent oracles: FD's translator +
search on this PDDL finds the same optimal plan length as FD on our `.sas`, and UP's reader
accepts it.

Encoding of the SAS+ semantics (the same as the ground writer's, lifted):
- a multi-valued state variable `parent(o: block) : place | gripper` is the predicate
  `(parent ?o - block ?value)` (untyped: object) true for exactly one value; `none` is a domain
  constant. An assignment `parent(o) := g` adds `(parent ?o ?g)` and deletes every other value with
  `(forall (?x) (when (parent ?o ?x) (not (parent ?o ?x))))` -- PDDL's add-after-delete
  semantics keeps the new value when it equals the old one;
- a boolean state variable is a predicate true iff the value is true;
- `derived p(x) := F` becomes `(:derived (p ?x) F)` with `exists`, `or`, `not`; the
  requirement `:derived-predicates` is declared only when the domain has derived predicates.
  `derived="inline"` substitutes non-recursive derived predicates into preconditions, goals and
  effect conditions instead (quantified preconditions), for readers without derived predicates
  (Unified Planning 1.3 rejects `:derived`);
- `a != b` between parameters is `(not (= ?a ?b))` (`:equality`); action costs via `total-cost`.
"""
from __future__ import annotations

from dataclasses import dataclass

from gnppdsl.compile.ground import error_at
from gnppdsl.compile.pddl import _Namer, pddl_name
from gnppdsl.errors import UserError
from gnppdsl.ir import model as m
from gnppdsl.ir.expr import Obj, Param

__all__ = ["LiftedPDDL", "write_lifted_pddl"]


@dataclass
class LiftedPDDL:
    domain: str
    problem: str
    action_names: dict[str, str]      # PDDL action name -> action name in the .pntc domain


class _Writer:
    def __init__(self, problem: m.Problem, derived: str) -> None:
        if derived not in ("keep", "inline"):
            raise ValueError(f"derived must be 'keep' or 'inline', not {derived!r}")
        self.p = problem
        self.d = problem.domain
        self.inline = derived == "inline"
        # one namespace for all (Unified Planning refuses a type and an action both named
        # `place`); actions and predicates keep their names, a clashing type becomes `place_type`
        self.types, self.preds, self.objects, self.actions = _Namer(), _Namer(), _Namer(), _Namer()
        used = self.types.used = self.preds.used = self.objects.used = self.actions.used
        for a in self.d.actions:
            self.actions(a, a)
        for sv in self.d.state_vars:
            self.preds(("sv", sv), sv)
        for dp in self.d.derived:
            self.preds(("dp", dp), dp)
        self.types.forward[m.ROOT_TYPE] = m.ROOT_TYPE      # PDDL's own root type
        used.add(m.ROOT_TYPE)
        for t in self.d.types:
            if t != m.ROOT_TYPE:
                self.types(t, t + "_type" if pddl_name(t) in used else t)
        self.none = self.objects(m.NONE, m.NONE) if any(sv.allows_none for sv in self.d.state_vars.values()) else None
        for o in self.p.objects:
            self.objects(o, o)
        self.fresh = 0
        if self.inline:
            self._check_inlinable()

    # ---- names ---------------------------------------------------------------------------
    def type_of(self, tp: m.TypedParam) -> str:
        names = [self.types.forward[t] for t in tp.types]
        return names[0] if len(names) == 1 else "(either " + " ".join(names) + ")"

    def term(self, t, env: dict[str, str]) -> str:
        if isinstance(t, Param):
            return env[t.name]
        if isinstance(t, Obj):
            if t.name == m.NONE:
                return self.none or m.NONE
            return self.objects.forward[t.name]
        raise UserError(f"PDDL: cannot write the term {t!r}")

    def bind(self, params, env: dict[str, str]) -> tuple[dict[str, str], str]:
        """Variables for `params` (fresh names so that nested quantifiers never shadow)."""
        env = dict(env)
        decl = []
        for tp in params:
            self.fresh += 1
            var = f"?{pddl_name(tp.name)}"
            if var in env.values():
                var = f"{var}-{self.fresh}"
            env[tp.name] = var
            decl.append(f"{var} - {self.type_of(tp)}")
        return env, " ".join(decl)

    # ---- formulas ------------------------------------------------------------------------
    def atom(self, var: str, args, value, env) -> tuple[str, bool]:
        sv = self.d.state_vars[var]
        head = [self.preds.forward[("sv", var)], *(self.term(a, env) for a in args)]
        if sv.is_bool:
            return "(" + " ".join(head) + ")", not (isinstance(value, Obj) and value.name == m.FALSE)
        return "(" + " ".join([*head, self.term(value, env)]) + ")", True

    def formula(self, f, env: dict[str, str], depth: int = 0) -> str:
        if isinstance(f, m.StateLit):
            text, positive = self.atom(f.var, f.args, f.value, env)
            return text if positive != f.negated else f"(not {text})"
        if isinstance(f, m.DerivedLit):
            if self.inline:
                dp = self.d.derived[f.pred]
                inner = dict(env)
                for tp, a in zip(dp.params, f.args):
                    inner[tp.name] = self.term(a, env)
                if depth > 64:
                    raise error_at(dp.span, f"PDDL: derived predicate {f.pred} is recursive; cannot inline it")
                body = self.formula(dp.body, inner, depth + 1)
            else:
                body = "(" + " ".join([self.preds.forward[("dp", f.pred)],
                                       *(self.term(a, env) for a in f.args)]) + ")"
            return f"(not {body})" if f.negated else body
        if isinstance(f, m.Compare):
            a, b = self.term(f.lhs, env), self.term(f.rhs, env)
            if f.op in ("=", "=="):
                return f"(= {a} {b})"
            if f.op == "!=":
                return f"(not (= {a} {b}))"
            raise error_at(getattr(f, "span", None), f"PDDL has no object ordering: cannot write `{f.op}` "
                           "(write the ground task instead: `gnpp compile --emit pddl-ground`)")
        if isinstance(f, m.And):
            return self.conj([self.formula(x, env, depth) for x in f.items])
        if isinstance(f, m.Or):
            items = [self.formula(x, env, depth) for x in f.items]
            return items[0] if len(items) == 1 else "(or " + " ".join(items) + ")"
        if isinstance(f, m.Not):
            return f"(not {self.formula(f.item, env, depth)})"
        if isinstance(f, m.Exists):
            inner, decl = self.bind(f.params, env)
            return f"(exists ({decl}) {self.formula(f.body, inner, depth)})"
        raise UserError(f"PDDL: cannot write the formula {f!r}")

    @staticmethod
    def conj(items: list[str]) -> str:
        if not items:
            return "(and)"
        return items[0] if len(items) == 1 else "(and " + " ".join(items) + ")"

    def _check_inlinable(self) -> None:
        deps = {n: set() for n in self.d.derived}

        def walk(f, out):
            if isinstance(f, m.DerivedLit):
                out.add(f.pred)
            for attr in ("items",):
                for x in getattr(f, attr, ()) or ():
                    walk(x, out)
            for attr in ("item", "body"):
                if getattr(f, attr, None) is not None:
                    walk(getattr(f, attr), out)

        for n, dp in self.d.derived.items():
            walk(dp.body, deps[n])
        seen: set[str] = set()

        def visit(n, stack):
            if n in stack:
                raise error_at(self.d.derived[n].span, f"PDDL: derived predicate {n} is recursive; it "
                               "cannot be inlined (keep the derived predicates)")
            if n in seen:
                return
            for k in deps[n]:
                visit(k, stack | {n})
            seen.add(n)

        for n in deps:
            visit(n, frozenset())

    # ---- effects -------------------------------------------------------------------------
    def effect(self, e: m.Effect, env) -> list[str]:
        a = e.assign
        sv = self.d.state_vars[a.var]
        cond = self.conj([self.formula(c, env) for c in e.conditions]) if e.conditions else None
        text, positive = self.atom(a.var, a.args, a.value, env)
        out = []
        if sv.is_bool:
            lit = text if positive else f"(not {text})"
            return [f"(when {cond} {lit})" if cond else lit]
        self.fresh += 1
        x = f"?old-{self.fresh}"
        old = "(" + " ".join([self.preds.forward[("sv", a.var)], *(self.term(t, env) for t in a.args), x]) + ")"
        guard = old if cond is None else f"(and {cond} {old})"
        out.append(f"(forall ({x}) (when {guard} (not {old})))")
        out.append(f"(when {cond} {text})" if cond else text)
        return out

    # ---- sections ------------------------------------------------------------------------
    def domain_text(self) -> tuple[str, dict[str, str]]:
        d = self.d
        reqs = [":strips", ":typing", ":negative-preconditions", ":disjunctive-preconditions",
                ":equality", ":existential-preconditions", ":conditional-effects"]
        if d.derived and not self.inline:
            reqs.append(":derived-predicates")
        reqs.append(":action-costs")
        lines = [f"(define (domain {pddl_name(d.name)})", f"  (:requirements {' '.join(reqs)})"]
        by_parent: dict[str, list[str]] = {}
        for t in d.types.values():
            if t.name == m.ROOT_TYPE:
                continue
            by_parent.setdefault(t.parent or m.ROOT_TYPE, []).append(self.types.forward[t.name])
        if by_parent:
            lines.append("  (:types " + "  ".join(f"{' '.join(ch)} - {self.types.forward[par]}"
                                                  for par, ch in by_parent.items()) + ")")
        consts = [f"{self.objects.forward[o]} - {self.types.forward[t]}" for o, t in d.constants.items()]
        if self.none:
            consts.append(self.none)       # untyped at the end of the list: of type object
        if consts:
            lines.append("  (:constants " + " ".join(consts) + ")")
        preds = []
        for name, sv in d.state_vars.items():
            env, decl = self.bind(sv.params, {})
            parts = [self.preds.forward[("sv", name)]] + ([decl] if decl else [])
            if not sv.is_bool:
                parts.append("?value")          # untyped: object (the `pddl` package knows no declared `object`)
            preds.append("(" + " ".join(parts) + ")")
        if not self.inline:
            for name, dp in d.derived.items():
                env, decl = self.bind(dp.params, {})
                preds.append("(" + " ".join([self.preds.forward[("dp", name)]] + ([decl] if decl else [])) + ")")
        lines.append("  (:predicates " + " ".join(preds) + ")")
        lines.append("  (:functions (total-cost) - number)")
        if not self.inline:
            for name, dp in d.derived.items():
                env, decl = self.bind(dp.params, {})
                head = " ".join([self.preds.forward[("dp", name)]] + ([decl] if decl else []))
                lines.append(f"  (:derived ({head})\n    {self.formula(dp.body, env)})")
        names = {}
        for name, act in d.actions.items():
            an = self.actions.forward[name]
            names[an] = name
            env, decl = self.bind(act.params, {})
            pre = self.conj([self.formula(f, env) for f in act.pre])
            effs = [x for e in act.effects for x in self.effect(e, env)]
            if act.cost_expr is not None or not float(act.cost).is_integer():
                raise error_at(getattr(act.cost_expr, "span", None) or act.span,
                               f"PDDL: the cost of action {name} is not an integer constant; the "
                               f"lifted export cannot write it (the grounded one can: --emit pddl-ground)")
            effs.append(f"(increase (total-cost) {int(act.cost)})")
            lines.append(f"  (:action {an}\n    :parameters ({decl})\n    :precondition {pre}\n"
                         f"    :effect (and {' '.join(effs)}))")
        return "\n".join(lines) + "\n)\n", names

    def problem_text(self) -> str:
        objs = [f"{self.objects.forward[o]} - {self.types.forward[t]}" for o, t in self.p.objects.items()
                if o not in self.d.constants]
        init = []
        for a in self.p.init:
            text, positive = self.atom(a.var, a.args, a.value, {})
            if positive:
                init.append(text)
        init.append("(= (total-cost) 0)")
        goal = self.conj([self.formula(g, {}) for g in self.p.goal])
        lines = [f"(define (problem {pddl_name(self.p.name)})", f"  (:domain {pddl_name(self.d.name)})"]
        if objs:
            lines.append("  (:objects " + " ".join(objs) + ")")
        lines += [f"  (:init {' '.join(init)})", f"  (:goal {goal})", "  (:metric minimize (total-cost))"]
        return "\n".join(lines) + "\n)\n"


def write_lifted_pddl(problem: m.Problem, derived: str = "keep") -> LiftedPDDL:
    """The lifted PDDL domain and problem of a resolved `Problem`. `derived`: "keep" writes
    `:derived` predicates (if the domain has any), "inline" substitutes them (see module doc)."""
    w = _Writer(problem, derived)
    domain, names = w.domain_text()
    return LiftedPDDL(domain, w.problem_text(), names)
