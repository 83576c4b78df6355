"""The optimisation phase in the loop: a feasible plan's solution, then its objective minimised.

The loop (Fig. 3 of paper 000) ends with a feasible solution of the first plan whose graph-NLP
is feasible; when the plan's rule instances carry `minimize` terms, that solution is the start
of `nlp.optimisation.optimise`. Its point replaces the solution only when the numpy evaluator
(which shares no code with the casadi NLP) finds every factor and bound within the solve's
tolerance and the objective lower; the objective is reported either way (`Stats.cost`).
"""
from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Mapping

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.evaluate import EvaluationError, max_violation
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.optimisation import objective_value, optimise
from gnppdsl.solve.plan_graph import bound_violation


@dataclass
class PhaseOutcome:
    values: dict[VarInstance, np.ndarray]
    cost_before: float | None      # the objective at the feasible solution (None: no objective)
    cost: float | None             # at the returned values
    accepted: bool                 # the optimiser's point replaced the feasible solution
    seconds: float = 0.0
    note: str = ""


Polish = Callable[[dict], "dict | None"]


def optimisation_phase(graph: GraphNLP, terms: list[FactorInstance],
                       values: Mapping[VarInstance, np.ndarray], compiler: BodyCompiler, geometry,
                       tolerance: float, time_limit: float, polish: Polish | None = None) -> PhaseOutcome:
    """Minimise the terms from the feasible `values`; `polish(point)` (the loop's feasibility
    solve from one start) repairs an optimiser's point that ends just outside the feasible set
    (an iteration limit reached on a large graph: sort2's motions ended 5e-6 off after 300
    iterations), and the repaired point is judged like any other. A quasi-Newton run that
    stops at its iteration limit is continued once with the exact Hessian (ipopt's
    limited-memory updates crawled on a small planar graph: 100 iterations to 0.340, then 19
    exact ones to 0.319), for at most as long as the first run took; the lowest verified
    point wins."""
    values = dict(values)
    if not terms:
        return PhaseOutcome(values, None, None, False)
    try:
        before = objective_value(terms, values, geometry)
    except EvaluationError as err:
        return PhaseOutcome(values, None, None, False, note=f"objective not evaluable: {err}")
    if time_limit <= 0.05:
        return PhaseOutcome(values, before, before, False, note="no time left to optimise")
    t_end = time.perf_counter() + time_limit
    best: tuple[float, dict, str] | None = None      # (cost, values, how) of the best accepted point
    notes, seconds, start, cap = [], 0.0, values, time_limit
    for hessian in ("limited-memory", "exact"):
        left = min(cap, t_end - time.perf_counter())
        if left <= 0.05:
            break
        out = optimise(graph, terms, start, compiler, time_limit=left, hessian=hessian)
        if out is None:
            return PhaseOutcome(values, before, before, False, note="no term on the plan's variables")
        seconds += out.seconds
        how = f"ipopt {out.status} after {out.iterations} iterations ({hessian} Hessian)"
        try:
            worst = _violation(graph, out.values, geometry)
            if not worst <= tolerance and polish is not None:
                repaired = polish(out.values)
                if repaired is not None:
                    out.values = {**out.values, **repaired}
                    worst = _violation(graph, out.values, geometry)
            after = objective_value(terms, out.values, geometry)
        except EvaluationError as err:
            notes.append(f"not re-checkable: {err}")
            after, worst = np.inf, np.inf
        if worst <= tolerance and np.isfinite(after) and after < (before if best is None else best[0]):
            best = (after, out.values, how)
        elif worst <= tolerance:
            notes.append(f"no lower cost ({after:.6g} >= {before:.6g}, {how})")
        else:
            notes.append(f"violation {worst:.2g} > {tolerance:g} ({how})")
        if out.status == "Solve_Succeeded":
            break
        # the quasi-Newton run stopped short (iteration limit): the exact Hessian from its
        # point, for at most as long again (its Hessians are what makes large graphs slow)
        start, cap = out.values, max(1.0, out.seconds)
    if best is not None:
        return PhaseOutcome(best[1], before, best[0], True, seconds, best[2])
    return PhaseOutcome(values, before, before, False, seconds,
                        "kept the feasible solution: " + "; ".join(notes))


def _violation(graph: GraphNLP, values: Mapping[VarInstance, np.ndarray], geometry) -> float:
    worst, _ = max_violation(graph.factor_instances, values, geometry)
    return max(worst, bound_violation(graph.variables, values))
