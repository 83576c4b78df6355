"""Brute force: every logical plan in order of length, each full graph-NLP solved from several
starts. The reference the tests compare GNPP against (completeness on small problems).

Why it is a fair reference: it uses no conflicts, no relaxations and no database, only the
plan enumeration of the logic planner (each plan returned once, then blocked) and the plain
feasibility solve of the whole graph-NLP with random restarts, so a GNPP bug in conflict
extraction or the logic reformulation cannot hide in it.
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

from gnppdsl.solve.compiled import Compiled
from gnppdsl.solve.plan_graph import plan_graph


@dataclass
class BruteResult:
    shortest: int | None                 # length of the shortest geometrically feasible plan
    plan: tuple[str, ...] | None
    plans_checked: int
    exhausted: bool                      # every plan up to max_length was checked (or one found)
    lengths: dict[int, int] = field(default_factory=dict)   # plan length -> plans checked


def brute_force(compiled: Compiled, max_length: int, restarts: int = 3, tolerance: float = 1e-6,
                time_limit: float = 120.0, seed: int = 0, max_plans: int = 5000) -> BruteResult:
    """Enumerate plans by length up to `max_length`; stop at the first feasible one."""
    from gnppdsl.logic.planner import IncrementalPlanner
    from gnppdsl.nlp.body_compiler import BodyCompiler
    from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

    deadline = time.perf_counter() + time_limit
    planner = IncrementalPlanner(compiled.task, max_horizon=max_length)
    compiler = BodyCompiler(compiled.geometry)
    factory = compiled.factory
    checked = 0
    lengths: dict[int, int] = {}
    while checked < max_plans:
        remaining = deadline - time.perf_counter()
        if remaining <= 0:
            return BruteResult(None, None, checked, False, lengths)
        res = planner.next_plan(max_horizon=max_length, time_limit=remaining)
        if not res.found:
            return BruteResult(None, None, checked, res.status.value == "no plan", lengths)
        plan = res.plan
        checked += 1
        lengths[len(plan)] = lengths.get(len(plan), 0) + 1
        graph = plan_graph(factory, plan.states)
        solver = FeasibilitySolver(compiled.geometry, SolverOptions(tolerance=tolerance, restarts=restarts),
                                   compiler=compiler)
        if solver.solve(graph, seed=seed).feasible:
            return BruteResult(len(plan), tuple(plan.names), checked, True, lengths)
    return BruteResult(None, None, checked, False, lengths)
