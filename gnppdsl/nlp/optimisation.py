"""The optimisation phase of optimal TAMP: a feasible plan's graph-NLP with its objective.

Paper 000 decides feasibility; paper 002 (R-LGP) asks for the cheapest motion of the plan it
commits to. Once the loop holds a feasible solution x* of the plan's graph-NLP G, this phase
solves

    min_x  sum_k c_k(x)   s.t.  every row of G's factors, the variables' bounds and unit
                                quaternions,

from x*, where the c_k are the `minimize` terms of the plan's rule instances
(`GraphNLPFactory.objectives`). The caller keeps the result only when an evaluation that shares
no code with this NLP (the numpy evaluator) finds it feasible within the solve's tolerance and
cheaper than x*; otherwise x* stands, so optimising never costs feasibility.

Why a second NLP and not the objective inside the elastic one of `feasibility`: there the
slacks are the objective, and a cost beside them trades violation for cost. Why a
limited-memory Hessian: the objective's curvature is cheap, but the exact Hessian of the
constraints is what made the Lab's graphs expensive (docs/design.md, "Linearised distance
rows"); starting at a feasible point, quasi-Newton steps with exact constraint Jacobians keep
the iterates near the feasible set.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, replace
from typing import Mapping, Sequence

import casadi as ca
import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Constraint, Num, Objective
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.graph import GraphNLP


def term_rows(term: FactorInstance) -> FactorInstance:
    """An objective instance as a factor whose rows are its terms (h_k = c_k, "eq" kind), so
    the body compiler and the numpy evaluator read it like any factor. Never a constraint: only
    this module and `objective_value` use it."""
    rows = tuple(Constraint(st.expr, "==", Num(0.0), span=st.span) for st in term.body
                 if isinstance(st, Objective))
    return replace(term, body=rows)


def objective_value(terms: Sequence[FactorInstance], values: Mapping[VarInstance, object],
                    geometry=None) -> float:
    """The sum of the terms at `values`, by the numpy evaluator (independent of casadi)."""
    from gnppdsl.nlp.evaluate import constraint_rows

    total = 0.0
    for t in terms:
        for _, h in constraint_rows(term_rows(t), values, geometry):
            total += float(np.sum(h))
    return total


@dataclass
class Optimised:
    values: dict[VarInstance, np.ndarray]     # the optimiser's point (not yet accepted)
    status: str                               # ipopt's return status
    iterations: int
    seconds: float


def _bounds(v: VarInstance, bound, default: float) -> np.ndarray:
    if bound is None:
        return np.full(v.dim, default)
    b = np.asarray(bound, float).reshape(-1)
    if b.size == v.point_dim and v.waypoints:
        b = np.tile(b, v.waypoints)
    return b if b.size == v.dim else np.full(v.dim, default)


def optimise(graph: GraphNLP, terms: Sequence[FactorInstance], start: Mapping[VarInstance, object],
             compiler: BodyCompiler, *, time_limit: float = 30.0, max_iter: int = 100,
             tolerance: float = 1e-8, hessian: str = "limited-memory") -> Optimised | None:
    """Minimise the terms over G's feasible set from `start` (G's feasible solution).
    `hessian="exact"`: ipopt's exact Hessian of the Lagrangian (the caller's second try when the
    quasi-Newton run stops at its iteration limit: a two-gripper planar problem, 13 factors, took
    100 limited-memory iterations to 0.340 and 19 exact ones to 0.319).

    Returns None when there is nothing to optimise (no term whose variables are all in G)."""
    variables = list(graph.variables)
    index = {v: i for i, v in enumerate(variables)}
    terms = [t for t in terms if all(v in index for v in t.variables)]
    if not terms:
        return None
    offsets = np.cumsum([0] + [v.dim for v in variables])
    x = ca.MX.sym("x", int(offsets[-1]))

    def args(f: FactorInstance) -> list:
        return [x[int(offsets[index[v]]):int(offsets[index[v]] + v.dim)] for v in f.variables]

    rows, lbg, ubg = [], [], []
    for _, f in graph.iter_factors():
        cb, p = compiler.compile(f)
        rows.append(cb.function(*args(f), ca.DM(p)))
        for kind in cb.kinds:
            lbg.append(0.0 if kind == "eq" else -np.inf)
            ubg.append(0.0)
    for v in variables:
        if v.space == "SE3":
            for k in range(v.waypoints or 1):
                q0 = int(offsets[index[v]]) + k * v.point_dim + 3
                rows.append(ca.sumsqr(x[q0:q0 + 4]) - 1)
                lbg.append(0.0)
                ubg.append(0.0)
    cost = 0
    for t in terms:
        cb, p = compiler.compile(term_rows(t))
        cost = cost + ca.sum1(cb.function(*args(t), ca.DM(p)))
    lbx = np.concatenate([_bounds(v, v.lower, -np.inf) for v in variables])
    ubx = np.concatenate([_bounds(v, v.upper, np.inf) for v in variables])
    x0 = np.concatenate([np.asarray(start[v], float).reshape(-1) for v in variables])
    opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
            "ipopt.hessian_approximation": hessian, "ipopt.max_iter": int(max_iter),
            "ipopt.tol": float(tolerance), "ipopt.max_cpu_time": max(0.1, float(time_limit)),
            "ipopt.mu_init": 1e-4, "ipopt.warm_start_init_point": "yes"}
    solver = ca.nlpsol("optimise", "ipopt", {"x": x, "f": cost, "g": ca.vertcat(*rows)}, opts)
    t0 = time.process_time()
    sol = solver(x0=np.clip(x0, lbx, ubx), lbx=lbx, ubx=ubx, lbg=np.array(lbg), ubg=np.array(ubg))
    stats = solver.stats()
    xs = np.asarray(sol["x"]).reshape(-1)
    values = {v: xs[int(offsets[i]):int(offsets[i + 1])].copy() for i, v in enumerate(variables)}
    return Optimised(values, str(stats.get("return_status", "")), int(stats.get("iter_count", 0)),
                     time.process_time() - t0)
