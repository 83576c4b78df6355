"""The grounded SAS+ task: the logic half of a PNTC problem <V, A, s0, g> (paper 000, Sec. III).

This module is the contract between the compiler (which builds a `SASTask` from the IR), the
logic planner (which encodes it in ASP), the Appendix-B reformulation (SAS+ -> SAS+) and the
plan validator. Everything is indexed by integers, like Fast Downward's `.sas` format, and keeps
the human-readable names so that conflicts and plans can be printed in DSL syntax.

Conventions
- A fact is a pair `(var, value)` of indices.
- A partial state is a `PartialState`: a sorted tuple of facts with at most one value per var.
- Derived variables (from `derived` predicates) have `axiom_layer >= 0`, domain `("false",
  "true")`, default value 0 ("false") in every state; axioms set them to 1. A precondition, goal
  or rule pattern may test them for 0 (negation by failure) or 1.
- Operators: `pre` holds prevail and effect preconditions together (as in PDDL); `effects`
  assigns values, optionally under conditions (conditional effects are needed by Appendix B).
- Costs: `Operator.cost` is a float >= 0 (the language's `cost` numbers and expressions);
  `pair_costs` are integers (R-LGP travel, already scaled). The plan cost is the sum of both;
  the planners see `integer_cost` (scaled by `cost_scale`, 1 when all costs are integers).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Iterable, Mapping, Sequence

Fact = tuple[int, int]

COST_RESOLUTION = 1000     # non-integer costs reach the planners in thousandths (cost_scale)


@dataclass(frozen=True, order=True)
class PartialState:
    """An assignment to a subset of the SAS+ variables (paper: p in P)."""

    facts: tuple[Fact, ...] = ()

    def __post_init__(self) -> None:
        facts = tuple(sorted(set(self.facts)))
        vars_ = [v for v, _ in facts]
        if len(vars_) != len(set(vars_)):
            raise ValueError(f"partial state assigns a variable twice: {facts}")
        object.__setattr__(self, "facts", facts)

    @staticmethod
    def of(mapping: Mapping[int, int] | Iterable[Fact]) -> "PartialState":
        items = mapping.items() if isinstance(mapping, Mapping) else mapping
        return PartialState(tuple(items))

    def as_dict(self) -> dict[int, int]:
        return dict(self.facts)

    def holds_in(self, state: Sequence[int]) -> bool:
        """p ⊆ s for a full state s (a sequence of value indices, derived values included)."""
        return all(state[v] == val for v, val in self.facts)

    def union(self, other: "PartialState") -> "PartialState":
        merged = self.as_dict()
        for v, val in other.facts:
            if merged.get(v, val) != val:
                raise ValueError("inconsistent partial states")
            merged[v] = val
        return PartialState.of(merged)

    def __len__(self) -> int:
        return len(self.facts)

    def __iter__(self):
        return iter(self.facts)


@dataclass(frozen=True)
class SASVariable:
    name: str                      # e.g. "parent(b1)"; derived: "clear(b2)"
    values: tuple[str, ...]        # e.g. ("s1", "region_a", "g"); booleans: ("false", "true")
    axiom_layer: int = -1          # -1: state variable; >= 0: derived variable (default value 0)

    @property
    def is_derived(self) -> bool:
        return self.axiom_layer >= 0


@dataclass(frozen=True)
class Effect:
    var: int
    value: int
    conditions: tuple[Fact, ...] = ()   # conditional effect: applies if all conditions hold in s


@dataclass(frozen=True)
class Operator:
    name: str                      # ground action in DSL syntax, e.g. "pick(b1, g, s1)"
    pre: tuple[Fact, ...]          # all preconditions (derived variables allowed)
    effects: tuple[Effect, ...]
    cost: float = 1                # >= 0, in the user's units (`cost 10.5`, a cost expression)

    @property
    def action(self) -> str:
        return self.name.split("(", 1)[0]


@dataclass(frozen=True)
class Axiom:
    """Derivation rule: if all `conditions` hold then derived var `var` takes value `value`."""

    conditions: tuple[Fact, ...]
    var: int
    value: int = 1


@dataclass
class SASTask:
    variables: list[SASVariable]
    initial: tuple[int, ...]                 # one value per variable (derived vars: default 0)
    goal: PartialState
    operators: list[Operator]
    axioms: list[Axiom] = field(default_factory=list)
    # Optional costs per pair of consecutive operators (R-LGP travel costs): a function of
    # (previous operator index or None at the start, operator index) -> extra cost. Kept as data
    # so it can be written out: {(prev, op): cost}. Missing pairs cost 0.
    pair_costs: dict[tuple[int | None, int], int] = field(default_factory=dict)
    name: str = "task"

    # ---- costs ---------------------------------------------------------------------------
    def cost_scale(self) -> int:
        """The factor that makes the costs integers for the logic planners (clingo `#minimize`
        and Fast Downward take integer costs): 1 when every operator cost is an integer (the
        pair costs always are), else `COST_RESOLUTION`, i.e. costs in thousandths, rounded.
        Plans are compared on these integers; `plan_cost` reports the float sum."""
        if all(float(op.cost).is_integer() for op in self.operators):
            return 1
        return COST_RESOLUTION

    def integer_cost(self, cost: float, scale: int | None = None) -> int:
        """`cost` in the planners' integer units (see `cost_scale`)."""
        return int(round(cost * (self.cost_scale() if scale is None else scale)))

    # ---- lookups -------------------------------------------------------------------------
    def var_index(self, name: str) -> int:
        for i, v in enumerate(self.variables):
            if v.name == name:
                return i
        raise KeyError(name)

    def fact(self, var_name: str, value: str) -> Fact:
        i = self.var_index(var_name)
        return (i, self.variables[i].values.index(value))

    def fact_str(self, fact: Fact) -> str:
        v, val = fact
        var = self.variables[v]
        if var.values == ("false", "true"):
            return var.name if val == 1 else f"not {var.name}"
        return f"{var.name} = {var.values[val]}"

    def partial_state_str(self, p: PartialState) -> str:
        """A partial state in DSL syntax, e.g. `{parent(b1) = s1, holding(g) = none}`."""
        return "{" + ", ".join(self.fact_str(f) for f in p.facts) + "}"

    def state_str(self, state: Sequence[int]) -> str:
        return self.partial_state_str(
            PartialState(tuple((i, v) for i, v in enumerate(state) if not self.variables[i].is_derived))
        )
