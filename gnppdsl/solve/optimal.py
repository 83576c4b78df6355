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

# `optimise`'s run: at most this many ipopt iterations, stopped once the objective of its feasible
# iterates (every row within FEASIBLE_SHARE x the check tolerance) has not dropped by 1e-4
# (relative) for OPTIMISE_PATIENCE iterations. A point the independent re-check then rejects
# (a row between 1 and FEASIBLE_SHARE x the tolerance) is repaired by `polish`. Why not 0.1 (the
# re-check passes every such iterate): ipopt reaches the optimum's cost with rows at 1e-3 and
# takes ~30 iterations to bring them below 1e-7; measured on sort2 (R-LGP, seed 0, same start):
# 0.1 -> 82 iterations, 1.9 s, to 0.053678; 10 -> 60 iterations, 1.3-1.5 s, to 0.053677
# (accepted without repair); 100 -> 58 iterations and a repair, to 0.0596. A run without
# `polish` keeps only iterates the re-check passes (STRICT_SHARE). The run from `previous` is
# repaired too: with STRICT_SHARE, sort_random instance 17 (R-LGP) reached 0.07268 with rows at
# 1e-5 in 31 iterations, then crept 200 more (5.4 s) bringing them towards 1e-7 at that cost.
OPTIMISE_MAX_ITER = 300
OPTIMISE_PATIENCE = 10
FEASIBLE_SHARE = 10.0
STRICT_SHARE = 0.1

# The run from `previous` (the plan's last optimum, which an active-set round's new pair factors
# cut by millimetres) takes the Hessian with the signed-distance rows linearised (`optimise`'s
# curvature "distance"). Why: that start is already near the optimum, what is left is to push
# the new pairs apart, and the exact Hessian first builds every new pair template's symbolic
# Hessian (~25 templates per round on the mobile Panda) and then evaluates them each iteration.
# Measured on sort_random (R-LGP, seed 0, the same starts, loaded machine), exact -> distance:
# instance 1 33 iterations 3.9 s -> 23, 1.1 s, objective 0.1760 -> 0.1745; 6: 4.2 s -> 1.5 s,
# 0.1745 -> 0.1729; 15: 1.9 -> 0.7 s, 0.0861 -> 0.0858; 17: 3.5 -> 1.1 s, 0.0727 -> 0.0602.
# From the feasible solution (far from the optimum) the exact Hessian stays: with "distance"
# there, 3 of 8 instances ran to the 300-iteration cap without a cheaper feasible point.
PREVIOUS_CURVATURE = "distance"


def optimisation_phase(graph: GraphNLP, terms: list[FactorInstance],
                       values: Mapping[VarInstance, np.ndarray], compiler: BodyCompiler, geometry,
                       tolerance: float, time_limit: float, polish: Polish | None = None,
                       previous: Mapping[VarInstance, np.ndarray] | None = None) -> PhaseOutcome:
    """Minimise the terms from the feasible `values`; `polish(point)` (the loop's feasibility
    solve from one start) repairs an optimiser's point that ends just outside the feasible set,
    and the repaired point is judged like any other (from `values` or from `previous`).
    The first run takes ipopt's exact Hessian
    (per-template derivatives, `nlp.optimisation`) and ends when the objective of its feasible
    iterates stalls (`OPTIMISE_PATIENCE`); only when it finds no cheaper feasible point does a
    limited-memory run try from the same start, for at most as long again. The lowest verified
    point wins. Measured on sort2 (R-LGP, seed 0, same feasible start): limited-memory 100
    iterations then exact ones to a CPU cap, 3.0 s to 0.0537-0.0645 (depending on where the
    cap fell); exact alone with the stall test 1.4 s to 0.0537; limited-memory alone with it
    1.7 s to 0.0678.

    `previous`: an optimised point of the same plan whose graph has since grown (pair factors
    of an active-set round, which that point violates by millimetres): the exact run starts
    there first (ipopt from an infeasible start; only feasible iterates count), and from the
    feasible `values` only when that finds no cheaper feasible point. Measured on sort4 (R-LGP,
    seed 0, round 1: 6 pairs, the point 1.2 mm off): 45 iterations, 2.8 s, to 0.162, against 80
    iterations, 4.3 s, to 0.233 from the feasible solution. The run from `previous` linearises
    the distance rows' curvature (`PREVIOUS_CURVATURE`)."""
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
    notes, seconds, cap = [], 0.0, time_limit
    runs = [("exact", values), ("limited-memory", values)]
    if previous is not None and set(previous) >= set(graph.variables):
        runs.insert(0, ("exact", {v: previous[v] for v in graph.variables}))
    # every run, from `previous` or from `values`, is repaired by `polish` when there is one
    share = FEASIBLE_SHARE if polish is not None else STRICT_SHARE
    for hessian, start in runs:
        left = min(cap, t_end - time.perf_counter())
        if left <= 0.05:
            break
        out = optimise(graph, terms, start, compiler, time_limit=left, hessian=hessian,
                       curvature="exact" if start is values else PREVIOUS_CURVATURE,
                       max_iter=OPTIMISE_MAX_ITER, feasible_below=share * tolerance,
                       patience=OPTIMISE_PATIENCE)
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
        if best is not None or (out.status == "Solve_Succeeded" and start is values):
            break
        if start is values:
            cap = max(1.0, out.seconds)
    if best is not None:
        return PhaseOutcome(best[1], before, best[0], True, seconds, best[2])
    return PhaseOutcome(values, before, before, False, seconds,
                        "kept the feasible solution: " + "; ".join(notes))


def _violation(graph: GraphNLP, values: Mapping[VarInstance, np.ndarray], geometry) -> float:
    worst, _ = max_violation(graph.factor_instances, values, geometry)
    return max(worst, bound_violation(graph.variables, values))
