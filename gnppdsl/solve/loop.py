"""The Graph-NLP Planner loop (paper 000, Fig. 3) and the One-way baseline.

GNPP, repeated until a plan's graph-NLP is feasible:
  1. the logic planner proposes the shortest plan <s_0 ... s_n> not excluded by any conflict;
  2. the factory builds its graph-NLP G;
  3. (switch g) if G contains a subgraph known to be infeasible, that is the conflict (no NLP);
     otherwise `_Run.evaluate` runs Algorithm 1: relaxations loose -> tight (switch r), the
     full graph last; an infeasible relaxed graph is searched component by component with the
     double binary search on time (t) and the convergence heuristic (n), via
     `gnppdsl.nlp.subgraph.find_infeasible_subgraph`, then shrunk to the subgraph induced by
     the violated factors' variables (n). Every feasibility check goes through `_Checker`,
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

import hashlib
import math
import re
import time
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Iterable, Sequence

import networkx as nx
import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.conflicts.database import SubgraphDatabase, names_of
from gnppdsl.conflicts.mapping import conflict_str, to_partial_states
from gnppdsl.errors import UserError
from gnppdsl.ir.expr import Slot
from gnppdsl.ir.model import SOLVER_ORDERS as ORDERS
from gnppdsl.solve.result import (NO_PLAN, SOLVED, SOLVER_FAILURE, TIME_LIMIT, Conflict, Result, Stats,
                                  Step)

TRAJ = "traj"
# order "staged": a relaxation level is solved before the full graph when it has at most this
# fraction of the factors of the plan's mode-switch graph (the full graph without trajectories)
STAGED_FRACTION = 0.5
# a one-start verdict (the plan's graph, a level warm-starting it) is polished after its start
# only when it ends closer to feasible than this; farther points are polished by `confirm`
LOCAL_POLISH_BELOW = 1e-2
# a subgraph starts from an earlier convergence point only when that violates it by less than
# this (and less than the earlier solutions do): see `_Checker.solve`
CLOSE_START = 1e-3
# graphs whose ipopt iteration costs at most this (`FeasibilitySolver.iteration_cost`, in plain
# rows) keep the polish of their one-start verdicts and certify their subgraphs: see `_Checker.certify`
CERTIFY_MAX_COST = 500.0
Progress = Callable[[str], None]


class _TimeUp(Exception):
    """Raised inside a feasibility check when the deadline has passed."""


# ---------------------------------------------------------------------------------------------
# options and compiled problems
# ---------------------------------------------------------------------------------------------
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
    lazy_search: bool = True         # gnpp: Alg. 1's search solves each small subgraph from one
                                     # start, only the conflict gets the restarts (`_Checker.confirm`);
                                     # on since session 9 (with held objects' initial guesses): lab5
                                     # 13.2 -> 4.5 s, lab3 4.9 -> 4.0 s, lab4 4.4 -> 5.0 s, planar
                                     # NLPs the same but p7 (29.7 -> 32); before it, lab5 seed 0
                                     # took 4x (a wrong one-start verdict to undo)
    lazy_large: bool = True          # gnpp: ... and each subgraph above LAZY_MAX_FACTORS factors: its
                                     # verdict gets the second opinion of `recheck` when it ends the
                                     # time search, the restarts when it is the conflict (see
                                     # LAZY_MAX_FACTORS for why)
    certify: bool = True             # gnpp: the lazy search decides a subgraph of a cheap graph
                                     # that failed from one start at that graph's convergence
                                     # point when it certifies it (no NLP), and confirms it with
                                     # the graph's restarts (`_Checker.certify`); planar p5
                                     # 5 -> 3 NLPs, p4 10 -> 6

    @staticmethod
    def from_settings(settings: Any = None, **overrides: Any) -> "SolveOptions":
        base = SolveOptions()
        if settings is not None:
            kw = {}
            for name in ("algorithm", "switches", "time_limit", "seed", "max_horizon", "tolerance",
                         "database", "max_iter", "nlp", "order", "jit", "distance_curvature"):
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
        if self.order not in ORDERS:
            raise UserError(f"order '{self.order}' is not available (use {', '.join(ORDERS[:-1])} "
                            f"or {ORDERS[-1]})")
        switches = "".join(c for c in "trng" if c in self.switches)
        if self.database and "g" not in switches:
            switches += "g"
        return replace(self, switches=switches if self.algorithm != "oneway" else "")


@dataclass
class Compiled:
    """A loaded problem with its SAS+ task, graph-NLP factory, geometry and relaxations."""

    problem: Any                      # gnppdsl.ir.model.Problem
    task: SASTask
    factory: Any                      # gnppdsl.compile.factory.GraphNLPFactory
    geometry: Any = None              # gnppdsl.geometry.context.GeometryContext or None
    relaxations: tuple = ()           # gnppdsl.nlp.subgraph.Relaxation, loose -> tight
    fingerprint: str = ""
    object_key: Any = None            # object name -> geometry identity (see `object_keys`)
    # jit mode -> the BodyCompiler its solves share (see `body_compiler`)
    compilers: dict = field(default_factory=dict, repr=False, compare=False)

    def body_compiler(self, jit_mode: str) -> Any:
        """The template compiler (gnppdsl.nlp.body_compiler.BodyCompiler) shared by every solve
        of this problem in this process. Why shared: building a template's casadi Function and
        its SX Jacobian and Hessian depends only on the factor body and the geometry, not on the
        solve, and it is a large part of a robot solve (lab2, seed 1: 2.9 of 4.8 s CPU); a
        second solve of the same problem (another seed, algorithm or time limit: `gnpp bench`,
        library users) then compiles nothing. One compiler per jit mode (`gnppdsl.nlp.jit`),
        since those with kernels hold compiled code; in the background mode a compiler is built
        again once kernels it queued have been compiled, so that the next solve uses them."""
        hit = self.compilers.get(jit_mode)
        if hit is not None and hit.kernels is not None and hit.kernels.newly_ready():
            hit = None
        if hit is None:
            from gnppdsl.nlp import jit
            from gnppdsl.nlp.body_compiler import BodyCompiler

            old = self.compilers.get(jit_mode)
            kernels = old.kernels if old is not None else jit.kernel_cache(jit_mode)
            hit = self.compilers[jit_mode] = BodyCompiler(self.geometry, kernels=kernels)
        return hit

    @property
    def name(self) -> str:
        return getattr(self.problem, "name", "problem")

    @property
    def domain_name(self) -> str:
        dom = getattr(self.problem, "domain", None)
        return getattr(dom, "name", "domain")


def load_and_compile(paths: Sequence[str] | str) -> Compiled:
    """Load a problem (its domain found next to it, or given first), compile task and factory."""
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    for p in paths:
        if not Path(p).is_file():
            raise UserError(f"{p}: no such file")
    if len(paths) > 2:
        raise UserError("give a problem file, optionally preceded by its domain file")
    from gnppdsl.ir import load_problem

    if len(paths) == 2:
        # either order: the problem is the file that declares `problem NAME for DOMAIN`
        first_is_problem = _PROBLEM_HEADER.search(Path(paths[0]).read_text(errors="replace")) is not None
        prob_path, dom_path = (paths[0], paths[1]) if first_is_problem else (paths[1], paths[0])
        problem = load_problem(prob_path, dom_path)
    else:
        problem = load_problem(paths[0])
    return compile_problem(problem)


_PROBLEM_HEADER = re.compile(r"^\s*problem\s+\w+\s+for\s+\w+", re.MULTILINE)


def compile_problem(problem: Any) -> Compiled:
    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.task import build_task
    from gnppdsl.nlp.subgraph import Relaxation

    from gnppdsl.compile.factory import scene_robot_dims

    task = build_task(problem)
    geometry = None
    robot_dims = None
    if getattr(problem, "scene", None) is not None:
        from gnppdsl.geometry.context import GeometryContext

        geometry = GeometryContext(problem.scene)
        fallback = scene_robot_dims(problem)

        def robot_dims(robot: str):
            # joint dimension and limits from the pinocchio model for URDF robots
            if robot in geometry.models:
                return geometry.robot_dims(robot)
            return fallback(robot)
    factory = GraphNLPFactory(problem, task, robot_dims=robot_dims)
    relaxations = tuple(Relaxation.of(r.name, r.drop) for r in (problem.relaxations or problem.domain.relaxations))
    return Compiled(problem, task, factory, geometry, relaxations, fingerprint(problem), object_keys(problem))


def fingerprint(problem: Any) -> str:
    """Hash of what the semantic labels of factors do not capture: the domain's templates,
    rules, frames and continuous declarations, and the scene's shapes and robot models (sdist /
    fk read them at solve time). Poses are folded into factor bodies as constants, so they are
    not needed here. Stable across processes (no hash-randomised set order, no spans)."""
    dom = problem.domain
    parts = [dom.templates, dom.rules, dom.frames, dom.continuous]
    scene = getattr(problem, "scene", None)
    if scene is not None:
        parts.append(scene.dimension)
        parts.append(scene.ignore_collisions)
    return hashlib.sha256(canonical(parts).encode()).hexdigest()[:24]


def object_keys(problem: Any) -> Callable[[str], str]:
    """Geometry identity of each scene entity (shape; robot model), for factor labels in the
    subgraph database: a factor naming `b1` in `sdist` only matches a factor naming an object
    `b1` of the same shape. Poses are not included (they are constants in the bodies)."""
    scene = getattr(problem, "scene", None)
    keys: dict[str, str] = {}
    if scene is not None:
        for n, o in scene.objects.items():
            keys[n] = hashlib.sha256(canonical(o.shape).encode()).hexdigest()[:12]
        for n, r in scene.robots.items():
            keys[n] = hashlib.sha256(canonical((r.kind, r.model, r.urdf, r.srdf, r.ee, r.locked, r.shape,
                                                r.package_dirs)).encode()).hexdigest()[:12]
    return lambda name: keys.get(name, "-")


def canonical(obj: Any) -> str:
    """A deterministic text form of nested dataclasses / containers (sets sorted, spans and
    other `compare=False` fields left out)."""
    import dataclasses

    if dataclasses.is_dataclass(obj) and not isinstance(obj, type):
        fields = [f for f in dataclasses.fields(obj) if f.compare]
        return f"{type(obj).__name__}(" + ",".join(f"{f.name}={canonical(getattr(obj, f.name))}" for f in fields) + ")"
    if isinstance(obj, dict):
        return "{" + ",".join(sorted(f"{canonical(k)}:{canonical(v)}" for k, v in obj.items())) + "}"
    if isinstance(obj, (set, frozenset)):
        return "{" + ",".join(sorted(canonical(x) for x in obj)) + "}"
    if isinstance(obj, (list, tuple)):
        return "[" + ",".join(canonical(x) for x in obj) + "]"
    return repr(obj)


# ---------------------------------------------------------------------------------------------
# trajectories: warm start by interpolation between the mode switches (Appendix C)
# ---------------------------------------------------------------------------------------------
def plan_graph(factory: Any, states: Sequence[Sequence[int]], name: str = "G") -> Any:
    """The graph-NLP of a state sequence: the factory's factors and variables, with its initial
    guess for each variable at these states (e.g. a held object's pose; see
    `GraphNLPFactory.initial_guess`) as the start of every NLP built from it."""
    from gnppdsl.nlp.graph import GraphNLP

    variables = factory.variables(states)
    guess = {}
    if hasattr(factory, "initial_guess"):
        for v in variables:
            g = factory.initial_guess(v, states)
            if g is not None:
                guess[v] = np.asarray(g, float)
    return GraphNLP.from_factors(factory.factors(states), variables, name=name, initial_guess=guess)


def is_trajectory(v: VarInstance) -> bool:
    """A motion variable (tagged `traj` or with waypoints), solved after the mode switches."""
    return TRAJ in v.tags or bool(v.waypoints)


def keyframe_of(traj: VarInstance, candidates: Iterable[VarInstance],
                neighbours: Iterable[VarInstance] = ()) -> str | None:
    """The variable key whose values at steps i and i+1 a trajectory at step i moves between:
    a non-trajectory variable with the same objects and the trajectory's point dimension,
    preferring one a factor connects to the trajectory (its boundary constraints)."""
    near = {v.key for v in neighbours if not v.waypoints}
    same = sorted({v.key for v in candidates
                   if not v.waypoints and v.args == traj.args and v.dim == traj.point_dim})
    for key in same:
        if key in near:
            return key
    return same[0] if same else None


def interpolate_trajectories(trajs: Iterable[VarInstance], values: dict[VarInstance, Any],
                             neighbours: Callable[[VarInstance], Iterable[VarInstance]] = lambda v: ()
                             ) -> dict[VarInstance, np.ndarray]:
    """Warm start of each trajectory: linear interpolation from its keyframe at step i to the
    one at i+1 (quaternions of SE3 points renormalised)."""
    by_key_step = {(v.key, v.step): v for v in values}
    out: dict[VarInstance, np.ndarray] = {}
    for tr in trajs:
        key = keyframe_of(tr, values.keys(), neighbours(tr))
        if key is None:
            continue
        a = by_key_step.get((key, tr.step))
        b = by_key_step.get((key, tr.step + 1), a)
        if a is None:
            a = b
        if a is None:
            continue
        out[tr] = straight_line(np.asarray(values[a], float).reshape(-1),
                                np.asarray(values[b], float).reshape(-1), tr.waypoints, a.space)
    return out


def straight_line(xa: np.ndarray, xb: np.ndarray, waypoints: int, space: str) -> np.ndarray:
    """`waypoints` points from xa to xb, evenly spaced (quaternions of SE3 points renormalised),
    stacked into one vector."""
    s = np.linspace(0.0, 1.0, waypoints)[:, None]
    pts = (1 - s) * xa[None, :] + s * xb[None, :]
    if space == "SE3" and pts.shape[1] == 7:
        pts[:, 3:7] /= np.maximum(np.linalg.norm(pts[:, 3:7], axis=1, keepdims=True), 1e-12)
    return pts.reshape(-1)


# ---------------------------------------------------------------------------------------------
# one solve
# ---------------------------------------------------------------------------------------------
@contextmanager
def overridden(obj: Any, **attrs: Any):
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


class _Checker:
    """The feasibility check handed to Algorithm 1 for one plan's graph-NLP.

    - switch g: answer from the database of solved subgraphs when it knows (no NLP);
    - graphs with trajectories: solve their mode switches first, warm start the trajectories
      by interpolation, then solve everything jointly;
    - count NLPs, remember feasible values for warm starts, enforce the deadline.
    """

    max_points = 3                       # infeasible convergence points kept for `known_solution`
    closest_point: dict | None = None    # set by `known_solution`: the start `solve` prefers
    local_first = False                  # set by `evaluate` around the first solves up to and
                                         # including the full graph's: see `local_solve`

    def __init__(self, run: "_Run", solver: Any, graph: Any, use_db: bool):
        self.run, self.solver, self.graph, self.use_db = run, solver, graph, use_db
        self.values: StampedValues = StampedValues()
        self.results: dict[frozenset, Any] = {}
        self.points: list[dict] = []      # convergence points of infeasible solves, newest first
        self.lazy = False                 # Alg. 1's search: one start per small NLP (see `confirm`)
        self.lazy_large = False           # ... and per NLP above LAZY_MAX_FACTORS factors
        self.unconfirmed: set = set()     # signatures of infeasible verdicts from one start
        self.derived: dict = {}           # graph -> its mode-switch graph, whose infeasible
                                          # verdict it took as its own (see `overturned`)
        self.parents: list[tuple] = []    # (factor refs, graph, result) of the newest cheap
                                          # infeasible solves: what `certify` decides subgraphs at
        self.parent_of: dict = {}         # signature -> the graph at whose convergence point it was
                                          # decided (certified, or its only violated component)
        self.components: set = set()      # ... of those, the components (`infer_components`)

    def solve(self, g: Any) -> Any:
        run = self.run
        if time.perf_counter() >= run.deadline:
            raise _TimeUp()
        key = g.signature()
        if key in self.results and not self.overturned(key):
            return self.results[key]
        known = self.known_solution(g)
        if known is not None:
            self.results[key] = known
            self.values.update(known.values)      # a solution like any other: warm starts
            return known
        trajs = [v for v in g.variables if is_trajectory(v)]
        if self.lazy and not trajs and run.options.certify:
            certified = self.certify(g)
            if certified is not None:
                return certified
        warm = self.warm_start(g)
        if self.closest_point is not None and not trajs:
            # an earlier convergence point that nearly satisfies g (CLOSE_START), and better
            # than the earlier solutions (with the initial guess) do, is the better start:
            # typically x* of a graph g is a slice of, whose solve stopped with small residuals
            # on g's factors while the contradiction lies elsewhere. Not a point that violates
            # g more: that is the local minimum g's solve should get a second chance to avoid
            # (Lab 1: the keyframes stalled at 2e-2 on a grasp, and their time slice started
            # there failed again; it failed from the warm start too, and only the restart from
            # the initial guess, `FeasibilitySolver._perturbed`, avoided the false conflict)
            warm.update(self.closest_point)
        if trajs and any(v not in self.values for v in trajs):
            modes = g.apply_relaxation({TRAJ}, "modes")
            if modes.n_factors:
                # the keyframes first: every factor at the mode switches (a relaxation of g),
                # also when relaxations already gave them values (they may lack collisions).
                # For the plan's own graph (not a subgraph Alg. 1 checks): one run from the
                # warm start, no random restarts. An infeasible verdict here only
                # starts the conflict search, whose subgraphs are solved with restarts (and a
                # whole multi-step component gets a second opinion), so it never becomes a
                # conflict by itself; random restarts of a 10-step Lab graph cost 100+ s.
                # The final polish of a point far from feasible is skipped there too (`local_solve`).
                local = {"restarts": 0, **self.far_polish(modes)} if key == self.graph.signature() else {}
                # never lazy: g takes this verdict as its own, and g's key is not marked
                # unconfirmed (`confirm` would pass a one-start verdict on)
                with overridden(self.solver.options, **local), overridden(self, lazy=False, lazy_large=False):
                    r0 = self.solve(modes)
                if not r0.feasible:
                    self.results[key] = r0
                    self.derived[key] = modes.signature()
                    if modes.signature() in self.unconfirmed:
                        self.unconfirmed.add(key)      # as final as the relaxation's verdict
                    return r0          # a relaxation is infeasible, so g is (Property 4.4)
                self.consistent_keyframes(modes, r0)
            warm.update(self.warm_start(g))
            todo = [v for v in trajs if v not in self.values]
            if run.reach:
                for v in list(todo):
                    pts = run.reach_warmstart(v, self.values)
                    if pts is not None:
                        warm[v] = pts
                        todo.remove(v)
            warm.update(interpolate_trajectories(
                todo, self.values,
                lambda v: [x for h in self.graph.graph.neighbors(v) for x in self.graph.graph.neighbors(h)]))
            if modes.n_factors and len({v.step for v in trajs}) > 1:
                known = self.motions_between_keyframes(g, trajs, warm)
                if known is not None:
                    self.results[key] = known
                    return known
        r = None
        if self.local_first and self.solver.options.restarts > 0:
            r = self.local_solve(g, warm)
            if not r.feasible:
                # a one-start verdict (`confirm`): Alg. 1 goes on to search g's slices, each
                # solved with restarts, and only if the subgraph it returns carries this verdict
                # does that get the restarts. Why not the restarts now: g is a whole relaxation
                # level, the largest NLP of the search (Lab 5: 130 factors over 8 steps, 3
                # starts 8-9 s) and its slices find the conflict anyway (0.4-1 s each).
                self.unconfirmed.add(key)
        if r is None:
            # ipopt's wall-time limit is fixed when a graph's NLP is assembled: give it what is left
            opts = self.solver.options
            opts.time_limit = max(0.05, run.remaining())
            lazy = self.lazy if g.n_factors <= LAZY_MAX_FACTORS else self.lazy_large
            # a one-start verdict: no restarts, and the polish of a point far from feasible
            # left to `confirm` too (as for the plan's own graph, `local_solve`)
            one_start = {"restarts": 0, **self.far_polish(g)}
            with overridden(opts, **(one_start if lazy else {})):
                r = self.solver.solve(g, warm_start=warm, seed=run.options.seed)
            run.nlp_calls += 1
            if lazy and not r.feasible and opts.restarts > 0:
                self.unconfirmed.add(key)
        if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
            # cut short by the time limit: not a verdict (never a conflict, never stored)
            raise _TimeUp()
        self.results[key] = r
        if r.feasible:
            self.values.update(r.values)
        else:
            # an infeasible graph's convergence point x* may still satisfy a relaxation or a
            # subgraph of it (e.g. everything but the collision factors)
            self.points = [r.values, *self.points][:self.max_points]
            self.infer_components(g, r)
            if r.duals is not None and run.options.certify and self.cheap(g):
                self.parents = [(frozenset(g.factor_refs), g, r), *self.parents][:self.max_points]
        return r

    def cheap(self, g: Any) -> bool:
        """Does an ipopt iteration on g cost at most CERTIFY_MAX_COST plain rows? (Planar plans:
        44-119; Lab mode-switch graphs: 2300-13000, their distance rows weighted.)"""
        return self.solver.iteration_cost(g) <= CERTIFY_MAX_COST

    def far_polish(self, g: Any) -> dict:
        """Solver options of a one-start verdict on g: the final polish of a point far from
        feasible is left to `confirm` (LOCAL_POLISH_BELOW), unless g is cheap. Why keep it
        there: the polish (the pull 1e-4 weaker) leaves multipliers only on the rows of the
        contradiction, which is what lets `certify` decide g's subgraphs without solving them
        (planar p5: ~1e-8 outside the support after it, ~4e-3 before)."""
        return {} if self.run.options.certify and self.cheap(g) else {"final_polish_below": LOCAL_POLISH_BELOW}

    def certify(self, g: Any) -> Any:
        """An infeasible verdict on g without an NLP: g is a proper subgraph of a cheap graph
        whose one-start solve ended infeasible, and that convergence point is a strict local
        minimum of g's own elastic NLP with the same violation (`certify_infeasible`). The
        verdict is one-start evidence like the lazy search's (unconfirmed): if g becomes the
        conflict, `confirm` gives it the restarts, as the graph's restarts when they certify g
        too. Why: the convergence heuristic's support (Sec. VI-C) is usually exactly such a
        subgraph, and solving it repeated what the graph's solve had shown (planar p5, per
        failed plan: the plan's NLP and the support's NLP, now the plan's alone)."""
        from gnppdsl.nlp.certificate import certify_infeasible

        refs = frozenset(g.factor_refs)
        for parent_refs, parent, point in self.parents:
            if not refs < parent_refs:
                continue
            r = certify_infeasible(self.solver, g, point, parent)
            if r is None:
                continue
            key = g.signature()
            self.results[key] = r
            self.parent_of[key] = parent
            self.unconfirmed.add(key)
            self.run.stats.certified_verdicts += 1
            return r
        return None

    def warm_start(self, g: Any) -> dict:
        """The start of g's NLP from this plan's earlier solutions (`self.values`), made
        consistent along g's equality factors (`a == b` between two variables, e.g. an object's
        pose while its parent stays): in each chain of them, the variables set by an earlier
        solve than the newest one take its value. (Values of one solve are left as they are:
        a relaxation without the equalities may hold different values along a chain, and its
        own values are the better start there: Lab 4, 2.2 against 4.2 s for its keyframes.)

        Why: `self.values` holds the latest solution of every variable, so consecutive steps
        can come from different solves, and where an equality crosses that seam the two values
        may be far apart. Lab 5 seed 2: a held block's relative pose at step 2 came from a
        subgraph's solution, at step 3 from a relaxation's, 180 degrees apart about its
        symmetry axis (both grasps valid); every slice across the seam then stopped at that
        local minimum (1.4 on the `same` row) until a random restart, 6 NLPs and 13 s. The
        chain takes the newest value: it comes from the graph solved last, which carried the
        most of the plan's factors that matter now."""
        warm = {v: self.values[v] for v in g.variables if v in self.values}
        chains = nx.Graph()
        for ref in g.factor_refs:
            pair = equality_pair(g.factor(ref))
            if pair is not None and all(v in warm for v in pair):
                chains.add_edge(*pair)
        for chain in nx.connected_components(chains):
            newest = max(chain, key=lambda v: (self.values.stamp[v], -v.step))
            for v in chain:
                if self.values.stamp[v] < self.values.stamp[newest]:
                    warm[v] = self.values[newest]
        return warm

    def overturned(self, key: frozenset) -> bool:
        """Was the cached verdict of this graph its mode-switch graph's infeasible one, which a
        later solve has turned to feasible (the search's second opinion, a restart of
        `confirm`, the union of its components)? Then the verdict is dropped and the graph is
        solved again. Why: Lab 5 seed 3, the plan's keyframes failed one start, Alg. 1 found
        the mode-switch level feasible, and the full graph, still holding the keyframes'
        verdict, was searched slice by slice with its motions (590-factor joint solves of
        40-80 s each, time-out), where the keyframes now known needed only its motions."""
        modes = self.derived.get(key)
        if modes is None or not getattr(self.results.get(modes), "feasible", False):
            return False
        del self.derived[key]
        self.results.pop(key, None)
        self.unconfirmed.discard(key)
        return True

    def consistent_keyframes(self, modes: Any, r0: Any) -> None:
        """Make the keyframes in `self.values` a solution of `modes` (the mode switches of a
        graph about to get its motions) before the motions are fixed between them.

        `self.values` collects the latest solution of every variable, so the keyframes of a
        slice may come from different solves (Lab 5 seed 3: steps 0-6 from a joint solve of
        G[0..6] with its motions, steps 7-8 from the mode-switch graph's solve), which need not
        agree at the seam (0.17 on a `same` row there), and every motion across it then fails
        with its keyframes fixed. When they do not satisfy `modes`, its NLP is solved once from
        them (one start: it stays near the keyframes whose motions were found) and, if that
        fails, `r0`'s solution of `modes` is taken."""
        run = self.run
        point = {v: self.values[v] for v in modes.variables if v in self.values}
        if len(point) == len(modes.variables) and \
                run.violation(modes.factor_instances, point, modes.variables) <= run.options.tolerance:
            return
        r = self.local_solve(modes, point)
        self.values.update(r.values if r.feasible else
                           {v: x for v, x in r0.values.items() if v in modes.variables})

    def local_solve(self, g: Any, warm: dict) -> Any:
        """The warm start and the polish, without random restarts: a feasible result, or an
        infeasible verdict from one start (the caller marks it unconfirmed, see `confirm`).

        Why: a level solved to warm-start the full graph should end near its start. The
        solver's random restarts come before its polish, so a first run that stops at a tiny
        residual (Lab 1, no_col_traj: 2.7e-5 on a placement row) was restarted from a random
        point and came back with a feasible but far-off configuration, from which the motions
        of the full graph did not converge; the polish alone solves it near the start.
        (Also the one-start solve of `consistent_keyframes` and `keyframes_with_motions`.)
        A run cut short by the time limit raises _TimeUp: it is no verdict."""
        run = self.run
        opts = self.solver.options
        # On the plan's graph the final polish of a point far from feasible is left to
        # `confirm` too: it is a second run of the largest NLP of the plan (Lab 5: 77
        # iterations, 5 s on a 10-step mode-switch graph ending at 2.6e-2) that does not turn
        # such a verdict; a stall closer than LOCAL_POLISH_BELOW is still polished (Lab 2's
        # keyframes stall at 1.6e-3 and the polish solves them). The small levels solved
        # before it keep their polish: it is cheap, and their convergence point shapes the
        # conflict search (Lab 4: two more NLPs without it).
        polish = self.far_polish(g) if g.signature() == self.graph.signature() else {}
        opts.time_limit = max(0.05, run.remaining())
        with overridden(opts, restarts=0, **polish):
            r = self.solver.solve(g, warm_start=warm, seed=run.options.seed)
        run.nlp_calls += 1
        if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
            raise _TimeUp()
        return r

    def motions_between_keyframes(self, g: Any, trajs: Sequence[VarInstance], warm: dict) -> Any:
        """The motions of g phase by phase with the keyframes fixed at the mode-switch solution:
        one small NLP per phase i, the time slice g[i..i+1] without other phases' motions, whose
        keyframe variables have lower = upper bound = their value. When every phase is solved,
        the union satisfies every factor of g (checked by `known_solution`, numpy) and is
        returned; else None, and the motions solved so far warm-start the joint solve of g.

        Why (measured on Lab 4 / Lab 5, two Panda arms, 20-waypoint motions): an ipopt
        iteration of the joint graph costs the sum of its phases, ~0.7 s with 6 phases and
        ~2.9 s with 10, and the joint solve iterates until the hardest motion converges (Lab 5:
        97 iterations, 281 s, not converged); with fixed keyframes the phases are independent
        and each takes only its own iterations.

        A phase that fails with its keyframes fixed joins the keyframes (`keyframes_with_motions`:
        the mode switches and that motion in one NLP, the keyframes free), and the other phases
        are solved again between the keyframes that NLP returns; up to MAX_JOINED_MOTIONS
        phases, then the joint solve of g. Never a verdict: a phase that fails here says
        nothing about g (the keyframes may have to move differently), so nothing here is
        stored as a result or becomes a conflict."""
        if any(v not in self.values for v in g.variables if not v.waypoints):
            return None
        fixed_values: dict = {}
        joined: list[int] = []
        while True:
            failed = self.phases_between_keyframes(g, trajs, warm, fixed_values, joined)
            if failed is None:
                break
            if len(joined) >= MAX_JOINED_MOTIONS:
                self.run.say(f"  {g.name}: motion {failed} not found with fixed keyframes; "
                             "solving all motions jointly")
                warm.update(fixed_values)
                return None
            joined.append(failed)
            r = self.keyframes_with_motions(g, joined, {**warm, **fixed_values})
            if not r.feasible:
                self.run.say(f"  {g.name}: keyframes with motions {joined} failed "
                             f"(violation {r.max_violation:.2g}); solving all motions jointly")
                warm.update(fixed_values)
                return None
            self.values.update({v: x for v, x in r.values.items() if not v.waypoints})
            fixed_values.update({v: x for v, x in r.values.items() if v.waypoints})
        warm.update(fixed_values)
        if not fixed_values:
            return None
        point = {**self.values, **fixed_values}
        self.points = [point, *self.points][:self.max_points]
        known = self.known_solution(g)
        if known is not None:
            self.values.update(known.values)
        return known

    def phases_between_keyframes(self, g: Any, trajs: Sequence[VarInstance], warm: dict,
                                 fixed_values: dict, joined: Sequence[int]) -> int | None:
        """Solve each phase of g not in `joined` between its fixed keyframes (`self.values`),
        adding the motions to `fixed_values`; the first phase that fails, or None."""
        for i in sorted({v.step for v in trajs}):
            if i in joined:
                continue
            s = g.time_slice(i, i + 1)
            s = s.subgraph(variables=[v for v in s.variables if not (v.waypoints and v.step != i)],
                           suffix=f"{{motion {i}}}")
            frozen = {v: _fixed(v, self.values[v]) for v in s.variables if not v.waypoints}
            if not frozen or not any(v.waypoints for v in s.variables):
                continue
            r = None
            idle = self.idle_motions(s, i)
            if idle:
                r = self.solve_motion(s, frozen, idle, warm, fixed_values)
            if r is None or not r.feasible:
                r = self.solve_motion(s, frozen, {}, warm, fixed_values)
            if not r.feasible:
                self.run.say(f"  {g.name}: motion {i} not found with fixed keyframes "
                             f"(violation {r.max_violation:.2g})")
                return i
            fixed_values.update({v: x for v, x in r.values.items() if v.waypoints})
        return None

    def keyframes_with_motions(self, g: Any, phases: Sequence[int], warm: dict) -> Any:
        """One NLP: g's mode switches with the motions of `phases`, every keyframe free (the
        subgraph of g induced by its keyframes and those trajectories), from one start.

        Why: a motion that fails between fixed keyframes usually needs its keyframes moved a
        little (Lab 5 seed 3: a detour 1.3e-2 over the velocity budget), and moving them moves
        the keyframes they are tied to (a held block's pose, the other arm's grasp) all along
        the plan, so the keyframes are solved together with that motion only. Its iteration
        costs the mode switches plus one motion, against every motion in the joint solve of
        g (Lab 5: 40-80 s for 8-10 phases)."""
        m = g.subgraph(variables=[v for v in g.variables if not v.waypoints or v.step in phases],
                       suffix="{keyframes+motions " + ",".join(map(str, phases)) + "}")
        start = {v: warm[v] for v in m.variables if v in warm}
        start.update({v: self.values[v] for v in m.variables if v in self.values and not v.waypoints})
        return self.local_solve(m, start)

    def idle_motions(self, s: Any, i: int) -> dict:
        """The trajectories of phase i whose keyframes at i and i+1 are equal up to IDLE_MOTION
        (an arm that does not move in this phase), each with the straight line between them as
        its fixed value.

        Why: with two arms, one usually waits while the other moves, and the waiting arm's
        20 waypoints carried as many collision rows as the moving one's (Lab 4: half of each
        phase's distance queries and Hessian blocks for a path whose straight-line start is
        already its solution)."""
        idle = {}
        by = {(v.key, v.step): v for v in self.values if not v.waypoints}
        for v in s.variables:
            if not v.waypoints or v.step != i:
                continue
            key = keyframe_of(v, s.variables, [x for h in s.graph.neighbors(v) for x in s.graph.neighbors(h)])
            a, b = by.get((key, i)), by.get((key, i + 1))
            if a is None or b is None:
                continue
            xa = np.asarray(self.values[a], float).reshape(-1)
            xb = np.asarray(self.values[b], float).reshape(-1)
            if xa.size == v.point_dim and np.max(np.abs(xa - xb), initial=0.0) <= IDLE_MOTION:
                # the straight line: its end points are exactly the keyframes, which the
                # solver moved by ~1e-8 although nothing asked the arm to move
                idle[v] = straight_line(xa, xb, v.waypoints, a.space)
        return idle

    def solve_motion(self, s: Any, frozen: dict, idle: dict, warm: dict, fixed_values: dict) -> Any:
        """One phase's NLP with its keyframes (`frozen`) and the `idle` trajectories fixed; the
        factors whose variables are then all fixed are checked once with numpy instead of
        being carried through every ipopt iteration, and so is the whole phase at its start
        (when the straight lines already clear everything, no NLP is built: measured on Lab 2,
        three of four phases, 0.2-0.8 s of assembly each for an ipopt run of 0 iterations).
        None when a fixed factor is violated (the caller solves the phase again with the idle
        trajectories free)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        run = self.run
        fixed = {**frozen, **{v: _fixed(v, x) for v, x in idle.items()}}
        start = {**warm, **fixed_values, **idle, **{v: self.values[v] for v in frozen}}
        m = s
        if idle:
            const = [ref for ref in s.factor_refs if all(u in fixed for u in s.graph.neighbors(ref))]
            if not run.violation([s.factor(ref) for ref in const], start) <= run.options.tolerance:
                return None
            m = s.subgraph(factors=[ref for ref in s.factor_refs if ref not in set(const)],
                           suffix="{moving}")
        if all(v in start for v in m.variables):
            point = {v: start[v] for v in m.variables}
            worst = run.violation(m.factor_instances, point, m.variables)
            if worst <= run.options.tolerance:
                run.stats.reused_solutions += 1
                return FeasibilityResult(True, {**point, **idle}, {r: 0.0 for r in m.factor_refs}, worst,
                                         0.0, 0.0, 0, "its start satisfies it", 0)
        # a solver of its own: assembled NLPs are cached by vertex set, which ignores bounds
        solver = run.new_solver()
        solver.options.restarts, solver.options.polish = 0, True
        solver.options.time_limit = max(0.05, run.remaining())
        r = solver.solve(GraphNLPView.with_variables(m, {v: f for v, f in fixed.items() if v in m}),
                         warm_start=start, seed=run.options.seed)
        run.nlp_calls += 1
        if time.perf_counter() >= run.deadline:
            raise _TimeUp()
        if r.feasible:
            r.values.update({v: x for v, x in idle.items() if v not in r.values})
        return r

    def confirm(self, g: Any) -> bool:
        """Is the infeasible verdict on g final? A verdict from one start (Alg. 1's search runs
        `lazy`) gets the random restarts it skipped (the same NLP, not a new one), so a
        conflict is learnt from exactly the evidence it was before: every start infeasible.

        Why lazy: the restarts of every intermediate infeasible verdict of the time search and
        the convergence heuristic were two thirds of Lab 3's NLP time (3 starts of 60-110
        iterations each, ~1-4 s per subgraph), while only the subgraph that becomes the
        conflict needs them. False means a restart found g feasible: the one-start verdicts
        that led to it are suspect (the caller forgets them and searches again with restarts)."""
        key = g.signature()
        if key not in self.unconfirmed:
            return True
        self.unconfirmed.discard(key)
        run = self.run
        parent = self.parent_of.get(key)
        if parent is not None:
            verdict = self.confirm_by_parent(g, parent)
            if verdict is not None:
                return verdict
        if getattr(self.results.get(key), "starts", 1) == 0:
            # no ipopt run behind the verdict (certified, or inferred at a graph's x*): these
            # restarts are g's first solve, an NLP
            run.nlp_calls += 1
        opts = self.solver.options
        opts.time_limit = max(0.05, run.remaining())
        r = self.solver.solve(g, warm_start={v: self.values[v] for v in g.variables if v in self.values},
                              seed=run.options.seed, first_attempt=1)
        if r is not None and not r.feasible and (time.perf_counter() >= run.deadline
                                                 or "walltime" in str(r.status).lower()):
            raise _TimeUp()
        if r is None or not r.feasible:
            self.remember_infeasible(g)
            return True
        self.results[key] = r
        self.values.update(r.values)
        return False

    def confirm_by_parent(self, g: Any, parent: Any) -> bool | None:
        """`confirm` for a g decided at the convergence point of a cheap `parent` (`certify`,
        `infer_components`): the parent's random restarts, each polished, are g's restarts
        when each decides g at its own convergence point: a certified subgraph is certified
        there again (each point a strict local minimum of g's NLP that violates it), a
        component is violated there (components share no variables: the parent's NLP is the
        sum of theirs, its local minima theirs). Evidence from as many starts as g's own solve.
        True: confirmed (the parent failed from every start too); False: the parent, so g, is
        feasible (now in the memo); None: a restart did not decide g, the parent is not cheap
        or had its restarts already (only its best point is known): g needs its own. Why the
        parent's and not g's: the parent's NLP is cheap and already counted, so a failed plan
        costs one NLP, as in One-way, with a conflict smaller than the plan."""
        pkey = parent.signature()
        if pkey not in self.unconfirmed or not self.cheap(parent):
            return None
        from gnppdsl.nlp.certificate import certify_infeasible

        component = g.signature() in self.components
        run, opts, tol = self.run, self.solver.options, self.run.options.tolerance
        warm = {v: self.values[v] for v in parent.variables if v in self.values}
        for k in range(1, max(0, opts.restarts) + 1):
            opts.time_limit = max(0.05, run.remaining())
            with overridden(opts, restarts=k, final_polish_below=math.inf):
                r = self.solver.solve(parent, warm_start=warm, seed=run.options.seed, first_attempt=k)
            if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
                raise _TimeUp()
            if r.feasible:
                self.unconfirmed.discard(pkey)
                self.results[pkey] = r
                self.values.update(r.values)
                return False
            if component:
                if not max(r.violations.get(ref, np.inf) for ref in g.factor_refs) > tol:
                    return None
            elif certify_infeasible(self.solver, g, r, parent) is None:
                return None
        self.unconfirmed.discard(pkey)    # the parent failed from every start as well
        self.remember_infeasible(g)
        return True

    def remember_infeasible(self, g: Any) -> None:
        """A confirmed infeasible g into the database (skipped while unconfirmed)."""
        run = self.run
        if self.use_db and run.db is not None:
            try:
                run.db.add(g, False, names_of(run.task, to_partial_states(g)))
            except ValueError:
                run.db.add(g, False, None)

    def forget_unconfirmed(self) -> None:
        """Drop every one-start infeasible verdict (after one of them proved wrong), and the
        certificates drawn from them."""
        for key in self.unconfirmed:
            self.results.pop(key, None)
            self.parent_of.pop(key, None)
        self.parents = [p for p in self.parents if p[1].signature() not in self.unconfirmed]
        self.unconfirmed.clear()

    def recheck(self, g: Any) -> Any:
        """Second opinion on an infeasible g whose large strict time slices are feasible (see
        `find_infeasible_subgraph`): forget its verdict and solve it again, now warm-started
        from every value known in this plan (the slices' solutions among them), from that one
        start: g's verdict had its restarts, or gets them from `confirm` if it becomes the
        conflict (`lazy_large`), and a failed second opinion of a 5-step Lab slice costs 2-5 s
        this way, 10-40 s with restarts. A feasible answer is a real solution (re-evaluated by
        the solver's verdict); an infeasible one stands as before."""
        key = g.signature()
        old = self.results.pop(key, None)
        self.run.say(f"  {g.name}: infeasible, but its slices without the first or the last step are "
                     f"feasible; solving it again from their solutions")
        with overridden(self.solver.options, restarts=0):
            r = self.solve(g)
        if not r.feasible and old is not None:
            self.results[key] = old
            return old
        return r

    def infer_components(self, g: Any, r: Any) -> None:
        """Verdicts on the components of an infeasible g without an NLP (Property 4.5).

        Components share no variables, so the convergence point x* restricted to a component
        whose factors (and bounds) all hold at x* is a solution of it: feasible. If exactly
        one component is violated at x* and every other one is feasible that way, the
        infeasibility of g lies in it: infeasible, with x* as its convergence point (what
        Alg. 1 would solve it for next)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        comps = g.connected_components()
        if len(comps) < 2 or not r.values:
            return
        tol = self.run.options.tolerance
        bad, good = [], 0
        for c in comps:
            per = {ref: r.violations.get(ref, np.inf) for ref in c.factor_refs}
            vals = {v: r.values[v] for v in c.variables if v in r.values}
            worst = max(per.values(), default=0.0)
            if worst <= tol and len(vals) == len(c.variables) and bound_violation(c.variables, vals) <= tol:
                good += 1
                self.results.setdefault(c.signature(), FeasibilityResult(
                    True, vals, per, worst, 0.0, 0.0, 0, f"holds at the convergence point of {g.name}", 0))
                self.values.update(vals)
            else:
                bad.append((c, per, vals, worst))
        if len(bad) == 1 and good == len(comps) - 1:
            c, per, vals, worst = bad[0]
            if g.signature() in self.unconfirmed:
                self.unconfirmed.add(c.signature())
                self.parent_of.setdefault(c.signature(), g)
                self.components.add(c.signature())
            if c.signature() not in self.results:
                activity = getattr(r, "activity", {})
                self.results[c.signature()] = FeasibilityResult(
                    False, vals, per, worst, r.slack, 0.0, 0, f"the only violated component of {g.name}", 0,
                    {ref: activity[ref] for ref in c.factor_refs if ref in activity})
                self.run.stats.inferred_verdicts += 1

    def known_solution(self, g: Any) -> Any:
        """A feasible verdict without an NLP: when the values of earlier feasible solves of this
        plan's subgraphs, or the convergence point of an earlier infeasible solve, or the start
        an NLP would be given (those values, the factory's initial guess for the others) cover
        every variable of g and satisfy all its factors and bounds (evaluated independently
        with numpy), g is feasible (Definition 4.3) and those values are a solution. Typical
        cases: a time slice inside a feasible relaxation; a relaxation without the factors
        violated at the full graph's convergence point; a slice whose factors the initial
        guess already satisfies (a block resting on its spot, a gripper at home), which ipopt
        would confirm in 0 iterations but which would count as an NLP (planar p7: 42 -> 30
        NLPs, p5: 9 -> 6)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        # (values, why they would do, whether they are a convergence point rather than the
        # start the NLP would be given)
        sources = [(self.values, "earlier solutions satisfy it", False),
                   *((p, "an earlier convergence point satisfies it", True) for p in self.points),
                   (self.start_point(g), "its start (earlier solutions and the initial guess) satisfies it",
                    False)]
        self.closest_point = None
        own = np.inf                      # violation at the start the NLP would be given
        best = (np.inf, None)             # the convergence point closest to satisfying g
        for point, why, converged in sources:
            if not point or any(v not in point for v in g.variables):
                continue
            values = {v: point[v] for v in g.variables}
            worst = self.run.violation(g.factor_instances, values, g.variables)
            if not worst <= self.run.options.tolerance:
                if not converged:
                    own = min(own, worst)
                elif worst < best[0]:
                    best = (worst, values)
                continue
            self.run.stats.reused_solutions += 1
            per = {r: 0.0 for r in g.factor_refs}
            return FeasibilityResult(True, values, per, worst, 0.0, 0.0, 0, why, 0)
        if best[0] < min(own, CLOSE_START):
            self.closest_point = best[1]
        return None

    def start_point(self, g: Any) -> dict | None:
        """The values of this plan's earlier feasible solves, completed by the initial guess of
        the plan's graph; None when it adds nothing to those values for g (already tried), or
        when it would complete a trajectory: a certified graph's values join `self.values`,
        where a trajectory means "solved", so `solve` would then skip the keyframes-first
        machinery for every later graph holding it (lab5 seed 8: three slices of 370-640
        factors solved jointly, 135 s, where their motions had been solved phase by phase)."""
        guess = self.graph.initial_guess
        missing = [v for v in g.variables if v not in self.values]
        if not missing or any(v not in guess or is_trajectory(v) for v in missing):
            return None
        return {**{v: guess[v] for v in missing}, **{v: self.values[v] for v in g.variables if v in self.values}}

    def __call__(self, g: Any) -> Any:
        run = self.run
        if self.use_db and run.db is not None:
            verdict = run.db.lookup(g)
            if verdict is not None:
                if verdict:
                    run.stats.db_feasible_hits += 1
                else:
                    run.stats.db_infeasible_hits += 1
                return verdict
        r = self.solve(g)
        if self.use_db and run.db is not None and (r.feasible or g.signature() not in self.unconfirmed):
            conflict = None
            if not r.feasible:
                try:
                    conflict = names_of(run.task, to_partial_states(g))
                except ValueError:
                    conflict = None
            run.db.add(g, r.feasible, conflict)
        return r


class GraphNLPView:
    """Helpers that build graph-NLPs the nlp layer reads, without changing its classes."""

    @staticmethod
    def with_variables(g: Any, replacements: dict) -> Any:
        """A copy of g whose variable vertices are the given replacement objects (equal to the
        originals, e.g. with other bounds, which do not take part in equality): the solver
        reads bounds from the graph's vertices and maps factor slots to them by equality."""
        import networkx as nx

        h = nx.relabel_nodes(g.graph, {v: r for v, r in replacements.items() if v in g.graph}, copy=True)
        return type(g)(g.factors, h, g.name, g.initial_guess)


def deadline_solver(base: type) -> type:
    """A FeasibilitySolver subclass that stops between ipopt runs at the solve's deadline.

    Why: ipopt's `max_wall_time` applies to one run and is fixed when an NLP is assembled,
    while one feasibility solve may run ipopt several times (random restarts, the polish
    re-solve). Checking the deadline before every run bounds the overshoot to one run started
    before the deadline (whose own limit is the time that was left at assembly)."""
    cached = _DEADLINE_SOLVERS.get(base)
    if cached is not None:
        return cached

    class DeadlineSolver(base):      # type: ignore[misc, valid-type]
        deadline: float = float("inf")

        def _run(self, *args: Any, **kwargs: Any) -> Any:
            if time.perf_counter() >= self.deadline:
                raise _TimeUp()
            return super()._run(*args, **kwargs)

    DeadlineSolver.__name__ = DeadlineSolver.__qualname__ = f"Deadline{base.__name__}"
    _DEADLINE_SOLVERS[base] = DeadlineSolver
    return DeadlineSolver


_DEADLINE_SOLVERS: dict[type, type] = {}


class _Run:
    def __init__(self, compiled: Compiled, options: SolveOptions, progress: Progress | None):
        from gnppdsl.logic.planner import IncrementalPlanner

        self.compiled, self.options, self.progress = compiled, options, progress
        self.task = compiled.task
        self.start = time.perf_counter()
        self.cpu_start = time.process_time()
        self.children_cpu_start = _children_cpu()
        self.deadline = self.start + options.time_limit
        self.stats = Stats()
        self.conflicts: list[Conflict] = []
        self.reach: dict[str, tuple[Any, Any]] = {}      # robot -> (ReachabilityGraph, block)
        if options.algorithm == "rlgp":
            self.task = self.with_reachability_costs(self.task)
        t0 = time.perf_counter()
        self.planner = IncrementalPlanner(self.task, max_horizon=options.max_horizon)
        self.stats.logic_time += time.perf_counter() - t0
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
        self.solvers: list[Any] = []      # every FeasibilitySolver of this run (ipopt runs, time)
        self.nlp_calls = 0                # NLPs solved through _Checker.solve
        self.heuristic_solves = 0         # NLPs Alg. 1 solved itself for a convergence point
        self.db: SubgraphDatabase | None = None
        if "g" in options.switches:
            self.db = SubgraphDatabase(options.database, scope=compiled.domain_name,
                                       fingerprint=compiled.fingerprint, object_key=compiled.object_key)

    # -- R-LGP (paper 002) ---------------------------------------------------------------------
    def with_reachability_costs(self, task: SASTask) -> SASTask:
        """Build the reachability graph of every `reachability` block (Sec. IV) and return the
        task with its end-effector travel costs as `pair_costs` (Alg. 1's heuristicCost): the
        planner then proposes, among the shortest plans, the one with the least travel."""
        from dataclasses import replace as dc_replace

        from gnppdsl.reach.integration import build_from_problem, pair_costs_from_problem

        problem = self.compiled.problem
        blocks = tuple(getattr(problem, "reachability", ()) or ())
        if not blocks:
            raise UserError(f"algorithm rlgp: problem '{self.compiled.name}' has no `reachability` block")
        t0 = time.perf_counter()
        costs: dict = dict(task.pair_costs)
        for block in blocks:
            graph = build_from_problem(problem, block.name)
            self.reach[block.robot] = (graph, block)
            for pair, c in pair_costs_from_problem(problem, task, graph, block.name).items():
                costs[pair] = costs.get(pair, 0) + c
            self.say(f"reachability graph '{block.name}' for {block.robot}: {graph.num_samples} samples")
        self.stats.reach_time += time.perf_counter() - t0
        return dc_replace(task, pair_costs=costs)

    def reach_warmstart(self, traj: VarInstance, values: dict) -> np.ndarray | None:
        """Alg. 1's getWaypoints: the graph's collision-checked path between the trajectory's
        keyframes, for trajectories a block names in `warmstart` (None: interpolate instead)."""
        if not traj.args or traj.args[0] not in self.reach or self.remaining() <= 0:
            return None
        graph, block = self.reach[traj.args[0]]
        if not any(w.traj == traj.kind for w in getattr(block, "warmstarts", ())):
            return None
        key = keyframe_of(traj, values.keys())
        by = {(v.key, v.step): v for v in values}
        a, b = by.get((key, traj.step)), by.get((key, traj.step + 1))
        if a is None or b is None:
            return None
        from gnppdsl.reach.integration import warmstart_waypoints

        t0 = time.perf_counter()
        try:
            pts = warmstart_waypoints(graph, values[a], values[b], traj.waypoints)
        except (ValueError, IndexError):
            return None
        finally:
            self.stats.reach_time += time.perf_counter() - t0
        pts = np.asarray(pts, float)
        return pts.reshape(-1) if pts.size == traj.dim else None

    # -- helpers -------------------------------------------------------------------------------
    def say(self, msg: str) -> None:
        if self.progress is not None:
            self.progress(msg)

    def remaining(self) -> float:
        return self.deadline - time.perf_counter()

    def new_solver(self) -> Any:
        """One FeasibilitySolver per plan graph (its assembled-NLP cache is keyed by vertex
        sets whose factor references are positions in *this* graph's factor list); the casadi
        Function cache (BodyCompiler) is shared by the whole run."""
        from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

        kw = {} if self.options.restarts is None else {"restarts": self.options.restarts}
        opts = SolverOptions(tolerance=self.options.tolerance, max_iter=self.options.max_iter,
                             plugin=self.options.nlp, time_limit=max(0.05, self.remaining()),
                             distance_curvature=self.options.distance_curvature, **kw)
        solver = deadline_solver(FeasibilitySolver)(self.compiled.geometry, opts, compiler=self.compiler)
        solver.deadline = self.deadline
        self.solvers.append(solver)
        return solver

    def build_graph(self, states: Sequence[Sequence[int]]) -> Any:
        t0 = time.perf_counter()
        graph = plan_graph(self.compiled.factory, states)
        self.stats.factory_time += time.perf_counter() - t0
        return graph

    def next_plan(self, enumerate_: bool) -> Any:
        t0 = time.perf_counter()
        if enumerate_:
            res = self.planner.next_plan(time_limit=max(0.0, self.remaining()))
        else:
            res = self.planner.shortest_plan(time_limit=max(0.0, self.remaining()),
                                             minimize_cost=self.options.algorithm == "rlgp")
        self.stats.logic_time += time.perf_counter() - t0
        return res

    sweeping_restarts = 8                 # random starts behind a conflict without facts

    def confirm_sweeping(self, sub_factors: Sequence[FactorInstance]) -> bool:
        """A conflict whose partial states hold no fact (its factors come from `always` rules
        only) matches every plan long enough: accepting it ends the search with "no plan".
        Such a sweeping claim gets a stricter check first: the subgraph is solved again from
        `sweeping_restarts` random starts; any solution refutes it (a false infeasible verdict,
        e.g. a local minimum). True if the conflict is not sweeping or stays infeasible."""
        from gnppdsl.nlp.graph import GraphNLP

        if any(p.facts for p in to_partial_states(sub_factors)):
            return True
        solver = self.new_solver()
        solver.options.restarts = max(solver.options.restarts, self.sweeping_restarts)
        solver.options.noise = max(solver.options.noise, 1.0)
        r = solver.solve(GraphNLP(list(sub_factors)), seed=self.options.seed + 1)
        self.nlp_calls += 1
        if not r.feasible and time.perf_counter() >= self.deadline:
            raise _TimeUp()                  # cut short: not a confirmation
        return not r.feasible

    def add_conflict(self, plan: Any, sub_factors: Sequence[FactorInstance], source: str,
                     relaxation: str) -> None:
        seq = to_partial_states(sub_factors)
        first = min(f.step for f in sub_factors)
        # the conflict must hold in the plan that produced it, else it would not exclude it
        holds = all(p.holds_in(plan.states[first + l]) for l, p in enumerate(seq))
        if not holds:
            raise AssertionError(f"conflict {seq} does not hold in the plan it came from at step {first}")
        t0 = time.perf_counter()
        new = self.planner.add_conflict(seq)
        if not new:
            # the planner already forbids it, yet proposed this plan: never loop forever
            self.planner.block_plan(plan)
        self.stats.logic_time += time.perf_counter() - t0
        c = Conflict(seq, conflict_str(self.task, seq), tuple(f.label for f in sub_factors), source,
                     relaxation, self.stats.plans, first, named=names_of(self.task, seq),
                     subgraph=tuple(sub_factors))
        self.conflicts.append(c)
        self.stats.conflicts += 1
        self.say(f"  conflict ({source}{', ' + relaxation if relaxation else ''}): {c.text}")

    def result(self, status: str, message: str, **kw: Any) -> Result:
        self.stats.total_time = time.perf_counter() - self.start
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
        if self.db is not None:
            self.db.close()
        return Result(problem=self.compiled.name, domain=self.compiled.domain_name,
                      algorithm=self.options.algorithm, switches=self.options.switches,
                      seed=self.options.seed, status=status, message=message,
                      conflicts=self.conflicts, stats=self.stats, time_limit=self.options.time_limit, **kw)

    def stop_result(self, res: Any) -> Result:
        from gnppdsl.logic.planner import Status

        if res.status is Status.TIMEOUT or self.remaining() <= 0:
            return self.result(TIME_LIMIT, f"time limit of {self.options.time_limit:g} s reached "
                                           f"after {self.stats.plans} plans")
        return self.result(NO_PLAN, res.message or "no plan")

    # -- the loops -----------------------------------------------------------------------------
    def solve(self) -> Result:
        try:
            if self.options.algorithm == "oneway":
                return self.oneway()
            return self.gnpp()
        except _TimeUp:
            return self.result(TIME_LIMIT, f"time limit of {self.options.time_limit:g} s reached "
                                           f"after {self.stats.plans} plans")

    def gnpp(self) -> Result:
        while True:
            res = self.next_plan(enumerate_=False)
            if not res.found:
                return self.stop_result(res)
            plan = res.plan
            self.stats.plans += 1
            if self.stats.N0 is None:
                self.stats.N0 = len(plan)
            self.say(f"plan #{self.stats.plans} (length {len(plan)}): {', '.join(plan.names) or '(empty)'}")
            graph = self.build_graph(plan.states)
            if self.db is not None:
                known = self.db.infeasible_inside(graph)
                if known:
                    self.stats.db_infeasible_hits += 1
                    self.add_conflict(plan, known, "database", "")
                    continue
            outcome = self.evaluate(graph, use_db=self.db is not None)
            if outcome[0] == "conflict":
                if not self.confirm_sweeping(outcome[1]):
                    self.say("  plan blocked: a conflict without facts (it would forbid every plan) "
                             "was found feasible from more starts")
                    self.planner.block_plan(plan)
                    self.conflicts.append(Conflict(
                        tuple(PartialState.of(enumerate(s)) for s in plan.states),
                        "blocked plan (a conflict without facts failed its confirmation): "
                        + "; ".join(plan.names), (), "plan", "", self.stats.plans, 0))
                    continue
                self.add_conflict(plan, outcome[1], "nlp", outcome[2])
                continue
            if outcome[0] == "solution":
                return self.solution(plan, graph, outcome[1])
            # the solver contradicted itself (infeasible as a whole, every component feasible):
            # no sound conflict, so only this plan is given up
            self.say(f"  plan blocked: {outcome[1]}")
            self.planner.block_plan(plan)
            self.conflicts.append(Conflict(tuple(PartialState.of(enumerate(s)) for s in plan.states),
                                           f"blocked plan ({outcome[1]}): " + "; ".join(plan.names), (),
                                           "plan", "", self.stats.plans, 0))

    def evaluate(self, graph: Any, use_db: bool) -> tuple:
        """Algorithm 1 on one plan's graph-NLP.

        Order "full_first" (default, Fig. 3 step 3): solve the full graph-NLP first; only when it
        is infeasible search for a conflict, relaxations loose -> tight. "relaxed_first": the
        relaxations before the full graph, as Alg. 1 is written. "staged": the small relaxation
        levels, then the full graph, the large levels only to locate a conflict (`staged`).
        Relaxation levels whose factor set equals an earlier level's or the full graph's are
        skipped (same verdict); after an infeasible full graph, levels that nearly hold at its
        convergence point are skipped too (`nearly_holds`: no verdict, so no conflict).
        Each relaxed graph G_r is first checked as a whole (one NLP; by Property 4.5 it is
        feasible iff all its components are), and only an infeasible G_r is searched component
        by component with the double binary search on time and the convergence heuristic
        (`find_infeasible_subgraph`). Same verdicts as Alg. 1.
        Returns ("solution", values) | ("conflict", factors, relaxation) | ("inconsistent", why).
        """
        from gnppdsl.nlp.feasibility import FeasibilityResult
        from gnppdsl.nlp.subgraph import find_infeasible_subgraph

        sw = self.options.switches
        solver = self.new_solver()
        checker = _Checker(self, solver, graph, use_db=use_db)
        rules = [r for r in self.compiled.relaxations if r.dropped] if "r" in sw else []
        levels: list = []
        full_key = frozenset(graph.factor_refs)
        seen: set = set()
        for rule in rules:
            g_r = graph.apply_relaxation(rule.dropped, rule.name)
            key = frozenset(g_r.factor_refs)
            if g_r.n_factors == 0 or key in seen or key == full_key:
                continue
            seen.add(key)
            levels.append((rule, g_r))
        levels.append((None, graph))
        if self.options.order == "full_first" and len(levels) > 1:
            levels.insert(0, (None, graph))
        elif self.options.order == "staged" and len(levels) > 1:
            levels = self.staged(graph, levels, solver.iteration_cost)
        x_star: dict | None = None            # convergence point of the infeasible full graph
        full_seen = False
        for index, (rule, g_r) in enumerate(levels):
            if g_r.n_factors == 0:
                continue
            if rule is not None and x_star is not None and self.nearly_holds(g_r, x_star):
                self.stats.screened_levels += 1
                continue
            # levels before the full graph warm-start it: their first solve stays near its
            # start (`_Checker.local_solve`). The full graph's first solve too: an infeasible
            # verdict there only starts Alg. 1, so it is kept unconfirmed (one start, no random
            # restarts) and gets the restarts only if the search returns a subgraph carrying it
            # (`confirm`); a feasible graph the one start missed has feasible components, which
            # the search then joins (planar p7: 102 -> 88 ipopt runs, p5: 18 -> 14)
            # (the full graph again at the end: its cached verdict, or, when that was its
            # keyframes' and they proved feasible since (`overturned`), a new one-start solve)
            with overridden(checker, local_first=not full_seen or rule is None):
                verdict = checker(g_r)
            full_seen = full_seen or rule is None
            feasible = verdict.feasible if hasattr(verdict, "feasible") else bool(verdict)
            if feasible:
                if rule is not None:
                    continue
                if hasattr(verdict, "values") and all(v in verdict.values for v in graph.variables):
                    return ("solution", verdict.values)
                r = checker.solve(graph)          # the database said feasible: get the values
                if r.feasible:
                    return ("solution", r.values)
                if use_db:                        # the solver disagrees with the database
                    return self.evaluate(graph, use_db=False)
                return ("inconsistent", "the full graph-NLP failed after a feasible verdict")
            if rule is None and index < len(levels) - 1:
                x_star = getattr(verdict, "values", None) or None
                continue                          # full graph infeasible: look for a conflict
            # Alg. 1 on the components of G_r; it returns the first infeasible one, so those
            # holding factors violated at G_r's convergence point are searched first.
            violated = set(verdict.violated(self.options.tolerance)) if hasattr(verdict, "violated") else set()
            comps = sorted(g_r.connected_components(),      # deterministic: no set order
                           key=lambda c: (not any(ref in violated for ref in c.factor_refs),
                                          c.steps or (0, 0), min(c.factor_refs)))

            def search_components(lazy: bool, lazy_large: bool) -> Any:
                with overridden(checker, lazy=lazy, lazy_large=lazy_large):
                    for comp in comps:
                        search = find_infeasible_subgraph(comp, (), sw.replace("r", "").replace("g", ""),
                                                          check=checker, solver=solver,
                                                          tolerance=self.options.tolerance,
                                                          recheck=checker.recheck,
                                                          recheck_above=LAZY_MAX_FACTORS)
                        self.stats.rechecks_feasible += search.stats.rechecks_feasible
                        self.heuristic_solves += search.stats.heuristic_solves
                        if search.subgraph is not None:
                            return search.subgraph
                    return None

            found = search_components(self.options.lazy_search, self.options.lazy_large)
            retries = 0
            while found is not None and not checker.confirm(found):
                # a one-start verdict led the search to a feasible subgraph (now in the memo
                # with its solution): search again without the one-start verdicts. The first
                # LAZY_RETRIES repeats keep one start for large subgraphs, the last one gives
                # every subgraph all its starts (the behaviour without lazy_search/lazy_large),
                # whose verdicts need no confirmation, so the loop ends. Why not all starts at
                # once: Lab 5 seed 6, a 76-factor slice failed one start and was solved by a
                # restart of `confirm`; the repeated search with restarts then spent 50 s on
                # each 360-factor slice and timed out.
                retries += 1
                strict = retries > LAZY_RETRIES
                self.say(f"  {found.name}: feasible from a restart; searching {g_r.name} again"
                         + (" with restarts" if strict else ""))
                self.stats.lazy_retries += 1
                checker.forget_unconfirmed()
                found = search_components(self.options.lazy_search and not strict,
                                          self.options.lazy_large and not strict)
            if found is None:
                # Every component is feasible, so G_r is (Property 4.5): the solver missed the
                # joint solution. The union of the components' solutions is one; never turn a
                # failed solve into a conflict.
                self.say(f"  {g_r.name}: components feasible, the whole solve failed; joining the components")
                values: dict = {}
                for comp in comps:
                    r = checker.solve(comp)
                    if not r.feasible:
                        return ("inconsistent", f"{comp.name} is feasible and infeasible in two solves")
                    values.update(r.values)
                if rule is None:
                    return ("solution", values)
                checker.values.update(values)
                checker.results[g_r.signature()] = FeasibilityResult(
                    True, values, {ref: 0.0 for ref in g_r.factor_refs}, 0.0, 0.0, 0.0, 0,
                    "its components are feasible", 0)
                continue
            return ("conflict", tuple(found.factor_instances), rule.name if rule is not None else "")
        return ("solution", {})

    @staticmethod
    def staged(graph: Any, levels: list, cost: Callable[[Any], float] = lambda g: g.n_factors) -> list:
        """Order "staged": the small relaxation levels (an ipopt iteration on them costs at most
        STAGED_FRACTION of one on the mode-switch graph, by `cost`: the loop passes
        `FeasibilitySolver.iteration_cost`, distance rows weighted; the default counts factors),
        then the full graph, then the other levels (only the mode-switch graph among them when
        it is one), then the full graph again (its cached verdict: Alg. 1 searches it when no
        level gives a conflict).

        Why (measured on Lab 4, two Panda arms): the cost of an ipopt iteration grows with the
        collision factors between robot links and objects, ~0.1 s on a 6-step mode-switch graph
        against ~0.005 s without them, and a cold-started infeasible full graph cost 60-145 s
        (restarts included) before the relaxations found the conflict in 1-3 s. The small
        levels (no robot, no collisions) are cheap, find the kinematic and placement conflicts,
        and their solutions warm-start the full graph; the large ones cost about as much as the
        full graph and only help to locate a conflict once it is infeasible. Same verdicts as
        Alg. 1: every level is still a relaxation of the plan's graph."""
        full = levels[-1]
        modes_graph = graph.apply_relaxation({TRAJ}, "modes")
        modes = cost(modes_graph if modes_graph.n_factors else graph)
        small = [lv for lv in levels[:-1] if cost(lv[1]) <= STAGED_FRACTION * modes]
        large = [lv for lv in levels[:-1] if cost(lv[1]) > STAGED_FRACTION * modes]
        # When a large level is the mode-switch graph itself (the full graph without motions),
        # it alone is searched: the full graph's check already solved it (no new NLP before
        # Alg. 1 starts on its slices), while every other large level costs a whole new solve
        # of about the full graph's size (Lab 5: 145 s for no_time_traj, 3 starts).
        key = frozenset(modes_graph.factor_refs)
        same = [lv for lv in large if frozenset(lv[1].factor_refs) == key]
        if same and modes_graph.n_factors < graph.n_factors:
            large = same
        return [*small, full, *large, full] if large else [*small, full]

    def nearly_holds(self, g_r: Any, x_star: dict) -> bool:
        """Screening of a relaxation level by the full graph's convergence point x*: when every
        factor and bound of G_r holds at x* within `screen_tolerance` (looser than the verdict
        tolerance), G_r is taken as not the place of the conflict and its NLP is skipped. Why:
        an infeasible solve stops early, leaving residuals of ~1e-5 on factors that are not part
        of the contradiction; solving such a level only confirms it feasible. Sound either way:
        a skipped level gives no conflict and no verdict, the conflict then comes from a tighter
        level and is still confirmed by an NLP."""
        tol = self.options.screen_tolerance
        if tol <= 0 or any(v not in x_star for v in g_r.variables):
            return False
        return self.violation(g_r.factor_instances, {v: x_star[v] for v in g_r.variables},
                              g_r.variables) <= tol

    def violation(self, factors: Sequence[FactorInstance], point: dict,
                  variables: Iterable[VarInstance] = ()) -> float:
        """Largest violation of `factors` (and of the bounds of `variables`) at `point` by the
        independent numpy evaluator; inf when a primitive cannot be evaluated there (the
        caller then solves instead). Counted in `stats.reuse_time`."""
        from gnppdsl.nlp.evaluate import max_violation

        t0 = time.perf_counter()
        try:
            worst = max_violation(factors, point, self.compiled.geometry)[0] if factors else 0.0
        except Exception:
            return np.inf
        finally:
            self.stats.reuse_time += time.perf_counter() - t0
        return max(worst, bound_violation(variables, point))

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
            r = _Checker(self, self.new_solver(), graph, use_db=False).solve(graph)
            if r.feasible:
                return self.solution(plan, graph, r.values)
            self.stats.conflicts += 1
            self.conflicts.append(Conflict(tuple(PartialState.of(enumerate(s)) for s in plan.states),
                                           "blocked plan: " + "; ".join(plan.names), (), "plan", "",
                                           self.stats.plans, 0))

    # -- solutions -----------------------------------------------------------------------------
    def solution(self, plan: Any, graph: Any, values: dict) -> Result:
        from gnppdsl.nlp.evaluate import EvaluationError, max_violation

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
        self.stats.factors = len(factors)
        self.stats.variables = len(graph.variables)
        steps = []
        for i, s in enumerate(plan.states):
            st = Step(i, plan.names[i - 1] if i > 0 else None, self.task.state_str(s))
            for v in graph.variables:
                if v.step != i or v not in values:
                    continue
                x = np.asarray(values[v], float).reshape(-1)
                if v.waypoints:
                    st.trajectories[v.key] = x.reshape(v.waypoints, v.point_dim).tolist()
                else:
                    st.values[v.key] = x.tolist()
            steps.append(st)
        tol = self.options.check_tolerance or self.options.tolerance
        extras = {"task": self.task, "plan": plan, "graph": graph, "values": values}
        if not worst <= tol:
            what = arg.label if arg is not None and worst > bound_worst else "a variable bound"
            return self.result(SOLVER_FAILURE,
                               f"the solver's solution fails the independent re-check: {what} "
                               f"violated by {worst:.3g} > {tol:g}",
                               plan=list(plan.names), steps=steps, extras=extras)
        return self.result(SOLVED, f"solved with {len(plan)} actions after {self.stats.plans} plans",
                           plan=list(plan.names), steps=steps, extras=extras)


LAZY_MAX_FACTORS = 40
"""Small and large subgraphs of Alg. 1's search (factors). Small ones are solved from one start
only with `lazy_search`: on Lab 3 (subgraphs of at most 26 factors) no one-start verdict was
ever overturned by the restarts. Large ones are solved from one start with `lazy_large`
(default): their restarts (random points, the initial guess) cost 10-20 s each on Lab 5 and
seldom succeed where the warm start failed, and the range the time search ends with gets a
second opinion from its sub-slices' solutions instead (`recheck`, given to ranges above this
size; session 7 without that second opinion: trusting one start on a 123-factor slice sent
the search to another conflict, seed 0: 28 NLPs and 157 s instead of 24 NLPs and 37 s)."""

LAZY_RETRIES = 1
"""Repeats of Alg. 1's search that keep one-start verdicts after `confirm` overturned one (the
overturned subgraph's solution is then in the memo); the next repeat gives every subgraph all
its starts."""

MAX_JOINED_MOTIONS = 3
"""Motions solved together with the keyframes (`_Checker.motions_between_keyframes`) before the
joint solve of every motion is tried instead."""

IDLE_MOTION = 1e-3
"""Largest keyframe change (per coordinate) of a trajectory that `motions_between_keyframes`
first tries with the straight line fixed (a waiting arm); if that phase fails it is solved
again with the trajectory free, so this is a speed setting, never a restriction."""


class StampedValues(dict):
    """`_Checker.values`: the latest value of each variable, and when it was set (`stamp`, one
    tick per `update`: the values of one solve share it), for `_Checker.warm_start`."""

    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__()
        self.stamp: dict = {}
        self.clock = 0
        self.update(*args, **kw)

    def __setitem__(self, key: Any, value: Any) -> None:
        self.clock += 1
        super().__setitem__(key, value)
        self.stamp[key] = self.clock

    def update(self, *args: Any, **kw: Any) -> None:       # type: ignore[override]
        self.clock += 1
        for key, value in dict(*args, **kw).items():
            super().__setitem__(key, value)
            self.stamp[key] = self.clock


def equality_pair(f: FactorInstance) -> tuple[VarInstance, VarInstance] | None:
    """The two variables of a factor whose only constraint is `x0 == x1` between its two
    variables of the same kind of space (e.g. `same(pose(o), pose(o)')`), else None."""
    if len(f.variables) != 2 or len(f.body) != 1:
        return None
    c, (a, b) = f.body[0], f.variables
    if c.op != "==" or {c.lhs, c.rhs} != {Slot(0), Slot(1)} or (a.space, a.dim) != (b.space, b.dim):
        return None
    return a, b


def _children_cpu() -> float:
    """CPU seconds of finished child processes (the C compiler of `gnppdsl.nlp.jit`)."""
    import resource

    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _fixed(v: VarInstance, value: Any) -> VarInstance:
    """v with lower = upper bound = value: equal to v (bounds do not take part in equality),
    so it replaces v in a graph-NLP's vertex set for a solve with v held fixed."""
    x = tuple(float(t) for t in np.asarray(value, float).reshape(-1))
    return replace(v, lower=x, upper=x)


def bound_violation(variables: Iterable[VarInstance], values: dict) -> float:
    """Largest violation of the variables' lower/upper bounds (part of the NLP, not factors)."""
    worst = 0.0
    for v in variables:
        if v not in values:
            continue
        x = np.asarray(values[v], float).reshape(-1)
        for bound, sign in ((v.lower, -1.0), (v.upper, 1.0)):
            if bound is None:
                continue
            b = np.asarray(bound, float).reshape(-1)
            if b.size != x.size and x.size % max(b.size, 1) == 0:
                b = np.tile(b, x.size // b.size)     # per-point bounds of a trajectory
            if b.size != x.size:
                continue
            d = sign * (x - b)
            d = d[np.isfinite(d)]
            if d.size:
                worst = max(worst, float(d.max()))
    return worst


# ---------------------------------------------------------------------------------------------
# entry points
# ---------------------------------------------------------------------------------------------
def solve_compiled(compiled: Compiled, options: SolveOptions | None = None,
                   progress: Progress | None = None) -> Result:
    """Solve an already compiled problem (a fresh planner, solver caches and database per call)."""
    options = (options or SolveOptions.from_settings(getattr(compiled.problem, "settings", None))).validated()
    return _Run(compiled, options, progress).solve()


def solve_problem(problem: Any, options: SolveOptions | None = None, progress: Progress | None = None,
                  **overrides: Any) -> Result:
    """Solve a problem given as a path, a list of paths, an IR `Problem` or a `Compiled`.

    Keyword overrides (algorithm, switches, time_limit, seed, ...) apply on top of `options`,
    or of the problem's own solver settings when `options` is None.
    """
    if isinstance(problem, Compiled):
        compiled = problem
    elif isinstance(problem, (str, Path, list, tuple)):
        compiled = load_and_compile(problem)
    else:
        compiled = compile_problem(problem)
    if options is None:
        options = SolveOptions.from_settings(getattr(compiled.problem, "settings", None), **overrides)
    elif overrides:
        options = replace(options, **{k: v for k, v in overrides.items() if v is not None}).validated()
    return solve_compiled(compiled, options, progress)
