"""One solve's state and services, shared by the loops (GNPP, One-way, R-LGP): the deadline,
statistics, the incremental planner, one FeasibilitySolver per plan graph, the subgraph database,
conflicts handed to the planner, the independent re-check of a solution and the `Result`.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING, Any, Iterable, Sequence

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.conflicts.batch import Batcher, Reachable
from gnppdsl.conflicts.database import names_of
from gnppdsl.conflicts.lifting import Lifter
from gnppdsl.conflicts.mapping import conflict_str, to_partial_states
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.compiled import Compiled
from gnppdsl.solve.deadline import TimeUp, deadline_solver
from gnppdsl.solve.lazy_database import LazyDatabase
from gnppdsl.solve.optimal import optimisation_phase
from gnppdsl.solve.options import Progress, SolveOptions
from gnppdsl.solve.path_length import path_lengths
from gnppdsl.solve.plan_graph import bound_violation, plan_graph
from gnppdsl.solve.result import NO_PLAN, SOLVED, SOLVER_FAILURE, TIME_LIMIT, Conflict, Result, Stats, steps_of
from gnppdsl.solve.batch_run import BatchLearning
from gnppdsl.solve.rlgp import ReachabilityCosts

if TYPE_CHECKING:  # pragma: no cover  (clingo, casadi: imported when a solve starts)
    from gnppdsl.logic.planner import Plan, PlanResult
    from gnppdsl.nlp.feasibility import FeasibilitySolver


class Run(ReachabilityCosts, BatchLearning):
    """What one solve holds while its loop runs (see the module docstring); the evaluation of
    a plan's graph (`plan_evaluation.PlanEvaluation`) and the loops (`loop.Loop`) derive from it."""

    def __init__(self, compiled: Compiled, options: SolveOptions, progress: Progress | None):
        from gnppdsl.logic.modes import make_planner

        self.compiled, self.options, self.progress = compiled, options, progress
        self.task = compiled.task
        # the deadline counts from the solve's start, loading and grounding included when the
        # caller says when that was (`SolveOptions.started`)
        self.start = time.perf_counter() if options.started is None else options.started
        self.cpu_start = time.process_time() if options.cpu_started is None else options.cpu_started
        self.children_cpu_start = _children_cpu()
        self.deadline = self.start + options.time_limit
        self.stats = Stats()
        watch = getattr(progress, "watch", None)   # a live status line reads the counters (cli/status.py)
        if watch is not None:
            watch(self.stats)
        self.conflicts: list[Conflict] = []
        self.reach = {}                   # robot -> (ReachabilityGraph, block)
        self.task = self.with_travel_costs(self.task)     # `travel(...)` costs from the graph
        if options.algorithm == "rlgp":
            self.task = self.with_reachability_costs(self.task)
        t0, c0 = time.perf_counter(), _cpu()
        self.planner = make_planner(self.task, options.planner, max_horizon=options.max_horizon)
        self.stats.logic_time += time.perf_counter() - t0
        self.stats.logic_cpu += _cpu() - c0
        from gnppdsl.nlp import jit

        forget = getattr(compiled.geometry, "forget_evaluations", None)
        if forget is not None:                 # a solve starts with no remembered evaluations
            forget()
        self.compiler = compiled.body_compiler(jit.mode(options.jit))
        self.kernels = self.compiler.kernels
        self.kernel_base = (0, 0.0, 0, 0)   # kernels compiled, compile time, failed, queued before this run
        if self.kernels is not None:
            self.kernels.deadline = self.deadline
            self.kernel_base = (self.kernels.compiled, self.kernels.compile_time, self.kernels.failed,
                                self.kernels.queued)
        self.solvers: list[FeasibilitySolver] = []      # every FeasibilitySolver of this run (ipopt runs, time)
        self.held: dict[int, tuple] = {}  # id(factor) -> (factor, {values key: violation}): `violation`
        self.screen_curved = False        # a screened NLP failed linearised and was solved with the
                                          # distances' curvature: later ones start with it (`screening`)
        self.nlp_calls = 0                # NLPs solved through FeasibilityCheck.solve
        self.heuristic_solves = 0         # NLPs Alg. 1 solved itself for a convergence point
        self.db: LazyDatabase | None = None   # records built when a query could match (`lazy_database`)
        if "g" in options.switches:
            self.db = LazyDatabase(options.database, scope=compiled.domain_name,
                                       fingerprint=compiled.fingerprint, object_key=compiled.object_key)
        self.lifter: Lifter | None = None
        if options.lift_conflicts and compiled.object_key is not None:
            self.lifter = Lifter(compiled.factory, self.task, compiled.problem.objects, compiled.object_key)
        self.batcher: Batcher | None = None
        self.graph_factors = 0            # factors of the last plan's graph-NLP (`build_graph`)
        self.graph_keyframes = 1          # ... and its keyframes (states)
        self.last_optimum = None          # (plan names, values) of the last accepted optimisation phase
        if options.batch_conflicts > 0 and options.algorithm != "oneway" and compiled.object_key is not None:
            self.batcher = Batcher(self.lifter or Lifter(compiled.factory, self.task, compiled.problem.objects,
                                                         compiled.object_key),
                                   options.batch_conflicts, reachable=Reachable(self.task),
                                   lazy=options.batch_lazy, subtype=compiled.problem.domain.is_subtype)
        self.batch_origin: int | None = None   # lazy batch: the origin of the candidate being learned
        self.stutter_memo: dict = {}            # full state -> the chain links of s -> s (`stutter`)
        self.windows: dict = {}                 # conflict -> the full states its image's steps index
        self.batch_shapes_memo: dict = {}       # lazy batch: Candidate.key -> its interleaved instances
        self.batch_lifted_memo: dict = {}       # lazy batch: Candidate.key -> [its renamings, its lifted images]
        self.attempt_cpu = time.process_time()   # CPU clock when the current plan's attempt began

    def say(self, msg: str) -> None:
        if self.progress is not None:
            self.progress(msg)

    def remaining(self) -> float:
        return self.deadline - time.perf_counter()

    def new_solver(self) -> FeasibilitySolver:
        """One FeasibilitySolver per plan graph (its assembled-NLP cache is keyed by vertex
        sets whose factor references are positions in *this* graph's factor list); the casadi
        Function cache (BodyCompiler) is shared by the whole run."""
        from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

        kw = {} if self.options.restarts is None else {"restarts": self.options.restarts}
        opts = SolverOptions(tolerance=self.options.tolerance, max_iter=self.options.max_iter,
                             plugin=self.options.nlp, time_limit=max(0.05, self.remaining()),
                             distance_curvature=self.options.distance_curvature,
                             kinematic_curvature=self.options.kinematic_curvature, **kw)
        solver = deadline_solver(FeasibilitySolver)(self.compiled.geometry, opts, compiler=self.compiler)
        solver.deadline = self.deadline
        if self.solvers:                 # kinematic_curvature auto: one record for the run
            solver.trials = self.solvers[0].trials
        self.solvers.append(solver)
        return solver

    def build_graph(self, states: Sequence[Sequence[int]]) -> GraphNLP:
        t0 = time.perf_counter()
        graph = plan_graph(self.compiled.factory, states)
        self.reach_keyframe_starts(graph, states)
        self.stats.factory_time += time.perf_counter() - t0
        self.graph_factors = graph.n_factors       # the batch's gate (`batch_min_factors`,
        self.graph_keyframes = len(states)         # `batch_min_keyframe_factors`)
        return graph

    def next_plan(self, enumerate_: bool) -> PlanResult:
        t0, c0 = time.perf_counter(), _cpu()
        try:
            if enumerate_:
                res = self.planner.next_plan(time_limit=max(0.0, self.remaining()))
            else:
                res = self.planner.shortest_plan(time_limit=max(0.0, self.remaining()),
                                                 minimize_cost=self.options.algorithm == "rlgp")
        finally:
            # a search stopped by the run's alarm or a signal (`interrupt.Interrupted`) still
            # counts: without this, lab5_paper's last Fast Downward search (> 50 s, cut off at
            # the time limit) was missing from logic_time
            self.stats.logic_time += time.perf_counter() - t0
            self.stats.logic_cpu += _cpu() - c0
        if res.plan is not None and self.stats.first_plan_time is None:
            self.stats.first_plan_time = time.perf_counter() - self.start
            self.stats.N0_shortest = res.plan.shortest
            if not res.plan.shortest:
                self.say(f"logic: {res.message} (N0 = {len(res.plan)} is not proven shortest)")
        return res
    sweeping_restarts = 8                 # random starts behind a conflict without facts

    def confirm_sweeping(self, sub_factors: Sequence[FactorInstance]) -> bool:
        """A conflict whose partial states hold no fact (its factors come from `always` rules
        only) matches every plan long enough: accepting it ends the search with "no plan".
        Such a sweeping claim gets a stricter check first: the subgraph is solved again from
        `sweeping_restarts` random starts; any solution refutes it (a false infeasible verdict,
        e.g. a local minimum). True if the conflict is not sweeping or stays infeasible."""
        if any(p.facts for p in to_partial_states(sub_factors)):
            return True
        solver = self.new_solver()
        solver.options.restarts = max(solver.options.restarts, self.sweeping_restarts)
        solver.options.noise = max(solver.options.noise, 1.0)
        return self.infeasible(solver, sub_factors, self.options.seed + 1)

    def infeasible(self, solver, factors: Sequence[FactorInstance], seed: int) -> bool:
        """The verdict of one stricter re-solve of `factors` (a sweeping conflict's check, a
        minimised conflict's smaller subgraph). A run cut short by the run's deadline or by
        ipopt's own time limit ("walltime", as `FeasibilityCheck.solve` reads it) is no
        verdict: TimeUp."""
        from gnppdsl.nlp.graph import GraphNLP

        r = solver.solve(GraphNLP(list(factors)), seed=seed)
        self.nlp_calls += 1
        if not r.feasible and (time.perf_counter() >= self.deadline or "walltime" in str(r.status).lower()):
            raise TimeUp()
        return not r.feasible

    def minimised(self, sub_factors: Sequence[FactorInstance]) -> tuple[FactorInstance, ...]:
        """The conflict's facts by the deletion filter (`conflicts.minimise`): each smaller
        subgraph is solved as the conflict itself is confirmed (the solver's restarts), so a
        dropped fact rests on the same infeasible verdict as the conflict."""
        from gnppdsl.conflicts.minimise import minimise_facts

        t0 = time.perf_counter()
        out, checks = minimise_facts(
            sub_factors, lambda factors: self.infeasible(self.new_solver(), factors, self.options.seed))
        self.stats.minimise_time += time.perf_counter() - t0
        self.stats.minimise_checks += checks
        return out

    def add_conflict(self, plan: Plan, sub_factors: Sequence[FactorInstance], source: str,
                     relaxation: str) -> None:
        """Map the infeasible subgraph to <p_0 ... p_L> (Sec. VII) and hand it to the planner,
        with every symmetric instance the factory confirms (`Lifter`, option lift_conflicts)
        as one lifted conflict."""
        if self.options.minimise_conflicts and source == "nlp":
            sub_factors = self.minimised(sub_factors)
        seq = to_partial_states(sub_factors)
        first = min(f.step for f in sub_factors)
        # the conflict must hold in the plan that produced it, else it would not exclude it
        holds = all(p.holds_in(plan.states[first + l]) for l, p in enumerate(seq))
        if not holds:
            raise AssertionError(f"conflict {seq} does not hold in the plan it came from at step {first}")
        t0, c0 = time.perf_counter(), _cpu()
        instances = [seq]
        self.images = {seq: tuple(sub_factors)}
        self.windows = {seq: list(plan.states)}      # the full states the images' steps index
        if self.lifter is not None:
            instances = self.lifter.instances(plan.states, sub_factors)
            self.images.update(self.lifter.images)
            self.windows.update(self.lifter.windows)
            self.stats.lift_time += time.perf_counter() - t0
        batched: list = []
        if self.batcher is not None and (
                self.graph_factors >= self.options.batch_min_factors
                or self.graph_factors >= self.options.batch_min_keyframe_factors * self.graph_keyframes):
            # NLPs, not logic: left out of logic_time / logic_cpu (its own batch_time)
            t1, c1 = time.perf_counter(), _cpu()
            batched = self.batch(plan, sub_factors, instances)
            t0, c0 = t0 + time.perf_counter() - t1, c0 + _cpu() - c1
        interleaved = self.interleaved(instances + batched)
        known = seq in set(self.planner.conflicts)
        new = self.planner.add_lifted(instances + batched + interleaved)
        if known or not new:
            # the planner already forbids it, yet proposed this plan: never loop forever
            self.planner.block_plan(plan)
        self.stats.logic_time += time.perf_counter() - t0
        self.stats.logic_cpu += _cpu() - c0
        others = tuple(conflict_str(self.task, s) for s in instances[1:])
        c = Conflict(seq, conflict_str(self.task, seq), tuple(f.label for f in sub_factors), source,
                     relaxation, self.stats.plans, first, named=names_of(self.task, seq),
                     instances=others, subgraph=tuple(sub_factors),
                     batched=tuple(conflict_str(self.task, s) for s in batched),
                     interleaved=tuple(conflict_str(self.task, s) for s in interleaved))
        self.conflicts.append(c)
        self.stats.conflicts += 1
        self.stats.conflict_instances += new
        self.stats.interleaved_instances += len(interleaved)
        lifted = f" (+{len(others)} symmetric instances)" if others else ""
        lifted += f" (+{len(batched)} batch-learned)" if batched else ""
        lifted += f" (+{len(interleaved)} interleaved)" if interleaved else ""
        self.say(f"  conflict ({source}{', ' + relaxation if relaxation else ''}): {c.text}{lifted}")

    def interleaved(self, seqs: Sequence) -> list:
        """The interleaved instances (`gnppdsl.conflicts.interleave`) of the conflicts `seqs` whose
        factors are known (`self.images`), up to the planner's horizon; none already in `seqs`
        or forbidden by the planner. Option stretch_conflicts: `preorder` templates count as
        chain links too."""
        if not self.options.interleave_conflicts:
            return []
        from gnppdsl.conflicts.interleave import stretched

        have = set(seqs) | set(self.planner.conflicts)
        out = []
        for s in seqs:
            factors = self.images.get(s)
            if factors is None:
                continue
            for inst in stretched(factors, self.options.max_horizon + 1,
                                  preorder=bool(self.options.stretch_conflicts),
                                  stutter=self.stutter(self.windows.get(s)))[1:]:
                if inst not in have:
                    have.add(inst)
                    out.append(inst)
        return out

    def stutter(self, states: Sequence[Sequence[int]] | None):
        """`interleave.Stutter` of a conflict whose factors' steps index the full `states`: the
        chain links the factory builds on the transition s_j -> s_j (memoised per state), at
        steps j, j+1. None without states (the conflict is stretched as before)."""
        if states is None:
            return None
        from gnppdsl.conflicts.interleave import chain_link

        preorder = bool(self.options.stretch_conflicts)

        def links(j: int) -> list:
            if not 0 <= j < len(states):
                return []
            s = tuple(states[j])
            if s not in self.stutter_memo:
                self.stutter_memo[s] = [f for f in self.compiled.factory.factors([s, s])
                                        if f.step == 0 and f.span == 2 and chain_link(f, preorder)]
            return [f.shifted(j) for f in self.stutter_memo[s]]
        return links

    def result(self, status: str, message: str, **kw: Any) -> Result:
        self.finish_stats()
        if self.db is not None:
            self.stats.db_match_time = self.db.stats.match_time
            self.stats.db_match_budget_exceeded = self.db.stats.budget_exceeded
            self.db.close()
        return Result(problem=self.compiled.name, domain=self.compiled.domain_name,
                      algorithm=self.options.algorithm, switches=self.options.switches,
                      seed=self.options.seed, status=status, message=message,
                      conflicts=self.conflicts, stats=self.stats, time_limit=self.options.time_limit, **kw)

    def finish_stats(self) -> None:
        """The run's totals in `stats` (times, NLP counts, kernels) as of now; called by `result`
        and again by the anytime phase, whose result is an earlier one."""
        self.stats.total_time = time.perf_counter() - self.start
        if self.reach:
            self.reach_statistics()
        # CPU of this process and of the child processes it waited for (the C compiler of the
        # setting jit: 0 with a warm cache; nothing else in a solve starts processes)
        self.stats.cpu_time = time.process_time() - self.cpu_start + _children_cpu() - self.children_cpu_start
        if self.kernels is not None:
            self.stats.kernels_native = self.kernels.loaded
            self.stats.kernels_compiled = self.kernels.compiled - self.kernel_base[0]
            self.stats.kernel_compile_time = self.kernels.compile_time - self.kernel_base[1]
            self.stats.kernels_failed = self.kernels.failed - self.kernel_base[2]
            self.stats.kernels_queued = self.kernels.queued - self.kernel_base[3]
            self.stats.kernel_error = self.kernels.last_error if self.stats.kernels_failed else ""
        # NLPs = feasibility problems solved (each may take several ipopt runs: restarts and
        # a polish before an infeasible verdict, counted in ipopt_runs); time of all of them
        self.stats.nlp_solves = self.nlp_calls + self.heuristic_solves
        self.stats.ipopt_runs = sum(s.solves for s in self.solvers)
        self.stats.nlp_time = sum(s.solve_time for s in self.solvers)
        self.stats.curvature_fallbacks = sum(s.curvature_fallbacks for s in self.solvers)
        self.stats.curvature_rescues = sum(s.curvature_rescues for s in self.solvers)

    def stop_result(self, res: PlanResult) -> Result:
        from gnppdsl.logic.planner import Status

        if res.status is Status.TIMEOUT or self.remaining() <= 0:
            return self.result(TIME_LIMIT, f"time limit of {self.options.time_limit:g} s reached "
                                           f"after {self.stats.plans} plans")
        return self.result(NO_PLAN, (res.message or "no plan") + self.local_conflicts_note())

    def local_conflicts_note(self) -> str:
        """For a "no plan" under conflicts that NLPs found (Alg. 1 or the database of their
        verdicts), what it rests on: a local solver's failure from the starts it tried, not a
        proof. Why said: pick_place3 instance 8 with plain GNPP learns {parent(red1) = center,
        not moved(red1)} -> pick from a base drive that fails from its straight-line start, and
        ends "no plan", while R-LGP's graph waypoints solve the same pick; a user must be able to
        tell such a verdict from a logical impossibility."""
        n = sum(c.source in ("nlp", "database") for c in self.conflicts)
        if not n:
            return ""
        return (f"; {n} of the conflicts {'rests' if n == 1 else 'rest'} on NLPs infeasible from every start tried (local "
                f"solves, not proofs): another seed, or R-LGP on a mobile manipulator, may "
                f"find a plan")

    def violation(self, factors: Sequence[FactorInstance], point: dict,
                  variables: Iterable[VarInstance] = ()) -> float:
        """Largest violation of `factors` (and of the bounds of `variables`) at `point` by the
        independent numpy evaluator; inf when a primitive cannot be evaluated there (the
        caller then solves instead). Counted in `stats.reuse_time`.

        A factor found to hold is remembered with the values of its variables (`remember_held`)
        and not evaluated again at the same values; what is returned for it is the largest
        violation of the call that found it (at most the tolerance). Why: the same factors are
        re-checked at the same values many times -- a keyframe's own factors by both phases
        next to it, every motion by its screened NLP's check and again by the whole graph's
        (`known_solution`); on stack_16 the numpy checks cost more than the motions' NLPs."""
        from gnppdsl.nlp.evaluate import max_violation

        t0 = time.perf_counter()
        try:
            todo, known = [], 0.0
            for f in factors:
                w = self._held_at(f, point)
                if w is None:
                    todo.append(f)
                else:
                    known = max(known, w)
            worst = max_violation(todo, point, self.compiled.geometry)[0] if todo else 0.0
        except Exception:
            return np.inf
        finally:
            self.stats.reuse_time += time.perf_counter() - t0
        if worst <= self.options.tolerance:
            self.remember_held(todo, point, worst)
        return max(worst, known, bound_violation(variables, point))

    def _held_at(self, f: FactorInstance, point: dict) -> float | None:
        entry = self.held.get(id(f))
        return None if entry is None else entry[1].get(_values_key(f, point))

    def remember_held(self, factors: Iterable[FactorInstance], point: dict, worst: float) -> None:
        """The factors hold at `point` within `worst` (<= the tolerance), checked with numpy
        by the caller: `violation` takes that for the same values of their variables. (Keyed
        by the factor object, which the entry keeps alive, and the bytes of its variables'
        values: an equal check, not a nearby one.)"""
        if not worst <= self.options.tolerance:
            return
        for f in factors:
            entry = self.held.get(id(f))
            if entry is None:
                entry = self.held[id(f)] = (f, {})
            entry[1][_values_key(f, point)] = worst

    def solution(self, plan: Plan, graph: GraphNLP, values: dict[VarInstance, np.ndarray]) -> Result:
        from gnppdsl.nlp.evaluate import EvaluationError, max_violation

        values = self.optimised(plan, graph, values)
        factors = graph.factor_instances
        try:
            worst, arg = max_violation(factors, values, self.compiled.geometry)
        except EvaluationError as err:    # a body the numpy re-check cannot evaluate
            return self.result(SOLVER_FAILURE, f"the solution cannot be re-checked independently: {err}",
                               plan=list(plan.names))
        bound_worst = bound_violation(graph.variables, values)
        worst = max(worst, bound_worst)
        self.stats.max_violation = worst
        self.stats.N = len(plan)
        self.stats.plan_cost = sum(self.task.operators[o].cost for o in plan.operators)
        self.stats.factors = len(factors)
        self.stats.variables = len(graph.variables)
        steps = steps_of(self.task, plan, graph, values)
        tol = self.options.check_tolerance or self.options.tolerance
        extras = {"task": self.task, "plan": plan, "graph": graph, "values": values}
        lengths = path_lengths(graph.variables, values, self.compiled.geometry) \
            if self.compiled.geometry is not None else {}
        if not worst <= tol:
            what = arg.label if arg is not None and worst > bound_worst else "a variable bound"
            return self.result(SOLVER_FAILURE,
                               f"the solver's solution fails the independent re-check: {what} "
                               f"violated by {worst:.3g} > {tol:g}",
                               plan=list(plan.names), steps=steps, extras=extras, path_length=lengths)
        return self.result(SOLVED, f"solved with {len(plan)} actions after {self.stats.plans} plans",
                           plan=list(plan.names), steps=steps, extras=extras, path_length=lengths)

    def optimised(self, plan: Plan, graph: GraphNLP, values: dict[VarInstance, np.ndarray]
                  ) -> dict[VarInstance, np.ndarray]:
        """The optimisation phase (`solve.optimal`) on the plan's feasible solution, when its
        rule instances carry `minimize` terms; the objective goes to `stats.cost`."""
        terms = self.compiled.factory.objectives(plan.states)
        if not terms:
            return values
        tol = self.options.check_tolerance or self.options.tolerance
        budget = self.remaining() if self.options.optimise else 0.0
        solver = None

        def polish(point: dict) -> dict | None:
            nonlocal solver
            from gnppdsl.solve.options import overridden

            solver = solver or self.new_solver()
            with overridden(solver.options, restarts=0):
                res = solver.solve(graph, warm_start=point)
            return res.values if res is not None and res.feasible else None

        # the plan's last optimised point (an active-set round added pair factors since): where the
        # phase starts first (`optimisation_phase`, `previous`)
        last = self.last_optimum
        previous = last[1] if last is not None and last[0] == plan.names else None
        out = optimisation_phase(graph, terms, values, self.compiler, self.compiled.geometry, tol, budget,
                                 polish, previous)
        if out.accepted:
            self.last_optimum = (plan.names, out.values)
        self.stats.cost_feasible, self.stats.cost = out.cost_before, out.cost
        self.stats.optimise_time, self.stats.optimised = out.seconds, out.accepted
        if out.cost is not None:
            self.say(f"objective {out.cost_before:.6g} at the feasible solution -> {out.cost:.6g}"
                     f"{'' if out.accepted else ' (' + out.note + ')'}")
        return out.values


def _cpu() -> float:
    """CPU seconds of this process and its finished children (Fast Downward runs in one)."""
    return time.process_time() + _children_cpu()


def _children_cpu() -> float:
    """CPU seconds of finished child processes (the C compiler of `gnppdsl.nlp.jit`, Fast
    Downward in the logic modes fd and auto)."""
    import resource

    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _values_key(f: FactorInstance, point: dict) -> tuple:
    """The values of f's variables at `point`, as bytes (`Run.remember_held`)."""
    return tuple(np.asarray(point[u], float).tobytes() for u in f.variables)
