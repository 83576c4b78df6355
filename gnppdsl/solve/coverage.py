"""The active set in the solve loop: every solution is verified independently before it is
returned, and the pairs the verification finds near join the plan's graph-NLP until it is clean.

Why in the loop and not after it: the pairs a solution brings near can make the plan's graph
infeasible (an arm that cannot reach past the other); that is a conflict like any other (the
pair factors carry generating partial states, `gnppdsl.compile.pair_factors`), so the loop goes
on to the next plan instead of ending with a colliding or no solution. Each round first repairs
the solution phase by phase (`repair`: the keyframes only when a new row is at a keyframe, then
each motion between its fixed keyframes, a motion whose start already satisfies its rows kept
without an NLP, one failing motion joined with the keyframes); a graph without motions gets one
joint solve from the solution instead (a warm start that is feasible except for the new rows).
When that fails, Algorithm 1 is run on the augmented graph (`PlanEvaluation.evaluate`), which
finds a solution from its own starts or the conflict. Only the last is a verdict: a repair that
fails proves nothing. What the repair learned is handed on as a start, not a verdict: its
keyframes (the solution's, after its keyframe solve and its joined motion) are the first values
of Algorithm 1's checker, so a level or graph they satisfy is known feasible by numpy
(`known_solution`) and the others start there; the trajectories are not handed on (their
motions are solved again phase by phase, from interpolation). Measured on lab4_paper with
`--batch-conflicts 0`, seed 0 (the round-1 repair fails at motion 4 after joining motion 2):
without this, Algorithm 1 started from the initial guess, solved the same keyframes+motion 2
NLP again (same factors, another start, 4.6 s) and needed a second round; with it, 80 -> 68
NLPs, 30.5 -> 23.7 s CPU (loaded machine), one round, verified. (Not a cache of the repair's
NLPs: Algorithm 1 never built one with the same start, so none would have been reused.)

Why phase by phase and no joint solve of the motions (measured on lab4_paper, 9 steps, two
Pandas, seed 0): the joint re-solve of the augmented graph (654 factors, every motion's
waypoints in one NLP) took 23 s CPU and failed in round 1 (125 pair factors, -3.6 cm), then
6.4 s in round 2 (4 pair factors), half of the whole solve; the repair of round 2 took 0.9 s
(two motions, 6 and 18 iterations). Round 1 failed the repair too (a second failing motion:
up to MAX_JOINED_MOTIONS joined motions cost 12 s more and failed as well, hence one:
`REPAIR_JOINED_MOTIONS`), and Algorithm 1 solved it in 10 s. Why not zero joined motions
(tried): lab4_paper 36 -> 28 s CPU (its one join duplicates the 6 s NLP Algorithm 1 then
solves again), but work1, whose round-1 motion misses by 1e-5 between fixed keyframes and is
repaired by the join, 35 -> 42 s (seed 0) and 25 -> 31 s (seed 1).
"""
from __future__ import annotations

import time

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.logic.planner import Plan
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.active_set import active_set_of, pair_factors, verify
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.options import overridden
from gnppdsl.solve.plan_evaluation import PlanEvaluation
from gnppdsl.solve.plan_graph import TRAJ, is_trajectory
from gnppdsl.solve.result import SOLVED, UNVERIFIED


REPAIR_JOINED_MOTIONS = 1
"""Motions `Coverage.repair` joins with the keyframes before it gives up (module docstring)."""

SCREEN_MAX_PAIRS = 200
"""An active-set round adding at most this many pair factors has its repair screened
(`screening`; stack_16: 28 pairs, its join 21 -> 1.3 s); more (clutter_4: ~2000) are all
near and kept, where screening only added NLP runs (clutter_4 103 -> 264 s CPU)."""


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
            extra_cpu = time.process_time() - c0     # the earlier rounds are in the result's own cpu_time
            limit = settings.max_rounds if res.stats.optimised else settings.max_feasible_rounds
            if report.ok or not self.options.active_set or rounds >= limit \
                    or any(f.kind != "collision" for f in report.issues):
                break
            # an optimised solution: a pair colliding along a motion joins all of it (the
            # optimisation would cut the corner at the next point without a row)
            new = pair_factors(self.compiled, res, report, graph, settings, spread=bool(res.stats.optimised))
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
            # a solution's start, screened (`screening`) when the round added few pairs: its
            # pairs are near by construction, so with many (clutter_4: 1670-2351 in round 1,
            # every one kept) a screened NLP is as large as the whole and only adds a run
            with overridden(check, screen=len(new) < SCREEN_MAX_PAIRS):
                r = self.repair(check, graph, values)
                if r is None:          # no motions to repair phase by phase: one joint solve
                    r = check.local_solve(graph, warm=values)
            if r is not False and r.feasible:
                values = {**values, **r.values}
                continue
            # the repair's keyframes (the solution's, moved by its keyframe and joined-motion
            # solves) start Algorithm 1's checker: warm starts only (module docstring)
            outcome = self.evaluate(graph, use_db=self.db is not None,
                                    known={v: x for v, x in check.values.items() if not v.waypoints})
            if outcome[0] != "solution":
                self.say(f"  active set: the plan with {added} pair factors is {outcome[0]}")
                return outcome
            values = outcome[1]
        if not report.ok and self.options.active_set and self.stats.optimised:
            res, report, extra_cpu = self.unoptimised(plan, graph, values, settings, res, report)
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

    def unoptimised(self, plan: Plan, graph: GraphNLP, values: dict[VarInstance, np.ndarray],
                    settings, res, report) -> tuple:
        """When the optimised solution still fails the verification after the active set's
        rounds: the plan's feasible solution (`values`, which satisfies every pair factor the
        rounds added) without the optimisation phase, verified like any other, returned when
        it is clean (its cost unoptimised, said in the message); else the optimised result and
        its report unchanged. Why: each round's optimisation shortens the path again and can
        cut an obstacle's corner between the rows (sort_random_pr2 instances 5, 6, 8, 12,
        R-LGP, PR2 base against the centre table), and a solution failing the verification is
        never reported as solved."""
        from dataclasses import replace

        # the run's stats are the results' (one object): the optimised result's figures are
        # restored when it stays the answer
        kept = {f: getattr(self.stats, f) for f in ("cost", "cost_feasible", "optimise_time", "optimised",
                                                    "max_violation", "factors", "variables")}
        with overridden(self, options=replace(self.options, optimise=False)):
            plain = self.solution(plan, graph, values)
        c1 = time.process_time()
        checked = verify(self.compiled, plain, settings) if plain.status == SOLVED else None
        extra = time.process_time() - c1       # `solution` set stats.cpu_time to the run's as of then
        if checked is None or not checked.ok:
            for f, x in kept.items():
                setattr(self.stats, f, x)
            return res, report, extra
        self.say("  active set: the optimised solution fails the verification; the feasible one is returned")
        plain.message += ("; the optimised solution failed the independent verification "
                          f"({report.failures[0]}), so the plan's feasible solution is returned")
        return plain, checked, extra

    def repair(self, check: FeasibilityCheck, graph: GraphNLP, values: dict[VarInstance, np.ndarray]):
        """`graph` (a solution's graph with the active set's new pair factors) solved from that
        solution phase by phase: the mode switches from its keyframes when they violate a new
        keyframe row (one start), then every motion between the fixed keyframes
        (`TrajectoryPhase.motions_between_keyframes`: a motion whose previous waypoints still
        satisfy its rows is kept by a numpy check, the others get a small NLP each, a motion
        that fails there is joined with the keyframes, up to REPAIR_JOINED_MOTIONS). Returns a
        solution of the whole graph checked with numpy (`known_solution`), or False when the
        repair failed (no verdict: the caller runs Algorithm 1 on the graph), or None for a
        graph without motions (the caller solves it jointly from `values`)."""
        trajs = [v for v in graph.variables if v.waypoints]
        if not trajs or any(v not in values for v in graph.variables):
            return None
        keyframes = {v: values[v] for v in graph.variables if not v.waypoints}
        modes = graph.apply_relaxation({TRAJ}, "modes")
        if modes.n_factors and any(is_trajectory(v) for v in graph.variables):
            point = {v: keyframes[v] for v in modes.variables}
            if not self.violation(modes.factor_instances, point, modes.variables) <= self.options.tolerance:
                r = check.local_solve(modes, point)
                if not r.feasible:
                    self.say(f"  active set: keyframes not repaired (violation {r.max_violation:.2g})")
                    return False
                keyframes.update(r.values)
        check.values.update(keyframes)
        r = check.motions_between_keyframes(graph, trajs, {v: values[v] for v in trajs},
                                            max_joined=self.repair_joins(graph) if check.screen
                                            else REPAIR_JOINED_MOTIONS)
        return r if r is not None and r.feasible else False

    def repair_joins(self, graph: GraphNLP) -> int:
        """Motions the repair may join with the keyframes: REPAIR_JOINED_MOTIONS, or
        MAX_JOINED_MOTIONS when the keyframes+motions NLPs are screened (`screening`: at least
        SCREEN_MIN_FACTORS collision factors). Why: one join was chosen because a join cost a
        whole keyframe NLP (lab4: 12 s more for the extra joins); screened, it costs a few of
        its near pairs (stack_16: 3438 factors, 21 s -> 840 factors, 1.3 s), while giving up
        sends the plan back to Algorithm 1, whose motions then fail between the same keyframes
        again (stack_16: motion 4 and 5, 7-11 s each, twice)."""
        from gnppdsl.solve.motions import MAX_JOINED_MOTIONS
        from gnppdsl.solve import screening

        if self.options.screen_collisions and sum(
                "collision" in f.tags and not any(v.waypoints for v in f.variables)
                for f in graph.factor_instances) >= screening.SCREEN_MIN_FACTORS:
            return max(REPAIR_JOINED_MOTIONS, MAX_JOINED_MOTIONS)
        return REPAIR_JOINED_MOTIONS


__all__ = ["Coverage"]
