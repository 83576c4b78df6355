"""Fact minimisation: a conflict keeps only the facts its infeasibility needs (issue 19).

Why: Alg. 1 returns a small infeasible subgraph M, but "small" is about factors and time
steps, not facts: the convergence heuristic keeps every factor violated at the optimizer's
convergence point, so M may hold a factor that only happens to be violated there (e.g.
`off_pads(o4)`, which brings `moved(o4)` into the conflict). Each fact of <p_0 .. p_L> narrows
the plans the conflict forbids, so a fact that is not needed costs the planner more plans and
the loop more NLPs.

The deletion filter: for each fact (step, v = x) of the conflict, the factors whose generator
needs it are removed from M; if what is left is still infeasible (`is_infeasible`, the same
verdict Alg. 1 rests on, injected by the caller) it becomes M. The result is an infeasible
subgraph of the original one, mapped back by `to_partial_states`, so soundness is exactly
that of any Alg. 1 conflict (Prop. 7.1, Theorem 7.1): nothing is assumed about which facts
matter. After the filter no single fact can be dropped this way (facts are tried in order, each
once; a later removal cannot make an earlier fact droppable, since removing factors only makes
the rest more feasible). Cost: one NLP per fact that is not the only support of M, at most
`max_checks`.
"""
from __future__ import annotations

from typing import Callable, Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.conflicts.mapping import to_partial_states


def facts_of(factors: Sequence[FactorInstance]) -> list[tuple[int, tuple[int, int]]]:
    """The facts of the conflict of `factors` as (absolute step, (var, value)), in order."""
    seq = to_partial_states(factors)
    first = min(f.step for f in factors)
    return [(first + l, fact) for l, p in enumerate(seq) for fact in p.facts]


def needing(factors: Sequence[FactorInstance], step: int, fact: tuple[int, int]) -> list[FactorInstance]:
    """The factors whose generator holds `fact` at absolute `step`."""
    return [f for f in factors
            if any(f.step + j == step and fact in p.facts for j, p in enumerate(f.generator))]


def minimise_facts(factors: Sequence[FactorInstance], is_infeasible: Callable[[tuple[FactorInstance, ...]], bool],
                   max_checks: int = 8) -> tuple[tuple[FactorInstance, ...], int]:
    """The deletion filter of the module docstring: (a subgraph of `factors` still infeasible
    whose conflict has no fact that could be dropped, number of NLP checks made)."""
    current = tuple(factors)
    checks = 0
    for step, fact in facts_of(current):
        if checks >= max_checks:
            break
        drop = needing(current, step, fact)
        if not drop or len(drop) == len(current):
            continue                      # gone already, or the whole subgraph needs it
        rest = tuple(f for f in current if f not in drop)
        checks += 1
        if is_infeasible(rest):
            current = rest
    return current, checks
