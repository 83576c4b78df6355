"""Independent checks of solve results, shared by the toy and the planar end-to-end tests."""
from __future__ import annotations

import numpy as np

from gnppdsl.logic.validate import validate_plan
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP


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
