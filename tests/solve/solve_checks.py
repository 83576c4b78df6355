"""Checks of solve results, shared by the toy and the planar end-to-end tests.

Independent of the solver path:
- a solution of a planar_blocks problem is re-checked against the graph-NLP written from the
  problem and scene files by tests/examples/planar_reference.py (its own logic, its own
  constraints: neither the factory nor the evaluator);
- every factor the factory builds for the plan is evaluated by the tests' own tree walk
  (tests/nlp/evaluate_reference.py) besides the project's evaluator;
- a conflict's subgraph is searched for a feasible point by scipy (tests/solve/scipy_oracle.py:
  SLSQP and least squares on the reference walk's rows, no GraphNLP / casadi / ipopt) besides the
  solver's own multi-start re-solve.
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

from gnppdsl.logic.validate import validate_plan
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

TESTS = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(TESTS / "examples"), str(TESTS / "nlp")]
from evaluate_reference import _reference_rows  # noqa: E402
from planar_reference import read_problem, solution_violation  # noqa: E402
from scipy_oracle import scipy_feasible  # noqa: E402


def _reference_violation(factor, values, geometry) -> float:
    rows = _reference_rows(factor, values, geometry)
    return max([0.0] + [abs(h) if k == "eq" else max(h, 0.0) for k, h in rows])


def check_solution(compiled, result, tol: float = 1e-6) -> float:
    """Soundness: the plan is valid for the task, and every factor of the full graph-NLP --
    rebuilt here from the plan's states by the factory, not taken from the solver -- holds at
    the returned values when evaluated by the numpy interpreter. Returns the max violation."""
    task = compiled.task
    ops = [next(i for i, o in enumerate(task.operators) if o.name == n) for n in result.plan]
    # valid plan reaching the goal, and (conflicts are real) it contains none of the conflicts
    conflicts = [c.partial_states for c in result.conflicts if c.source != "plan"]
    report = validate_plan(task, ops, conflicts=conflicts)
    assert report.valid, report.error
    states = report.states
    factors = compiled.factory.factors(states)
    variables = compiled.factory.variables(states)
    values = result.extras["values"]
    # the JSON-facing step values agree with the raw values
    for st in result.steps:
        for key, val in st.values.items():
            v = next(v for v in variables if v.key == key and v.step == st.index)
            assert np.allclose(val, np.asarray(values[v]).reshape(-1))
    assert all(v in values for f in factors for v in f.variables)
    worst, arg = max_violation(factors, values, compiled.geometry)
    assert worst <= tol, (worst, arg.label if arg else None)
    for f in factors:           # the tests' own tree walk agrees
        assert _reference_violation(f, values, compiled.geometry) <= tol, f.label
    problem = getattr(compiled, "problem", None)
    if problem is not None and problem.domain.name == "planar_blocks":
        # the graph-NLP rebuilt from the files by the reference model, not by the factory
        named = {(v.kind, v.args[0], v.step): x for v, x in values.items() if not v.waypoints}
        ref = solution_violation(read_problem(Path(problem.path)), list(result.plan), named)
        assert ref <= tol, f"the reference model of {problem.name} finds a violation {ref}"
    for v in variables:
        x = np.asarray(values[v], float).reshape(-1)
        if v.lower is not None:
            lo = np.asarray(v.lower, float)
            assert np.all(x >= np.resize(lo, x.size) - tol), v
        if v.upper is not None:
            up = np.asarray(v.upper, float)
            assert np.all(x <= np.resize(up, x.size) + tol), v
    return worst


def check_conflict_infeasible(compiled, conflict, restarts: int = 8, noise: float = 1.0, seed: int = 7) -> None:
    """A conflict is real: its subgraph stays infeasible from many random starts, and its
    partial states hold in every state sequence that generated the factors."""
    assert conflict.subgraph, conflict.text
    graph = GraphNLP.from_factors(conflict.subgraph)
    solver = FeasibilitySolver(compiled.geometry, SolverOptions(restarts=restarts, noise=noise))
    r = solver.solve(graph, seed=seed)
    assert not r.feasible, f"conflict {conflict.text} is feasible (violation {r.max_violation})"
    assert r.starts == restarts + 1
    # a second method sharing no assembly code: scipy on the tests' own evaluation of the rows
    other = scipy_feasible(conflict.subgraph, compiled.geometry, seed=seed)
    assert not other.feasible, (f"conflict {conflict.text}: scipy finds a feasible point "
                                f"(violation {other.best_violation:.1e})")
