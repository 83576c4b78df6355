"""What a solve returns: plan, states, continuous values, trajectories, conflicts, statistics.

Why dataclasses of plain values (strings, floats, lists): the result is printed by the CLI,
written as JSON (`--json FILE`), aggregated by `gnpp bench`, and re-checked by tests; none of
them should need the compiler's objects. Conflicts are kept both as SAS+ partial states (for
tests that re-solve them) and in DSL syntax (for people).
"""
from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

from gnppdsl.compile.sas import PartialState

# Why a solve ended. Only SOLVED carries a plan with continuous values.
SOLVED = "solved"
NO_PLAN = "no_plan"                 # the logic planner proved no (further) plan exists up to the horizon
TIME_LIMIT = "time_limit"
SOLVER_FAILURE = "solver_failure"   # a plan's graph-NLP was feasible in every check but the full solve failed
UNVERIFIED = "verification_failed"  # the solver's solution failed the independent verification and was not repaired
INTERRUPTED = "interrupted"         # SIGINT / SIGTERM (`gnppdsl.interrupt`): the partial result
#: largest violation a "solved" result may have at the independent re-check (`Result.checked`),
#: whatever tolerance was asked for: the tolerance option is capped at 1e-2 too
SANE_VIOLATION = 1e-2
STATUSES = (SOLVED, NO_PLAN, TIME_LIMIT, SOLVER_FAILURE, UNVERIFIED, INTERRUPTED)


def algorithm_title(algorithm: str, switches: str | None) -> str:
    """The name of an algorithm as in the papers' tables: One-way, GNPP_trn, R-LGP_trn."""
    if algorithm == "oneway":
        return "One-way"
    name = "R-LGP" if algorithm == "rlgp" else "GNPP"
    return f"{name}_{switches}" if switches else name


@dataclass
class Conflict:
    """An infeasible subgraph mapped back to partial states <p_0 ... p_L> (paper Sec. VII)."""

    partial_states: tuple[PartialState, ...]
    text: str                        # DSL syntax: `{parent(b1) = s1} -> {parent(b1) = g}`
    factors: tuple[str, ...]         # labels of the infeasible subgraph's factors
    source: str                      # "nlp" (Alg. 1), "database" (known infeasible), "plan" (One-way)
    relaxation: str = ""             # the relaxation in which it was found ("" = full graph)
    plan_index: int = 0              # which candidate plan produced it (1-based)
    at_step: int = 0                 # absolute step of p_0 in that plan
    named: tuple = ()                # the partial states by name: ((("parent(b1)", "s1"), ...), ...)
    instances: tuple = ()            # lifted: the further symmetric instances (DSL text each)
    batched: tuple = ()              # batch-learned: renamed instances an NLP found infeasible (DSL text each)
    interleaved: tuple = ()          # the instances above with steps inserted or removed where M allows
                                     # it (DSL text each; `gnppdsl.conflicts.interleave`)
    # not serialised: the infeasible subgraph's factor instances (tests re-solve them)
    subgraph: tuple = field(default=(), repr=False, compare=False)

    def to_json(self) -> dict:
        return {
            "text": self.text,
            "length": len(self.partial_states),
            "partial_states": [[list(f) for f in p.facts] for p in self.partial_states],
            "named": [[list(f) for f in p] for p in self.named],
            "factors": list(self.factors),
            "source": self.source,
            "relaxation": self.relaxation,
            "plan_index": self.plan_index,
            "at_step": self.at_step,
            "instances": list(self.instances),
            "batched": list(self.batched),
            "interleaved": list(self.interleaved),
        }


@dataclass
class Step:
    """One symbolic state s_i with its continuous values x_i (and the trajectory to s_{i+1})."""

    index: int
    action: str | None                        # the action that led here (None for s_0)
    state: str                                # s_i in DSL syntax
    values: dict[str, list[float]] = field(default_factory=dict)          # key -> x_i^k
    trajectories: dict[str, list[list[float]]] = field(default_factory=dict)  # key -> waypoints
    # filled by gnppdsl.solve.timing.annotate_motion: seconds from the start at s_i, the time of
    # each waypoint of the trajectories to s_{i+1}, world poses of the movable entities at s_i
    time: float | None = None
    trajectory_times: dict[str, list[float]] = field(default_factory=dict)
    world: dict[str, list[float]] = field(default_factory=dict)


@dataclass
class Stats:
    nlp_solves: int = 0               # NLPs handed to the solver (database hits not counted)
    ipopt_runs: int = 0               # solver runs behind them (multi-starts, polish re-solves)
    nlp_time: float = 0.0             # seconds inside the NLP solver
    curvature_fallbacks: int = 0      # kinematic_curvature auto: NLPs whose linearised runs did not
                                      # end feasible and were run again with the exact Hessian
    curvature_rescues: int = 0        # ... of which the exact runs found feasible
    logic_time: float = 0.0           # seconds in the logic planner (incl. adding conflicts)
    logic_cpu: float = 0.0            # CPU seconds of the same (Fast Downward's child processes included)
    factory_time: float = 0.0         # seconds building graph-NLPs
    reach_time: float = 0.0           # seconds building / querying reachability graphs (rlgp)
    reach_samples: int = 0            # rlgp: IK-validated end-effector samples of the graphs (Eq. 2)
    reach_restored: int = 0           # ... graphs whose samples came from the store (`reach.persist`)
    reach_queries: int = 0            # ... path queries (travel costs, warm starts)
    reach_library_hits: int = 0       # ... answered by the solution library
    reach_edge_checks: int = 0        # ... lazy edge collision checks
    reach_edges_removed: int = 0      # ... edges those checks removed
    reach_enhanced_nodes: int = 0     # ... nodes added by enhancement (Gaussian samples)
    reach_contact_ends: int = 0       # ... query ends in collision, joined by segments leaving it
    reach_warmstarts: int = 0         # trajectories warm-started with a graph path (getWaypoints)
    reach_waypoints: int = 0          # ... their waypoints
    reach_straight: int = 0           # warm starts the graph had no path for (straight line instead)
    total_time: float = 0.0           # wall clock
    cpu_time: float = 0.0             # CPU seconds of this process and its C compiler runs (the paper's "time")
    plans: int = 0                    # candidate logic plans evaluated
    conflicts: int = 0                # conflicts learned (a lifted conflict once)
    conflict_instances: int = 0       # ground instances they forbid (>= conflicts)
    interleaved_instances: int = 0    # ... of which interleaved (`conflicts.interleave`: steps inserted or removed)
    lift_time: float = 0.0            # seconds finding symmetric instances (`conflicts.lifting`)
    batch_candidates: int = 0         # renamed conflicts decided by an NLP (`conflicts.batch`)
    batch_learned: int = 0            # ... found infeasible, learned with their conflict
    batch_cached: int = 0             # renamed conflicts decided without an NLP (earlier verdict, database)
    batch_unreachable: int = 0        # renamed conflicts no plan reaches (h^2): dropped, no NLP
    batch_time: float = 0.0           # seconds building and solving them
    minimise_checks: int = 0          # NLPs of the fact minimisation (`conflicts.minimise`)
    minimise_time: float = 0.0        # seconds in it
    db_feasible_hits: int = 0
    db_infeasible_hits: int = 0
    db_match_time: float = 0.0        # seconds matching subgraphs in the database (`semantic.monomorphism`)
    db_match_budget_exceeded: int = 0  # matches given up at their budget (answered as misses)
    reused_solutions: int = 0         # subgraphs shown feasible by earlier solutions (no NLP)
    reuse_time: float = 0.0           # seconds spent evaluating those
    rechecks_feasible: int = 0        # failed graphs solved on a second try from their slices' solutions
    screened_levels: int = 0          # relaxation levels skipped: nearly hold at the full graph's x*
    screened_solves: int = 0          # graphs solved with only their near collision factors (`screening`)
    screened_dropped: int = 0         # collision factors those NLPs left out (checked with numpy)
    inferred_verdicts: int = 0        # infeasible components located at an infeasible graph's x*
    certified_verdicts: int = 0       # infeasible subgraphs certified at a graph's x* (no NLP)
    lazy_retries: int = 0             # Alg. 1 searches repeated with restarts (a one-start verdict was wrong)
    cold_refutations: int = 0         # conflicts-to-be found feasible from their initial guess (`Confirmation.cold_refutes`)
    kernels_native: int = 0           # derivative kernels run as compiled C (setting jit)
    kernels_compiled: int = 0         # ... of which compiled by this solve (the rest: from the cache)
    kernel_compile_time: float = 0.0  # seconds generating and compiling them (C compiler included)
    kernels_failed: int = 0           # kernels left to the virtual machine after an error
    kernels_queued: int = 0           # kernels handed to background compile workers (later solves load them)
    kernel_error: str = ""            # the last such error
    N0: int | None = None             # length of the first logical plan
    N0_shortest: bool | None = None   # the logic mode proved that first plan shortest (N0 exact)
    first_plan_time: float | None = None   # seconds from the start to the first logical plan
    N: int | None = None              # length of the returned solution
    max_violation: float | None = None   # independent re-check of every factor at the solution
    cost: float | None = None         # the objective (`minimize` terms) at the returned solution
    cost_feasible: float | None = None   # ... at the loop's feasible solution, before optimising
    optimised: bool = False           # the optimisation phase's point replaced that solution
    plan_cost: float | None = None    # the returned plan's symbolic action costs (operator costs)
    optimise_time: float = 0.0        # CPU seconds of the optimisation phase
    factors: int = 0                  # factors in the solution's graph-NLP
    variables: int = 0


@dataclass
class Result:
    problem: str
    domain: str
    algorithm: str                    # "gnpp" or "oneway"
    switches: str                     # subset of "trng" ("" for oneway)
    seed: int
    status: str
    message: str = ""
    plan: list[str] = field(default_factory=list)
    steps: list[Step] = field(default_factory=list)
    conflicts: list[Conflict] = field(default_factory=list)
    stats: Stats = field(default_factory=Stats)
    time_limit: float | None = None
    # filled by gnppdsl.solve.timing.annotate_motion (docs/result.schema.json)
    inputs: dict[str, str] = field(default_factory=dict)            # "problem", "domain": file paths
    coordinates: dict[str, list[str]] = field(default_factory=dict)  # variable key -> component names
    robots: dict[str, dict[str, Any]] = field(default_factory=dict)  # robot -> joints, configuration / trajectory keys
    # the independent verification (`gnppdsl.solve.verify_solution`): {ok, failures: [{kind,
    # step, waypoint, bodies, distance, message}], keyframes, waypoints, midpoints, min_distance}
    verification: dict[str, Any] | None = None
    # robot -> {"base": metres driven (None: fixed base), "end_effector": metres}
    path_length: dict[str, dict[str, float | None]] = field(default_factory=dict)
    # the anytime phase (`gnppdsl.solve.anytime.AnytimeReport.to_json`): cost = plan cost +
    # objective, whether optimality was proved and over which plans, the history (time, cost)
    anytime: dict[str, Any] | None = None
    # not serialised: the objects the tests re-check (task, factors, VarInstance -> value)
    extras: dict[str, Any] = field(default_factory=dict, repr=False, compare=False)

    @property
    def solved(self) -> bool:
        return self.status == SOLVED

    def checked(self, bound: float = SANE_VIOLATION) -> "Result":
        """This result, or a copy with status solver_failure when it claims "solved" but its
        independent re-check (`stats.max_violation`) exceeds `bound` or is not a number."""
        v = self.stats.max_violation
        if not self.solved or v is None or (math.isfinite(v) and v <= bound):
            return self
        from dataclasses import replace

        return replace(self, status=SOLVER_FAILURE,
                       message=f"the solution's constraint violation {v:.3g} exceeds {bound:g} at the "
                               f"independent re-check; not reported as solved")

    @property
    def algorithm_name(self) -> str:
        return algorithm_title(self.algorithm, self.switches)

    # ---- output ------------------------------------------------------------------------------
    def to_json(self) -> dict:
        return {
            "problem": self.problem,
            "domain": self.domain,
            "algorithm": self.algorithm,
            "algorithm_name": self.algorithm_name,
            "switches": self.switches,
            "seed": self.seed,
            "status": self.status,
            "solved": self.solved,
            "message": self.message,
            "time_limit": self.time_limit,
            "inputs": dict(self.inputs),
            "plan": list(self.plan),
            "coordinates": dict(self.coordinates),
            "robots": dict(self.robots),
            "steps": [asdict(s) for s in self.steps],
            "conflicts": [c.to_json() for c in self.conflicts],
            "cost": _finite({"cost": self.stats.cost})["cost"],
            "path_length": _finite(self.path_length),
            "stats": _finite(asdict(self.stats)),
            "verification": self.verification,
            "anytime": self.anytime,
        }

    def write_json(self, path: str | Path, what: str = "--json") -> None:
        """Write atomically and never through a symbolic link (`gnppdsl.outputs`), so a
        reader never sees half a file; errors name the option (`what`)."""
        from gnppdsl.outputs import write_atomic

        write_atomic(path, json.dumps(self.to_json(), indent=2) + "\n", what)

    def summary(self, max_conflicts: int = 20) -> str:
        s = self.stats
        lines = [f"{self.problem} ({self.domain}) with {self.algorithm_name}, seed {self.seed}: "
                 + ("SOLVED" if self.solved else f"NOT SOLVED ({self.status})")]
        if self.message:
            lines.append(f"  {self.message}")
        if self.solved:
            lines.append(f"plan ({len(self.plan)} actions):")
            for st in self.steps:
                head = f"  s{st.index}" + (f"  <- {st.action}" if st.action else "  (initial)")
                lines.append(head)
                lines.append(f"      {st.state}")
                for key, val in st.values.items():
                    lines.append(f"      {key} = [{', '.join(_num(x) for x in val)}]")
                for name, pose in st.world.items():
                    lines.append(f"      world {name} = [{', '.join(_num(x) for x in pose)}]")
                for key, pts in st.trajectories.items():
                    lines.append(f"      {key}: {len(pts)} waypoints to s{st.index + 1}")
        if self.conflicts:
            lines.append(f"conflicts ({len(self.conflicts)}):")
            for c in self.conflicts[:max_conflicts]:
                where = f" [{c.relaxation}]" if c.relaxation else ""
                lines.append(f"  #{c.plan_index} {c.source}{where}: {c.text}")
            if len(self.conflicts) > max_conflicts:
                lines.append(f"  ... {len(self.conflicts) - max_conflicts} more (see --json)")
        lines.append(
            f"stats: NLPs {s.nlp_solves} ({s.ipopt_runs} solver runs, {s.nlp_time:.2f} s"
            + (f", {s.curvature_fallbacks} exact-Hessian fallbacks, {s.curvature_rescues} feasible"
               if s.curvature_fallbacks else "") + f"), logic {s.logic_time:.2f} s, "
            f"factory {s.factory_time:.2f} s, " + (f"reachability {s.reach_time:.2f} s, " if s.reach_time else "")
            + f"plans {s.plans}, conflicts {s.conflicts}, "
            f"N0 {_opt(s.N0)}{'' if s.N0_shortest is not False else ' (not proven shortest)'}, N {_opt(s.N)}, total {s.total_time:.2f} s ({s.cpu_time:.2f} s CPU)"
        )
        if s.reach_samples:
            lines.append(f"reachability: {s.reach_samples} samples"
                         f"{_restored(s.reach_restored)}, "
                         f"{s.reach_queries} queries "
                         f"({s.reach_library_hits} from the library), {s.reach_edge_checks} edge checks "
                         f"({s.reach_edges_removed} edges removed), {s.reach_enhanced_nodes} enhancement "
                         f"nodes, {s.reach_contact_ends} ends in contact; {s.reach_warmstarts} trajectories warm-started with graph paths "
                         f"({s.reach_waypoints} waypoints), {s.reach_straight} without a path")
        if s.kernels_failed:
            lines.append(f"jit: {s.kernels_failed} kernels not compiled, run by casadi's virtual machine "
                         f"(last error: {s.kernel_error.strip().splitlines()[-1][:200] if s.kernel_error.strip() else '?'})")
        if s.kernels_queued:
            lines.append(f"jit: {s.kernels_queued} derivative kernels are being compiled in the background "
                         f"(this solve ran them in casadi's virtual machine; later solves load them)")
        if s.kernels_native:
            lines.append(f"jit: {s.kernels_native} derivative kernels as compiled C ({s.kernels_compiled} "
                         f"compiled now, {s.kernel_compile_time:.1f} s; the others from the cache)")
        if s.db_feasible_hits or s.db_infeasible_hits or s.db_match_time >= 0.1:
            lines.append(f"database: {s.db_feasible_hits} feasible and {s.db_infeasible_hits} "
                         f"infeasible hits (NLPs skipped), {s.db_match_time:.2f} s matching"
                         + (f", {s.db_match_budget_exceeded} matches over budget (misses)"
                            if s.db_match_budget_exceeded else ""))
        v = self.verification
        if v is not None:
            lines.append(f"independent verification (pinocchio + coal): {'OK' if v['ok'] else 'FAILED'}, "
                         f"{v['keyframes']} keyframes, {v['waypoints']} waypoints, {v['midpoints']} midpoints"
                         + ("" if v["min_distance"] is None else f", min distance {v['min_distance']:+.4f}"))
            lines += [f"  {f['message']}" for f in v["failures"][:10]]
        if s.cost is not None:
            how = ("optimised" if s.optimised else "not improved") + f" in {s.optimise_time:.2f} s"
            lines.append(f"objective: {s.cost:.6g} (the feasible solution's: {s.cost_feasible:.6g}; {how})")
        a = self.anytime
        if a is not None:
            proof = (f"optimal, proved over {a['scope']}" if a["proved_optimal"]
                     else f"not proved optimal ({a['stopped']})")
            lines.append(f"anytime: cost {a['cost']:.6g} = plan cost {a['plan_cost']:g} + objective "
                         f"{a['objective']:.6g}, {proof}; {a['plans']} plans in {a['seconds']:.2f} s, "
                         f"costs " + " -> ".join(f"{h['cost']:.6g} at {h['time']:.1f} s" for h in a["history"]))
        for robot, lengths in self.path_length.items():
            parts = [f"{k.replace('_', ' ')} {v:.3f} m" for k, v in lengths.items() if v is not None]
            if parts:
                lines.append(f"path length of {robot}: {', '.join(parts)}")
        if s.max_violation is not None:
            lines.append(f"independent re-check: max violation {s.max_violation:.2e} over "
                         f"{s.factors} factors, {s.variables} variables")
        return "\n".join(lines)


def _num(x: float) -> str:
    """4 significant digits; solver noise below 1e-9 (`1.107e-14`) printed as 0."""
    return "0" if abs(x) < 1e-9 else f"{x:.4g}"


def steps_of(task: Any, plan: Any, graph: Any, values: dict) -> list[Step]:
    """The steps of a solution: each state s_i of `plan` (a logic plan) as text with the values
    of the graph's variables at step i (trajectories as waypoint lists)."""
    import numpy as np

    steps = []
    for i, s in enumerate(plan.states):
        st = Step(i, plan.names[i - 1] if i > 0 else None, task.state_str(s))
        for v in graph.variables:
            if v.step != i or v not in values:
                continue
            x = np.asarray(values[v], float).reshape(-1)
            if v.waypoints:
                st.trajectories[v.key] = x.reshape(v.waypoints, v.point_dim).tolist()
            else:
                st.values[v.key] = x.tolist()
        steps.append(st)
    return steps


def _restored(n: int) -> str:
    return f" ({n} graph{'s' * (n > 1)} restored from the store)" if n else ""


def _opt(x: Any) -> str:
    return "-" if x is None else str(x)


def _finite(d: dict) -> dict:
    """JSON has no inf/nan: write them as strings."""
    return {k: (str(v) if isinstance(v, float) and not math.isfinite(v) else v) for k, v in d.items()}
