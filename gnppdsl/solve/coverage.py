"""The active set in the solve loop: every solution is verified independently before it is
returned, and the pairs the verification finds near join the plan's graph-NLP until it is clean.

Why in the loop and not after it: the pairs a solution brings near can make the plan's graph
infeasible (an arm that cannot reach past the other); that is a conflict like any other (the
pair factors carry generating partial states, `gnppdsl.compile.pair_factors`), so the loop goes
on to the next plan instead of ending with a colliding or no solution. Each round first solves
the augmented full graph from the solution (one NLP, a warm start that is feasible except for
the new rows); only when that fails is Algorithm 1 run on it (`PlanEvaluation.evaluate`), which
finds a solution from its own starts or the conflict.
"""
from __future__ import annotations

import time

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.logic.planner import Plan
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.active_set import active_set_of, pair_factors, verify
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.plan_evaluation import PlanEvaluation
from gnppdsl.solve.result import SOLVED, UNVERIFIED


class Coverage(PlanEvaluation):
    """A solve whose solutions are verified and covered by the active set."""

    def cover(self, plan: Plan, graph: GraphNLP, values: dict[VarInstance, np.ndarray]) -> tuple:
        """The verified result of a solution of `plan`'s graph: ("result", Result) (solved and
        verified, or verification_failed), or ("conflict", factors, relaxation) /
        ("inconsistent", why) from the graph with the pair factors (handled like the outcome
        of `evaluate`)."""
        settings = active_set_of(self.compiled.problem)
        rounds = added = 0
        extra_cpu = 0.0
        while True:
            res = self.solution(plan, graph, values)
            if res.status != SOLVED:
                return ("result", res)
            c0 = time.process_time()
            report = verify(self.compiled, res, settings)
            extra_cpu += time.process_time() - c0
            if report.ok or not self.options.active_set or rounds >= settings.max_rounds \
                    or any(f.kind != "collision" for f in report.issues):
                break
            new = pair_factors(self.compiled, res, report, graph, settings)
            if not new:
                break
            rounds += 1
            added += len(new)
            self.say(f"  active set round {rounds}: {len(new)} pair factors "
                     f"(closest {min(f.distance for f in report.issues):+.4f} m)")
            graph = GraphNLP.from_factors(list(graph.factor_instances) + new, graph.variables,
                                          name=graph.name, initial_guess=graph.initial_guess,
                                          restart_guess=graph.restart_guess)
            check = FeasibilityCheck(self, self.new_solver(), graph, use_db=False)
            r = check.local_solve(graph, warm=values)
            if r.feasible:
                values = {**values, **r.values}
                continue
            outcome = self.evaluate(graph, use_db=self.db is not None)
            if outcome[0] != "solution":
                self.say(f"  active set: the plan with {added} pair factors is {outcome[0]}")
                return outcome
            values = outcome[1]
        res.stats.cpu_time += extra_cpu
        res.verification = report.to_json()
        if rounds:
            res.message += f"; the active set added {added} pair factors in {rounds} round{'s' * (rounds > 1)}"
        if not report.ok:
            res.status = UNVERIFIED
            res.message = ("the solution fails the independent verification (pinocchio + coal): "
                           + "; ".join(report.failures[:3])
                           + (f" (+{len(report.issues) - 3} more)" if len(report.issues) > 3 else ""))
        return ("result", res)


__all__ = ["Coverage"]
