"""The Graph-NLP Planner loop (paper 000, Fig. 3) and the One-way baseline.

GNPP, repeated until a plan's graph-NLP is feasible:
  1. the logic planner proposes the shortest plan <s_0 ... s_n> not excluded by any conflict;
  2. the factory builds its graph-NLP G;
  3. (switch g) if G contains a subgraph known to be infeasible, that is the conflict (no NLP);
     otherwise `PlanEvaluation.evaluate` runs Algorithm 1: relaxations loose -> tight (switch r), the
     full graph last; an infeasible relaxed graph is searched component by component with the
     double binary search on time (t) and the convergence heuristic (n), via
     `gnppdsl.nlp.subgraph.find_infeasible_subgraph`, then shrunk to the subgraph induced by
     the violated factors' variables (n). Every feasibility check goes through `FeasibilityCheck`,
     which answers from the database of solved subgraphs (switch g), solves trajectories after
     the mode switches (Appendix C), counts NLPs and enforces the time limit;
  4. feasible: the solution is re-checked independently (numpy evaluation of every factor of
     the full graph, `gnppdsl.nlp.evaluate`) and returned; infeasible: the subgraph is mapped to
     partial states <p_0 ... p_L> and added to the planner as a conflict (Sec. VII).

One-way (Sec. VIII-C): enumerate plans by length, solve each full graph-NLP, and block only the
failed plan; the planner learns nothing about why.

Time limit: one deadline for the whole solve, checked before every NLP and passed to the
planner and to ipopt (max_wall_time), so the loop ends soon after it with status time_limit.
"""
from __future__ import annotations

import time

from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Any, Sequence

from gnppdsl.compile.sas import PartialState
from gnppdsl.ir.model import Problem
from gnppdsl.solve.compiled import Compiled, compile_problem, load_and_compile
from gnppdsl import collector, interrupt
from gnppdsl.solve.deadline import TimeUp
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.options import Progress, SolveOptions
from gnppdsl.solve.anytime import Anytime
from gnppdsl.solve.result import INTERRUPTED, TIME_LIMIT, Conflict, Result
from gnppdsl.solve.timing import annotate_motion

if TYPE_CHECKING:  # pragma: no cover  (clingo: imported when a solve starts)
    from gnppdsl.logic.planner import Plan


class Loop(Anytime):
    """The loops of one solve: GNPP (Fig. 3; R-LGP when `algorithm` is rlgp, with the travel
    costs of `rlgp`) and One-way (Sec. VIII-C)."""

    def solve(self) -> Result:
        try:
            if self.options.algorithm == "oneway":
                return self.oneway()
            return self.gnpp()
        except TimeUp:
            return self.result(TIME_LIMIT, f"time limit of {self.options.time_limit:g} s reached "
                                           f"after {self.stats.plans} plans")
        except interrupt.Interrupted as stop:          # SIGINT / SIGTERM / the run's alarm
            return self.result(TIME_LIMIT if stop.reason == "time_limit" else INTERRUPTED,
                               f"{stop.describe()} after {self.stats.plans} plans")

    def gnpp(self) -> Result:
        while True:
            res = self.next_plan(enumerate_=False)
            if not res.found:
                return self.stop_result(res)
            out = self.attempt(res.plan)
            if out is not None:
                return self.improve(out) if self.options.anytime > 0 and out.solved else out

    def attempt(self, plan: Plan) -> Result | None:
        """Fig. 3, steps 2-4 on one plan: its verified Result (solved or not), or None when the
        plan gave a conflict (handed to the planner) or was blocked."""
        self.stats.plans += 1
        self.attempt_cpu = time.process_time()     # the lazy batch's eager share (`Run.batch`)
        if self.stats.N0 is None:
            self.stats.N0 = len(plan)
        self.say(f"plan #{self.stats.plans} (length {len(plan)}): {', '.join(plan.names) or '(empty)'}")
        if self.batch_hit(plan):           # a queued renamed candidate it holds is infeasible
            return None
        graph = self.build_graph(plan.states)
        if self.db is not None and self.db.knows_infeasible():   # (no record: no semantic graph to build)
            known = self.db.infeasible_inside(graph)
            if known:
                self.stats.db_infeasible_hits += 1
                self.add_conflict(plan, known, "database", "")
                return None
        outcome = self.evaluate(graph, use_db=self.db is not None)
        if outcome[0] == "solution":           # verified; near pairs join (the active set)
            outcome = self.cover(plan, graph, outcome[1])
        if outcome[0] == "result":
            return outcome[1]
        if outcome[0] == "conflict":
            if not self.confirm_sweeping(outcome[1]):
                self.say("  plan blocked: a conflict without facts (it would forbid every plan) "
                         "was found feasible from more starts")
                self.planner.block_plan(plan)
                self.conflicts.append(Conflict(
                    tuple(PartialState.of(enumerate(s)) for s in plan.states),
                    "blocked plan (a conflict without facts failed its confirmation): "
                    + "; ".join(plan.names), (), "plan", "", self.stats.plans, 0))
                return None
            self.add_conflict(plan, outcome[1], "nlp", outcome[2])
            return None
        # the solver contradicted itself (infeasible as a whole, every component feasible):
        # no sound conflict, so only this plan is given up
        self.say(f"  plan blocked: {outcome[1]}")
        self.planner.block_plan(plan)
        self.conflicts.append(Conflict(tuple(PartialState.of(enumerate(s)) for s in plan.states),
                                       f"blocked plan ({outcome[1]}): " + "; ".join(plan.names), (),
                                       "plan", "", self.stats.plans, 0))
        return None

    def oneway(self) -> Result:
        while True:
            res = self.next_plan(enumerate_=True)      # next_plan blocks the plan it returns
            if not res.found:
                return self.stop_result(res)
            plan = res.plan
            self.stats.plans += 1
            if self.stats.N0 is None:
                self.stats.N0 = len(plan)
            self.say(f"plan #{self.stats.plans} (length {len(plan)}): {', '.join(plan.names) or '(empty)'}")
            graph = self.build_graph(plan.states)
            r = FeasibilityCheck(self, self.new_solver(), graph, use_db=False).solve(graph)
            if r.feasible:
                outcome = self.cover(plan, graph, r.values)
                if outcome[0] == "result":
                    return outcome[1]             # else: blocked with the pairs it brings near
            self.stats.conflicts += 1
            self.conflicts.append(Conflict(tuple(PartialState.of(enumerate(s)) for s in plan.states),
                                           "blocked plan: " + "; ".join(plan.names), (), "plan", "",
                                           self.stats.plans, 0))


def solve_compiled(compiled: Compiled, options: SolveOptions | None = None,
                   progress: Progress | None = None) -> Result:
    """Solve an already compiled problem (a fresh planner, solver caches and database per call)."""
    options = (options or SolveOptions.from_settings(getattr(compiled.problem, "settings", None))).validated()
    with collector.solving():             # fewer passes of the cyclic collector (collector.py)
        result = Loop(compiled, options, progress).solve()
    annotate_motion(result, compiled)      # joint names, time stamps, world poses (timing.py)
    return result


def solve_problem(problem: str | Path | Sequence[str] | Problem | Compiled, options: SolveOptions | None = None,
                  progress: Progress | None = None,
                  **overrides: Any) -> Result:
    """Solve a problem given as a path, a list of paths, an IR `Problem` or a `Compiled`.

    Keyword overrides (algorithm, switches, time_limit, seed, ...) apply on top of `options`,
    or of the problem's own solver settings when `options` is None.
    """
    started = (time.perf_counter(), time.process_time())     # loading and grounding count
    if isinstance(problem, Compiled):
        compiled = problem
        started = (None, None)
    elif isinstance(problem, (str, Path, list, tuple)):
        compiled = load_and_compile(problem)
    else:
        compiled = compile_problem(problem)
    if options is None:
        options = SolveOptions.from_settings(getattr(compiled.problem, "settings", None), **overrides)
    elif overrides:
        options = replace(options, **{k: v for k, v in overrides.items() if v is not None}).validated()
    if options.started is None:
        options = replace(options, started=started[0], cpu_started=started[1])
    return solve_compiled(compiled, options, progress)
