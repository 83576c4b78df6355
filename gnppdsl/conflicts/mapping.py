"""Infeasible subgraph -> sequence of partial states <p_0 ... p_L> (paper 000, Sec. VII).

Why: the logic planner does not know about factors; it can only forbid sequences of partial
states. Every factor remembers the partial state(s) that generated it (`FactorInstance.generator`:
`(p,)` at step i, or `(p, p')` at steps i and i+1), so tracing the map Π back is a union, per
step, of the generators of the subgraph's factors. By factor time-invariance (Property 4.2) and
Property 4.3, any state sequence containing the resulting <p_0 ... p_L> at any offset generates a
graph-NLP that contains the same subgraph, hence is infeasible when the subgraph is (Property 4.4).

The relative time order is kept and steps are renumbered from 0 (the first step any factor of
the subgraph touches). Steps in between that no factor constrains stay in the sequence as empty
partial states, so the distance in time between the constrained steps is preserved.
"""
from __future__ import annotations

from typing import Any, Iterable

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.sas import PartialState


def factors_of(subgraph: Any) -> tuple[FactorInstance, ...]:
    """The factor instances of a subgraph given in one of the shapes the layers use.

    Accepted: an iterable of `FactorInstance`; a `GraphNLP` (its `factor_instances`); an object
    with a `factors` attribute (a sequence or a callable); a networkx
    graph whose factor vertices carry the instance in the node attribute ``factor``.
    """
    if isinstance(subgraph, FactorInstance):
        return (subgraph,)
    # `GraphNLP.factors` is the factor list of the *full* graph shared by all its subgraphs;
    # `factor_instances` are the factors present in this (sub)graph.
    factors = getattr(subgraph, "factor_instances", None)
    if factors is None:
        factors = getattr(subgraph, "factors", None)
    if factors is not None:
        if callable(factors):
            factors = factors()
        if isinstance(factors, dict):
            factors = factors.values()
        return tuple(factors)
    nodes = getattr(subgraph, "nodes", None)
    if nodes is not None and hasattr(nodes, "data"):
        return tuple(d["factor"] for _, d in nodes(data=True) if isinstance(d.get("factor"), FactorInstance))
    return tuple(f for f in subgraph if isinstance(f, FactorInstance))


def step_range(factors: Iterable[FactorInstance]) -> tuple[int, int]:
    """(first, last) absolute step that the generators of `factors` refer to, `last` extended
    to the step each factor needs to *exist*: a trajectory variable at step i (the motion
    i -> i+1) exists only when step i + 1 does (the factory leaves its factors out at the plan's
    last step), so a factor on it is generated only by plans that go on after step i. Without
    the extension a conflict found inside a plan would also forbid plans in which its partial
    states hold at the very end, whose graph-NLPs lack those factors (Prop. 7.1 needs every
    matching plan to contain the subgraph); the extra step is an empty partial state."""
    factors = list(factors)
    steps = [f.step + j for f in factors for j in range(len(f.generator))]
    if not steps:
        raise ValueError("a subgraph without factors maps to no partial states")
    needed = [v.step + (1 if v.waypoints else 0) for f in factors for v in f.variables]
    return min(steps), max(steps + needed)


def to_partial_states(subgraph: Any) -> tuple[PartialState, ...]:
    """The sequence <p_0 ... p_L> whose induced subgraph M(<p_0 ... p_L>) contains `subgraph`.

    Raises ValueError if the subgraph has no factors (nothing to explain) or if two generators
    disagree on a variable at the same step (impossible for factors of one state sequence).
    """
    factors = factors_of(subgraph)
    first, last = step_range(factors)
    per_step: list[dict[int, int]] = [dict() for _ in range(last - first + 1)]
    for f in factors:
        for j, p in enumerate(f.generator):
            slot = per_step[f.step + j - first]
            for var, val in p.facts:
                if slot.setdefault(var, val) != val:
                    raise ValueError(
                        f"factors of one subgraph disagree at step {f.step + j}: variable {var} "
                        f"is {slot[var]} and {val} ({f.label})"
                    )
    return tuple(PartialState.of(d) for d in per_step)


def conflict_str(task: Any, partial_states: Iterable[PartialState]) -> str:
    """A conflict in DSL syntax, one partial state per step: `{parent(b1) = s1} -> {...}`.

    `task` is the `SASTask` that names the variables.
    """
    return " -> ".join(task.partial_state_str(p) for p in partial_states)
