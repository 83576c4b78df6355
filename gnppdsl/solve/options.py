"""How to solve: `SolveOptions` (algorithm, switches, limits, the loop's modes), merged from a
problem's `solver { }` settings and the caller's overrides; `overridden`, which sets options (the
solver's, or the feasibility check's own modes) for the duration of one solve; `Progress`, the
callback that receives the loop's messages.
"""
from __future__ import annotations

from contextlib import contextmanager
from dataclasses import dataclass, replace
from typing import Any, Callable, Iterator

from gnppdsl.errors import UserError
from gnppdsl.ir.model import SOLVER_ORDERS as ORDERS
from gnppdsl.ir.model import SOLVER_PLANNERS as PLANNERS
from gnppdsl.ir.model import SolverSettings


Progress = Callable[[str], None]   # may also have `watch(stats)`: given the solve's live Stats once


@dataclass(frozen=True)
class SolveOptions:
    """How to solve: algorithm, switches, limits. `from_settings` merges the problem's
    `solver { }` settings with command-line overrides (None = keep)."""

    algorithm: str = "gnpp"          # "gnpp" | "oneway" | "rlgp" (GNPP + reachability graph)
    switches: str = "trn"            # subset of "trng" (gnpp only)
    time_limit: float = 60.0
    seed: int = 0
    max_horizon: int = 12
    tolerance: float = 1e-6
    database: str | None = None      # SQLite path (implies switch g)
    max_iter: int = 1000
    restarts: int | None = None      # extra random starts after an infeasible verdict (None: nlp default)
    nlp: str = "ipopt"               # casadi plugin: ipopt | sqpmethod
    check_tolerance: float | None = None   # independent re-check threshold (default: tolerance)
    screen_tolerance: float = 1e-4   # gnpp: skip a relaxation level tried after an infeasible full
                                     # graph whose factors all hold this well at that graph's
                                     # convergence point (full_first, staged; 0: off)
    order: str = "full_first"        # gnpp: "full_first" = solve the plan's graph-NLP, run Alg. 1
                                     # only when it is infeasible (Fig. 3, step 3); "relaxed_first"
                                     # = relaxations loose -> tight before the full graph;
                                     # "staged" = the small relaxations first, then the full
                                     # graph, the others only to find a conflict (see `evaluate`)
    jit: bool | None = None          # large derivative kernels as compiled C (gnppdsl.nlp.jit):
                                     # None: compiled in the background for later solves, True:
                                     # compiled now, False: never (`jit.mode`)
    distance_curvature: bool = True  # ipopt's Hessian includes the curvature of signed-distance rows
                                     # (`SolverOptions.distance_curvature`)
    kinematic_curvature: bool | str = "auto"  # ... and of forward-kinematics rows (True, False or
                                     # "auto": `SolverOptions.kinematic_curvature`; docs/design.md,
                                     # "Linearised first, exact where that fails")
    planner: str = "auto"            # logic mode (`gnppdsl.logic.modes`): auto | sequential | fd
    lazy_search: bool = True         # gnpp: Alg. 1's search solves each small subgraph from one
                                     # start, only the conflict gets the restarts (`FeasibilityCheck.confirm`);
                                     # on since session 9 (with held objects' initial guesses): lab5
                                     # 13.2 -> 4.5 s, lab3 4.9 -> 4.0 s, lab4 4.4 -> 5.0 s, planar
                                     # NLPs the same but p7 (29.7 -> 32); before it, lab5 seed 0
                                     # took 4x (a wrong one-start verdict to undo)
    lazy_large: bool = True          # gnpp: ... and each subgraph above LAZY_MAX_FACTORS factors: its
                                     # verdict gets the second opinion of `recheck` when it ends the
                                     # time search, the restarts when it is the conflict (see
                                     # LAZY_MAX_FACTORS for why)
    started: float | None = None     # time.perf_counter() when this solve began, loading and
                                     # grounding included: the time limit (and total_time) counts
                                     # from there. solve_problem on a path or Problem: before
                                     # loading (`gnpp solve` passes what is left); None: when the loop
                                     # starts (solve_compiled on a problem compiled earlier)
    cpu_started: float | None = None  # time.process_time() at that moment (cpu_time counts from it)
    optimise: bool = True            # minimise the plan's `minimize` terms from its feasible solution
                                     # (`solve.optimal`); without terms nothing happens
    certify: bool = True             # gnpp: the lazy search decides a subgraph of a cheap graph
                                     # that failed from one start at that graph's convergence
                                     # point when it certifies it (no NLP), and confirms it with
                                     # the graph's restarts (`FeasibilityCheck.certify`); planar p5
                                     # 5 -> 3 NLPs, p4 10 -> 6
    active_set: bool = True          # a solution the independent verification rejects gets the
                                     # pairs it found near as factors and is solved again
                                     # (`gnppdsl.solve.coverage`); False: it ends the solve as
                                     # verification_failed (every solution is verified either way)
    screen_collisions: bool = True   # graphs with many collision factors are solved first with
                                     # only those near at the start, every factor re-checked with
                                     # numpy after each NLP (`gnppdsl.solve.screening`); a miss
                                     # solves the whole graph as before. False: always whole
    lift_conflicts: bool = True      # gnpp: each conflict is learned with every symmetric instance
                                     # the factory confirms (same NLP up to renaming objects of
                                     # equal geometry and scene data, `gnppdsl.conflicts.lifting`);
                                     # False: the one instance found (before issue 19)
    interleave_conflicts: bool = True   # gnpp: each conflict (and its lifted and batch-learned
                                     # instances) also forbids its copies with steps inserted or
                                     # removed across transitions M relates only by chain
                                     # equalities (a parked base, an object staying put), up to
                                     # max_horizon (`gnppdsl.conflicts.interleave`). On: field4
                                     # 155.8 -> 58.8 s CPU, field5 131.8 -> 39.8; work1-5, stack_8,
                                     # clutter_2/3, p4, p7: the same plans, conflicts and NLPs
    batch_conflicts: int = 64        # gnpp: NLPs per conflict deciding its renamings onto other
                                     # objects of the same type (pairs too, e.g. block and arm)
                                     # that lifting cannot accept; the infeasible ones are learned
                                     # with it (`gnppdsl.conflicts.batch`); 0: off
    batch_min_factors: int = 200     # ... only for conflicts of plans whose graph-NLP has at least
                                     # this many factors: a candidate costs about one keyframe's
                                     # NLP, a loop iteration the whole graph's; on the planar
                                     # problems (17-120 factors) the batch only added NLPs (p6
                                     # 10 -> 23), on the Lab families (900+) it saves iterations
    batch_min_keyframe_factors: int = 20  # ... or at least this many factors per keyframe (the
                                     # robot's keyframes are heavy: a 2-action Workshop plan has 136
                                     # factors, 45 per keyframe, and its per-arm reach conflicts are
                                     # one loop iteration each without the batch: work1 9 -> 3
                                     # plans, 12.1 -> 5.7 s CPU; planar keyframes have 3-15)
    batch_lazy: bool = True          # ... the renamed candidates are queued, and one is solved only
                                     # when a proposed plan contains its partial states (then, if
                                     # infeasible, it is that plan's conflict, no graph-NLP built,
                                     # and the other candidates of its conflict are decided at once);
                                     # False: every candidate solved when its conflict is learned.
                                     # The first candidates are still decided at once for half
                                     # the CPU of the conflict's plan (`batch.EAGER_SHARE`).
                                     # field2 13.9 -> 5.2-7.7 s CPU, work2 19.2 -> 11.4 (seed 0;
                                     # docs/design.md, "Lazy batch")
    stretch_conflicts: bool = False  # gnpp, with interleave_conflicts: transitions of `preorder`-tagged
                                     # templates (tools.push_motion) are chain links too, so a push held
                                     # over several steps is learned for every length
                                     # (`gnppdsl.conflicts.interleave`, "Preorder chains"). Off: work3
                                     # 8 -> 6 plans (34.4 -> 27.6-29.3 s CPU), but on work5 the 217
                                     # stretched instances made clingo's calls 2.5 -> 155 s CPU
    minimise_conflicts: bool = False  # gnpp: drop every fact of a conflict whose factors the
                                     # infeasibility does not need (`gnppdsl.conflicts.minimise`,
                                     # one NLP with restarts per fact)
    anytime: float = 0.0             # seconds after the first solution spent on cheaper logical
                                     # plans under a cost bound (`gnppdsl.solve.anytime`; 0: off),
                                     # within the time limit

    @staticmethod
    def from_settings(settings: SolverSettings | None = None, **overrides: Any) -> "SolveOptions":
        base = SolveOptions()
        if settings is not None:
            kw = {}
            for name in ("algorithm", "switches", "time_limit", "seed", "max_horizon", "tolerance",
                         "database", "max_iter", "nlp", "order", "jit", "distance_curvature", "kinematic_curvature", "planner",
                         "optimise", "anytime", "batch_conflicts", "batch_lazy", "interleave_conflicts",
                         "stretch_conflicts"):
                if hasattr(settings, name) and getattr(settings, name) is not None:
                    kw[name] = getattr(settings, name)
            base = replace(base, **kw)
        opts = replace(base, **{k: v for k, v in overrides.items() if v is not None})
        return opts.validated()

    def validated(self) -> "SolveOptions":
        if self.algorithm not in ("gnpp", "oneway", "rlgp"):
            raise UserError(f"algorithm '{self.algorithm}' is not available (use gnpp, oneway or rlgp)")
        if set(self.switches) - set("trng"):
            raise UserError(f"switches '{self.switches}' are not a subset of 'trng'")
        if self.algorithm == "oneway" and self.database:
            raise UserError("a subgraph database (--db) needs the gnpp algorithm")
        if self.time_limit <= 0:
            raise UserError("the time limit must be positive")
        from gnppdsl.ir.model import setting_problem

        for key in ("tolerance", "time_limit", "seed", "max_horizon", "max_iter", "anytime", "batch_conflicts"):
            value = getattr(self, key, None)        # the ranges of the `solver { }` block
            problem = setting_problem(key, value) if value is not None else None
            if problem is not None:
                raise UserError(f"{key} {value} {problem}")
        if self.kinematic_curvature not in (True, False, "auto"):
            raise UserError(f"kinematic_curvature '{self.kinematic_curvature}' is not available (use true, false or auto)")
        if self.planner not in PLANNERS:
            raise UserError(f"planner '{self.planner}' is not available (use {', '.join(PLANNERS)})")
        if self.planner == "fd" and self.algorithm != "gnpp":
            raise UserError(f"planner fd cannot serve algorithm {self.algorithm}: "
                            + ("One-way enumerates plans in order of length" if self.algorithm == "oneway"
                               else "R-LGP minimises travel costs") + " (use planner sequential or auto)")
        if self.anytime and self.algorithm == "oneway":
            raise UserError("anytime needs the gnpp or rlgp algorithm (One-way learns no conflicts "
                            "to bound its plans)")
        if self.order not in ORDERS:
            raise UserError(f"order '{self.order}' is not available (use {', '.join(ORDERS[:-1])} "
                            f"or {ORDERS[-1]})")
        switches = "".join(c for c in "trng" if c in self.switches)
        if self.database and "g" not in switches:
            switches += "g"
        return replace(self, switches=switches if self.algorithm != "oneway" else "")


@contextmanager
def overridden(obj: object, **attrs: object) -> Iterator[object]:
    """`obj`'s attributes set to `attrs` for the duration of the block, restored afterwards
    (also on an exception, e.g. the time limit): the checker switches its solver's restarts
    and polish, and its own one-start modes, per solve."""
    saved = {name: getattr(obj, name) for name in attrs}
    for name, value in attrs.items():
        setattr(obj, name, value)
    try:
        yield obj
    finally:
        for name, value in saved.items():
            setattr(obj, name, value)
