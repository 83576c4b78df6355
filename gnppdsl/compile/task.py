"""IR -> grounded SAS+ task (`SASTask`): the logic half <V, A, s0, g> of a PNTC problem.

What the compiler decides here (and why):
- One SAS+ variable per ground state variable, `parent(b1)`, whose values are the objects of the
  declared types (declaration order) plus `none` if allowed; booleans get ("false", "true").
- One derived variable (default false) per ground derived atom, with one axiom per disjunct of
  its body in disjunctive normal form (`exists` expands over the objects). SAS+ axioms only
  derive "true", so a negated complex sub-formula (`not exists o . parent(o) = x`) becomes a
  positive auxiliary derived variable that is tested for its default value 0. A `!=` test of a
  multi-valued variable in a precondition, goal or effect condition becomes an auxiliary derived
  variable "v != x" (one axiom per other value), since SAS+ conditions are conjunctions of facts.
  Axiom layers are longest paths in the ground dependency graph where only negative edges
  count (negation must cross layers; negation inside recursion is reported as an error).
- `initial` in any rule adds a marker variable `initial` (true only in s_0: every operator
  sets it false), so conflicts that mention it can only ever match at step 0.
- `final` in any rule adds a state variable `final` (false in s_0) and one operator `final()`
  (cost 0) that requires the goal and sets it; every other operator requires `not final`, and
  the task's goal becomes `final`. So every plan ends with `final()`, `final` holds in s_n and
  nowhere before, and a `final` rule applies exactly at the last step: the state after the
  last action, reached by a motion in which no symbolic fact changes (the robot may move home,
  the objects stay where `stay` rules keep them). Conflicts that mention `final` can only
  match at a plan's end. Why a compiled step and not "the goal holds": the last action's
  keyframe is usually bound to its objects (a place puts the gripper at the block), so "the
  robot ends at home" needs a motion after it.
- Ground operators that can never apply (a value outside a variable's domain, contradictory
  preconditions, a false static comparison, inconsistent effects) are dropped, and so are those
  relaxed reachability from s_0 shows never applicable, with the values no variable can reach
  (`gnppdsl.compile.reachability`: every plan is kept; 80 planar blocks: 6720 -> 400 operators).
- An operator's cost is its action's `cost` (a float), or its `cost` expression evaluated for
  the binding from the problem and the scene (`gnppdsl.compile.costs`).
"""
from __future__ import annotations

from itertools import product

from gnppdsl.compile.costs import ground_costs
from gnppdsl.compile.ground import (FINAL, MARKER, Binding, bindings, compare_holds, error_at, operator_name,
                                    term_name, var_name)
from gnppdsl.compile.reachability import prune_unreachable
from gnppdsl.compile.sas import Axiom, Effect, Fact, Operator, PartialState, SASTask, SASVariable
from gnppdsl.errors import UserError
from gnppdsl.ir import model as m

__all__ = ["build_task", "uses_initial"]

BOOL = (m.FALSE, m.TRUE)
_DNF_LIMIT = 64          # an And whose expansion exceeds this gets auxiliary variables

Conj = tuple[Fact, ...]
DNF = list[Conj]          # [] = false, [()] = true


# the source of the compiled `final()` operator (ground_costs reads its cost from the operator)
_FINAL_ACTION = m.Action(FINAL, (), (), (), 0)


def uses_initial(domain: m.Domain) -> bool:
    return any(r.kind == "initial" for r in domain.rules)


class _Builder:
    def __init__(self, problem: m.Problem, prune: bool = True) -> None:
        self.problem = problem
        self.prune = prune
        self.domain = problem.domain
        self.names: list[str] = []
        self.values: list[tuple[str, ...]] = []
        self.derived: list[bool] = []
        self.index: dict[str, int] = {}
        self.axioms: list[Axiom] = []
        self.aux_cache: dict[tuple, int] = {}
        self.sources: list[tuple[m.Action, Binding]] = []   # operator i's action and binding

    # ---- variables ---------------------------------------------------------------------
    def add_var(self, name: str, values: tuple[str, ...], derived: bool, span=None) -> int:
        if name in self.index:
            raise error_at(span, f"variable '{name}' declared twice")
        self.index[name] = len(self.names)
        self.names.append(name)
        self.values.append(values)
        self.derived.append(derived)
        return self.index[name]

    def aux(self, dnf: DNF, name: str) -> int:
        """A derived variable true iff one of the conjunctions holds (shared when equal)."""
        key = tuple(sorted(dnf))
        if key in self.aux_cache:
            return self.aux_cache[key]
        base, k = name, 1
        while name in self.index:
            k += 1
            name = f"{base}#{k}"
        v = self.add_var(name, BOOL, True)
        self.aux_cache[key] = v
        for conj in key:
            self.axioms.append(Axiom(conj, v, 1))
        return v

    def fact_str(self, fact: Fact) -> str:
        v, val = fact
        return f"{self.names[v]} = {self.values[v][val]}"

    # ---- literals and formulas ---------------------------------------------------------
    def state_lit(self, lit: m.StateLit, b: Binding) -> DNF:
        name = var_name(lit.var, [term_name(a, b) for a in lit.args])
        v = self.index.get(name)
        value = term_name(lit.value, b)
        if v is None or self.derived[v] or value not in self.values[v]:
            return [()] if lit.negated else []
        val = self.values[v].index(value)
        if not lit.negated:
            return [((v, val),)]
        return [((v, w),) for w in range(len(self.values[v])) if w != val]

    def derived_lit(self, lit: m.DerivedLit, b: Binding) -> DNF:
        name = var_name(lit.pred, [term_name(a, b) for a in lit.args])
        v = self.index.get(name)
        if v is None or not self.derived[v]:
            return [()] if lit.negated else []
        return [((v, 0 if lit.negated else 1),)]

    def dnf(self, f, b: Binding, owner: str) -> DNF:
        if isinstance(f, m.StateLit):
            return self.state_lit(f, b)
        if isinstance(f, m.DerivedLit):
            return self.derived_lit(f, b)
        if isinstance(f, m.Compare):
            return [()] if compare_holds(self.problem, f, b) else []
        if isinstance(f, m.Or):
            out: DNF = []
            for item in f.items:
                out.extend(self.dnf(item, b, owner))
            return _simplify(out)
        if isinstance(f, m.Exists):
            out = []
            for extra in bindings(self.problem, f.params):
                out.extend(self.dnf(f.body, {**b, **extra}, owner))
            return _simplify(out)
        if isinstance(f, m.And):
            parts = [self.dnf(item, b, owner) for item in f.items]
            size = 1
            for p in parts:
                size *= max(1, len(p))
            if size > _DNF_LIMIT:
                parts = [p if len(p) <= 1 else [((self.aux(p, f"{owner}~or"), 1),)] for p in parts]
            out = []
            for combo in product(*parts):
                merged = _merge(combo)
                if merged is not None:
                    out.append(merged)
            return _simplify(out)
        if isinstance(f, m.Not):
            inner = self.dnf(f.item, b, owner)
            if not inner:
                return [()]
            if () in inner:
                return []
            if len(inner) == 1 and len(inner[0]) == 1:
                (v, val), = inner[0]
                if self.values[v] == BOOL:   # boolean state or derived variable: flip it
                    return [((v, 1 - val),)]
            return [((self.aux(inner, f"{owner}~not"), 0),)]
        raise error_at(getattr(f, "span", None), f"unsupported formula {f!r}")

    def conjunction(self, lits, b: Binding, owner: str) -> Conj | None:
        """Facts of a conjunction of literals; None if it can never hold. A literal whose
        DNF has several disjuncts (`v != x`) becomes one auxiliary derived fact."""
        facts: list[Fact] = []
        for lit in lits:
            d = self.dnf(lit, b, owner)
            if not d:
                return None
            if len(d) == 1:
                facts.extend(d[0])
            else:
                name = f"{owner}~cond"
                if isinstance(lit, m.StateLit) and lit.negated:
                    name = f"{var_name(lit.var, [term_name(a, b) for a in lit.args])} != {term_name(lit.value, b)}"
                facts.append((self.aux(d, name), 1))
        return _merge([facts])

    # ---- the task ----------------------------------------------------------------------
    def build(self) -> SASTask:
        p, d = self.problem, self.domain
        for sv in d.state_vars.values():
            values = p.values_of(sv)
            for args in p.groundings(sv.params):
                self.add_var(var_name(sv.name, args), values, False, sv.span)
        marker = None
        if uses_initial(d):
            marker = self.add_var(MARKER, BOOL, False)
        final = self.add_var(FINAL, BOOL, False) if any(r.kind == "final" for r in d.rules) else None
        heads = []
        for dp in d.derived.values():
            for binding in bindings(p, dp.params):
                args = [binding[q.name] for q in dp.params]
                heads.append((self.add_var(var_name(dp.name, args), BOOL, True, dp.span), dp, binding))
        for v, dp, binding in heads:
            for conj in self.dnf(dp.body, binding, self.names[v]):
                self.axioms.append(Axiom(conj, v, 1))

        initial = self.initial_state(marker)
        goal = self.goal()
        operators = self.operators(marker, final)
        if final is not None:
            effects = (Effect(final, 1),) + ((Effect(marker, 0),) if marker is not None else ())
            operators.append(Operator(f"{FINAL}()", _merge([goal.facts, ((final, 0),)]), effects, 0))
            self.sources.append((_FINAL_ACTION, {}))
            goal = PartialState.of([(final, 1)])
        layers = self.layers()
        variables = [SASVariable(n, vals, layers.get(i, 0) if der else -1)
                     for i, (n, vals, der) in enumerate(zip(self.names, self.values, self.derived))]
        init = tuple(0 if der else initial[i] for i, der in enumerate(self.derived))
        axioms = sorted(set(self.axioms), key=lambda a: (variables[a.var].axiom_layer, a.var, a.conditions))
        task = SASTask(variables, init, goal, operators, axioms, name=p.name)
        task = ground_costs(p, task, self.sources)
        return prune_unreachable(task) if self.prune else task

    def initial_state(self, marker: int | None) -> dict[int, int]:
        p = self.problem
        init: dict[int, int] = {}
        for a in p.init:
            name = var_name(a.var, [term_name(x, {}) for x in a.args])
            v = self.index.get(name)
            if v is None or self.derived[v]:
                raise error_at(a.span, f"'{name}' is not a state variable of this problem")
            value = term_name(a.value, {})
            if value not in self.values[v]:
                raise error_at(a.span, f"'{value}' is not a possible value of {name} "
                                        f"(possible: {', '.join(self.values[v])})")
            if v in init and init[v] != self.values[v].index(value):
                raise error_at(a.span, f"two initial values for {name}")
            init[v] = self.values[v].index(value)
        if marker is not None:
            init[marker] = 1
        for v, name in enumerate(self.names):
            if self.derived[v] or v in init:
                continue
            if self.values[v] == BOOL:
                init[v] = 0
            elif m.NONE in self.values[v]:
                init[v] = self.values[v].index(m.NONE)
            else:
                raise error_at(p.span, f"no initial value for {name}")
        return init

    def goal(self) -> PartialState:
        conj = self.conjunction(self.problem.goal, {}, "goal")
        if conj is None:
            # at the goal's first item (the problem's own span is its first line)
            first = next((g for g in self.problem.goal if getattr(g, "span", None) is not None), None)
            raise error_at(first.span if first is not None else self.problem.span,
                           "the goal can never hold (a value outside a variable's domain "
                           "or contradictory goal facts)")
        return PartialState.of(conj)

    def operators(self, marker: int | None, final: int | None = None) -> list[Operator]:
        ops: list[Operator] = []
        for act in self.domain.actions.values():
            for b in bindings(self.problem, act.params):
                op = self.operator(act, b, marker, final)
                if op is not None:
                    ops.append(op)
                    self.sources.append((act, b))
        return ops

    def operator(self, act: m.Action, b: Binding, marker: int | None,
                 final: int | None = None) -> Operator | None:
        name = operator_name(act.name, act.params, b)
        pre = self.conjunction(act.pre, b, name)
        if pre is None:
            return None
        if final is not None:                   # nothing happens after the final step
            pre = _merge([pre, ((final, 0),)])
        effects: list[Effect] = []
        unconditional: dict[int, int] = {}
        for eff in act.effects:
            a = eff.assign
            target = var_name(a.var, [term_name(x, b) for x in a.args])
            v = self.index.get(target)
            value = term_name(a.value, b)
            if v is None or self.derived[v] or value not in self.values[v]:
                return None                     # statically inapplicable grounding
            val = self.values[v].index(value)
            conds = self.conjunction(eff.conditions, b, name) if eff.conditions else ()
            if conds is None:
                continue                        # the condition can never hold
            if not conds:
                if unconditional.get(v, val) != val:
                    return None                 # contradictory effects
                unconditional[v] = val
            effects.append(Effect(v, val, tuple(conds)))
        if marker is not None and marker not in unconditional:
            effects.append(Effect(marker, 0))
        return Operator(name, pre, tuple(dict.fromkeys(effects)), act.cost)

    def layers(self) -> dict[int, int]:
        """Axiom layers by stratification: layer(head) >= layer(v) for a positive condition on
        a derived v, > for a negative one (default value 0). Computed as longest paths by
        relaxation to a fixpoint (no graph library: networkx alone would cost `gnpp compile`
        0.3 s of start-up); a layer above the number of derived variables can only come from a
        cycle through a negation, i.e. the predicates are not stratified."""
        derived = [v for v, der in enumerate(self.derived) if der]
        layer = {v: 0 for v in derived}
        edges = {}
        for ax in self.axioms:
            for v, val in ax.conditions:
                if self.derived[v]:
                    w = 1 if val == 0 else 0
                    edges[(v, ax.var)] = max(w, edges.get((v, ax.var), 0))
        edge_list = sorted(edges.items())
        limit = len(derived)
        changed = True
        while changed:
            changed = False
            for (u, v), w in edge_list:
                if layer[u] + w > layer[v]:
                    layer[v] = layer[u] + w
                    changed = True
                    if layer[v] > limit:
                        raise UserError(
                            f"derived predicates are not stratified: {self.names[v]} depends "
                            f"negatively on itself (through {self.names[u]})")
        return layer


def _merge(conjs) -> Conj | None:
    """Union of conjunctions; None if two facts give one variable different values."""
    out: dict[int, int] = {}
    for conj in conjs:
        for v, val in conj:
            if out.get(v, val) != val:
                return None
            out[v] = val
    return tuple(sorted(out.items()))


def _simplify(dnf: DNF) -> DNF:
    if () in dnf:
        return [()]
    return list(dict.fromkeys(dnf))


def build_task(problem: m.Problem, prune: bool = True) -> SASTask:
    """Ground the problem's logic into a SAS+ task (see the module docstring). `prune=False`
    keeps what relaxed reachability would drop (the full grounding: its tests, and the
    oracle that pruning keeps every plan)."""
    return _Builder(problem, prune).build()
