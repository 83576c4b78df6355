"""Brute force for the conflict-soundness tests (lifting, batch learning): every plan of a
compiled problem up to a length, each plan's full graph-NLP solved from several starts. A
learned conflict is sound when it forbids none of the plans found feasible here."""
from __future__ import annotations

from gnppdsl.logic.planner import IncrementalPlanner
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.solve.plan_graph import plan_graph


def feasible_plans(compiled, max_len: int, restarts: int = 3):
    """The plans up to `max_len` whose full graph-NLP the solver finds feasible, and the number
    of plans checked."""
    planner = IncrementalPlanner(compiled.task, max_horizon=max_len)
    out, checked = [], 0
    while True:
        res = planner.next_plan(max_horizon=max_len, time_limit=60)
        if not res.found:
            return out, checked
        checked += 1
        solver = FeasibilitySolver(compiled.geometry, SolverOptions(tolerance=1e-6, restarts=restarts))
        if solver.solve(plan_graph(compiled.factory, res.plan.states), seed=0).feasible:
            out.append(res.plan)
