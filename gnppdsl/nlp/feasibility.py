"""Feasibility of a (sub)graph-NLP with an elastic formulation solved by ipopt.

Why elastic: ipopt on the plain feasibility problem (zero objective) certifies infeasibility
unreliably and slowly (stack-facts: 5/10 toy problems, up to 0.8 s). Adding a slack to every
constraint row,

    min  sum(s) + rho * |x - x0|^2
    s.t. h_ineq(x) - s_ineq <= 0,   h_eq(x) - s_plus + s_minus = 0,   s >= 0,
         |quat(x)|^2 = 1 for SE3 variables,   lower <= x <= upper (joint limits),

is always feasible, converges in a few ms, and its optimum x* is the convergence point the
paper's heuristic needs (Sec. VI-C): the factors still violated at x* span the candidate
conflict. The verdict is *not* read from the slacks: the real constraints are evaluated at x*
(quaternions normalised) and the graph is feasible iff every row's violation is below the
tolerance. The L1 penalty is exact, so a small regulariser (rho) does not move feasible optima
off the constraints; it only makes the optimum unique and keeps ipopt well conditioned.

A local optimizer can miss a feasible point; `restarts` re-solves an infeasible verdict from
random starts (Theorem 7.1 relies on the optimizer finding feasible solutions), and `polish`
re-solves the best point with a 1e-4 weaker pull (a badly scaled row far from the start).

Cost control (measured on the lab and mobile Panda domains, see SolverOptions): assembly in MX
when bodies use geometry primitives (each factor stays a call of its template Function), an
ipopt iteration monitor that stops as soon as the real rows hold or progress stalls, a cache
of assembled NLPs per vertex set, and a per-instance compile memo.
"""
from __future__ import annotations

import math
import time
import zlib
from collections import OrderedDict
from dataclasses import dataclass, field, replace
from typing import Mapping, NamedTuple

import casadi as ca
import numpy as np

from gnppdsl import interrupt
from gnppdsl.compile.factors import VarInstance
from gnppdsl.errors import UserError
from gnppdsl.nlp.body_compiler import BodyCompiler, CompiledBody
from gnppdsl.nlp.elastic_derivatives import hessian_function, jacobian_function, mapped_rows
from gnppdsl.nlp.geometry_protocol import DISTANCE_PRIMITIVES, Geometry
from gnppdsl.nlp.graph import FactorRef, GraphNLP
from gnppdsl.nlp import shape_cache
from gnppdsl.nlp.monitor import START_HELD, IterationMonitor as _Monitor, raise_on_nan as _raise_on_nan
from gnppdsl.nlp.solver_options import KINEMATIC_CURVATURE_MODES, CurvatureTrials, SolverOptions  # noqa: F401

#: the status of a run whose near start a few Levenberg-Marquardt steps made hold
#: (`FeasibilitySolver._projected`): ipopt not run
START_PROJECTED = "Start_Projected"


@dataclass
class FeasibilityResult:
    """Verdict and convergence point of one feasibility solve."""

    feasible: bool
    values: dict[VarInstance, np.ndarray]          # x* per variable vertex
    violations: dict[FactorRef, float]             # real violation per factor at x*
    max_violation: float
    slack: float                                   # optimum of the elastic objective (sum s)
    solve_time: float                              # seconds (assembly + all ipopt runs)
    iterations: int
    status: str
    starts: int = 1                                # number of ipopt runs (1 + restarts used)
    # per factor, the largest |multiplier| of its elastic rows at the convergence point (see
    # `active`); empty when the point is not the solver's own last iterate
    activity: dict[FactorRef, float] = field(default_factory=dict)
    # every multiplier at the convergence point, with the pull that produced it: what
    # `gnppdsl.nlp.certificate` needs to decide a subgraph there without solving it (None when
    # the multipliers are not known)
    duals: "Duals | None" = None

    def violated(self, tolerance: float) -> list[FactorRef]:
        """Factors violated at the convergence point (input of the convergence heuristic)."""
        return [r for r, v in self.violations.items() if v > tolerance]

    def active(self, tolerance: float, share: float = 0.1) -> list[FactorRef]:
        """The support of the infeasibility at the convergence point: the violated factors and
        those whose multiplier is at least `share` of the penalty weight. Why: at the optimum of
        the elastic form a violated row has multiplier 1 (its slack's weight) and a row that
        holds has one in [0, 1], near 1 when it is what keeps the violated rows from being
        satisfied (planar p5: the spot's pose, the kinematic switch and the reach box that a
        violated grasp fights carry 0.8-0.9, the other rows 1e-11 to 4e-3). These factors,
        without the rest of the graph, are the first candidate of the convergence heuristic."""
        if not self.activity:
            return []
        violated = set(self.violated(tolerance))
        return [r for r in self.violations if r in violated or self.activity.get(r, 0.0) >= share]


@dataclass(frozen=True)
class Duals:
    """The elastic NLP's multipliers at a convergence point x*, per factor and per variable (so
    that any subgraph can take its share), and the pull (centre x0, weight rho) of the run that
    ended there. Why keep them: at an infeasible x* the factors carrying no multiplier play no
    part in the contradiction, and the optimality conditions of a subgraph without them can be
    checked at x* from these numbers alone (`gnppdsl.nlp.certificate`)."""

    rows: dict[FactorRef, np.ndarray]          # lam_g of each factor's rows, in the order of h
    quats: dict[VarInstance, np.ndarray]       # lam_g of each variable's unit-quaternion rows
    bounds: dict[VarInstance, np.ndarray]      # lam_x of each variable's entries
    start: dict[VarInstance, np.ndarray]       # x0, the centre of the pull
    rho: float                                 # the pull's weight


class _Multipliers(NamedTuple):
    """What one ipopt run (`FeasibilitySolver._run`) ended with besides its point: the
    multipliers of the rows and bounds, the pull (centre x0, weight rho) and the whole z
    (variables and slacks), from which a polish is warm-started."""

    lam_g: np.ndarray
    lam_x: np.ndarray
    x0: np.ndarray
    rho: float
    z: np.ndarray


@dataclass
class _Assembled:
    solver: ca.Function
    h_fun: ca.Function                 # x, P -> real constraint rows (for the verdict)
    variables: list[VarInstance]
    offsets: list[int]
    n_x: int
    kinds: np.ndarray                  # per real row: True if eq
    factor_rows: list[tuple[FactorRef, int, int]]
    params: np.ndarray
    n_ineq: int
    n_eq: int
    lbx: np.ndarray
    ubx: np.ndarray
    lbg: np.ndarray
    ubg: np.ndarray
    monitor: _Monitor | None = None
    row_factors: tuple = ()            # the FactorInstance of each factor_rows entry (kept alive:
                                       # the cache key holds their ids)
    spec: tuple = ()                   # (name, plugin, nlp, options) of `solver`: see `_polisher`
    polisher: ca.Function | None = None
    near: ca.Function | None = None    # `FeasibilitySolver._near`, built on first use
    root: "_Assembled | None" = None   # the assembly this one shares its solver with (shape_cache)
    linearised: bool = False           # forward-kinematics rows left out of ipopt's Hessian
                                       # (`kinematic_curvature` false or the first pass of "auto")
    # `params` and ipopt's parameter vector as casadi DMs, each with the `params` array it was
    # made from (`replace` copies these fields: an assembly with other numbers remakes them)
    _params_dm: tuple = (None, None)
    _p_dm: tuple = (None, None)
    _last_rows: tuple = (None, b"", None)      # (params, x's bytes, h(x)): see `rows`

    def params_dm(self) -> ca.DM:
        """`params` as a DM, converted once per assembly. Why: casadi converts a numpy
        argument element by element (~55 ns each: a path NLP's 1,600-2,400 parameters cost
        ~0.1 ms per `h_fun` call), a DM is copied in ~8 us."""
        src, dm = self._params_dm
        if src is not self.params:
            dm = ca.DM(self.params)
            self._params_dm = (self.params, dm)
        return dm

    def p_dm(self, x0: np.ndarray, rho: float) -> ca.DM:
        """The solver's parameter vector (x0, params, rho) as a DM kept per assembly, whose
        x0 and rho are overwritten in place (see `params_dm` for why; casadi copies a call's
        inputs, so the buffer may change after the call)."""
        src, dm = self._p_dm
        if src is not self.params:
            dm = ca.DM(np.concatenate([x0, self.params, [rho]]))
            self._p_dm = (self.params, dm)
            return dm
        if self.n_x:
            dm[:self.n_x] = x0
        dm[dm.numel() - 1] = rho
        return dm

    def rows(self, x: np.ndarray) -> np.ndarray:
        """h(x): the real constraint rows at x (read-only), remembered for the last x. Why: a
        run that returns its start (`START_HELD`) has its verdict taken at the point whose rows
        the start check has just evaluated (`elastic_point`): a path NLP's rows cost ~0.3-0.7
        ms, and half of `bench_komo.py`'s path NLPs end so."""
        x = np.ascontiguousarray(x, dtype=float).reshape(-1)
        key = x.tobytes()
        src, last, h = self._last_rows
        if src is self.params and last == key:
            return h
        h = np.asarray(self.h_fun(x, self.params_dm()), dtype=float).reshape(-1)
        h.flags.writeable = False
        self._last_rows = (self.params, key, h)
        return h


def elastic_point(a: _Assembled, x: np.ndarray) -> np.ndarray:
    """z = (x, the slacks at their optimum for x: each row's violation) of `a`'s elastic NLP."""
    h = a.rows(x)
    hi, he = h[~a.kinds], h[a.kinds]
    return np.concatenate([x, np.maximum(hi, 0), np.maximum(he, 0), np.maximum(-he, 0)])


def g_rows_of(a: _Assembled) -> np.ndarray:
    """For each row of h (the factors' rows in order), its row in the elastic NLP's g, which
    holds the inequality rows first, then the equality rows, then the unit quaternions."""
    g_row = np.empty(a.kinds.size, dtype=np.int64)
    g_row[~a.kinds] = np.arange(a.n_ineq)
    g_row[a.kinds] = a.n_ineq + np.arange(a.n_eq)
    return g_row


def _z_bounds(variables: list[VarInstance], n_slacks: int) -> tuple[np.ndarray, np.ndarray]:
    """Bounds of z = (x, slacks): the variables' bounds, then slacks >= 0."""
    lbx = np.concatenate([_bounds(v, v.lower, -np.inf) for v in variables]) if variables else np.zeros(0)
    ubx = np.concatenate([_bounds(v, v.upper, np.inf) for v in variables]) if variables else np.zeros(0)
    return np.concatenate([lbx, np.zeros(n_slacks)]), np.concatenate([ubx, np.full(n_slacks, np.inf)])


def _bounds(v: VarInstance, bound, default: float) -> np.ndarray:
    if bound is None:
        return np.full(v.dim, default)
    b = np.asarray(bound, float)
    if b.size == v.point_dim and v.waypoints:
        b = np.tile(b, v.waypoints)
    if b.size != v.dim:
        raise ValueError(f"{v.name}: bounds of length {b.size}, expected {v.dim}")
    return b


def _quat_slices(v: VarInstance) -> list[slice]:
    if v.space != "SE3":
        return []
    n = max(v.waypoints, 1)
    d = v.dim // n
    return [slice(k * d + 3, k * d + 7) for k in range(n)]


def _unit_quaternions(v: VarInstance, x: np.ndarray) -> np.ndarray:
    """x (v's values, modified in place and returned) with every quaternion of v normalised."""
    for sl in _quat_slices(v):
        nq = np.linalg.norm(x[sl])
        if nq > 0:
            x[sl] = x[sl] / nq
    return x


def _moved(v: VarInstance, val, rng: np.random.Generator, scale: float) -> np.ndarray:
    """A start: v's value `val` plus normal noise of std `scale`, quaternions renormalised."""
    return _unit_quaternions(v, np.asarray(val, float).reshape(-1) + rng.normal(0.0, scale, v.dim))


def interpolated_trajectory(v: VarInstance, known: Mapping[VarInstance, np.ndarray]
                            ) -> np.ndarray | None:
    """Start for trajectory x_i (motion from step i to i+1): the straight line between the
    known values of the mode-switch variables it connects (same objects and point space, steps
    i and i+1), as the paper warm-starts trajectories after solving without them (App. C)."""
    ends = {}
    for u, val in known.items():
        if (u.args == v.args and not u.waypoints and u.space == v.space
                and u.dim == v.point_dim and u.step in (v.step, v.step + 1)):
            ends.setdefault(u.kind, {})[u.step] = np.asarray(val, float).reshape(-1)
    full = [k for k, d in ends.items() if len(d) == 2]
    if len(full) != 1:
        return None
    a, b = ends[full[0]][v.step], ends[full[0]][v.step + 1]
    t = np.linspace(0.0, 1.0, v.waypoints)[:, None]
    pts = (1 - t) * a + t * b
    for sl in _quat_slices(VarInstance(v.kind, v.args, v.step, v.space, v.point_dim)):
        pts[:, sl] /= np.linalg.norm(pts[:, sl], axis=1, keepdims=True)
    return pts.reshape(-1)


# `FeasibilitySolver.iteration_cost`: a row that queries a signed distance costs about this many
# plain rows per ipopt iteration. Measured on the Lab graph-NLPs (distance_curvature off; ms per
# iteration ~ 0.5 + 0.004 per plain row + 0.043 per distance row: 1.4 ms for 228 plain rows,
# 5.3-6.1 ms for 514 + 84 distance rows, 33 ms for 430 + 711, 13.3 ms for 178 + 296).
DISTANCE_ROW_COST = 10.0
# `FeasibilitySolver._separated`: std of the offset given to a first start equal to another
# variable's of the same kind and step
SEPARATION = 1e-3

# Starts added when every run so far ended at a point where some row is NaN or infinite
# (`_verdict`: worst = inf). Why: such a point is no verdict, and a row undefined at one point
# ipopt reached (a distance query coal failed at, field5 seed 0 of 709ab9a) is not a fault of
# the model; the run ended in "solver fault" at once when the NLP had one start (restarts=0, the
# loop's first check). Only when the rows are undefined from these starts too is the NLP
# reported as faulty (`monitor.raise_on_nan`).
UNDEFINED_RESTARTS = 2


class FeasibilitySolver:
    """Assembles and solves graph-NLPs; owns the per-template Function cache (BodyCompiler)
    and a cache of assembled NLPs per subgraph, so multi-starts and repeated checks of the
    same subgraph do not rebuild anything."""

    def __init__(self, geometry: Geometry | None = None, options: SolverOptions | None = None,
                 compiler: BodyCompiler | None = None):
        self.options = options or SolverOptions()
        self.compiler = compiler or BodyCompiler(geometry)
        self._nlps: OrderedDict[frozenset, _Assembled] = OrderedDict()   # LRU
        self.deadline = math.inf        # time.perf_counter() at which ipopt runs stop (_Monitor)
        self._built = 0
        self.solves = 0                 # ipopt runs
        self.solve_time = 0.0
        self.curvature_fallbacks = 0    # solves whose linearised runs failed and got exact ones
        self.curvature_rescues = 0      # ... of which the exact Hessian made feasible
        self._exact_pass = False        # assembling the exact Hessian (`exact_assembly`)
        self._project = True            # a near start may take `_projected`'s steps (`solve`)
        self.trials = CurvatureTrials()  # ... how its linearised runs fared (a loop shares one)
        kc = self.options.kinematic_curvature
        if kc not in KINEMATIC_CURVATURE_MODES:
            raise UserError(f"kinematic_curvature must be true, false or auto, not {kc!r}")

    @property
    def kinematic_exact(self) -> bool:
        """Whether the NLPs assembled now keep the forward-kinematics rows' second derivatives
        in ipopt's Hessian: the setting (linearised first under "auto"), unless the exact
        one is being assembled (`exact_assembly`)."""
        return self._exact_pass or self.options.kinematic_curvature is True

    # -- cost -------------------------------------------------------------------------------
    def iteration_cost(self, graph: GraphNLP) -> float:
        """Estimated cost of one ipopt iteration on `graph`, in units of a plain constraint
        row: rows of templates that query signed distances count DISTANCE_ROW_COST each (a
        coal query plus the forward kinematics of both bodies, for the row and its Jacobian),
        every other row 1. Why not the factor count: a factor may be one row or a hundred, and
        a level without collisions costs a fraction of the mode-switch graph's iteration even
        when it keeps more than half of its factors (Lab 3: 20 of 38 factors, 2 vs 6.4 ms per
        iteration). Cheap: the compiled bodies are remembered per template structure and per
        factory body (`BodyCompiler.compile`), and every level's factors are the plan graph's."""
        cost = 0.0
        for _, f in graph.iter_factors():
            cb, _ = self.compiler.compile(f)
            cost += cb.n_rows * (DISTANCE_ROW_COST if DISTANCE_PRIMITIVES & cb.primitives else 1)
        return cost

    # -- assembly ---------------------------------------------------------------------------
    def assemble(self, graph: GraphNLP) -> _Assembled:
        # Key: the variables and the factor *instances* (by identity; the cached entry keeps
        # them alive). Not FactorRefs: those are positions in one plan's factor list, so two
        # plans' graphs could share refs for different factors. A hit from another graph gets
        # its factor rows re-labelled with that graph's refs.
        inst = list(graph.iter_factors())
        key = (frozenset(graph.variables), frozenset(id(f) for _, f in inst), self.kinematic_exact)
        a = self._nlps.get(key)
        if a is not None:
            self._nlps.move_to_end(key)
            ref_of = {id(f): r for r, f in inst}
            if any(ref_of[id(f)] != r for (r, _, _), f in zip(a.factor_rows, a.row_factors)):
                a = replace(a, factor_rows=[(ref_of[id(f)], i0, i1) for (_, i0, i1), f
                                             in zip(a.factor_rows, a.row_factors)])
            return a
        variables = graph.variables
        offsets, n = [], 0
        for v in variables:
            offsets.append(n)
            n += v.dim
        index = {v: i for i, v in enumerate(variables)}
        compiled: list[tuple[FactorRef, CompiledBody, np.ndarray]] = []
        for r, f in graph.iter_factors():
            cb, p = self.compiler.compile(f)
            compiled.append((r, cb, p))
        # SX assembly inlines every factor (fastest for small bodies); MX keeps each factor a
        # call of its template Function, whose derivatives casadi builds once per template.
        # Geometry primitives (FK chains, coal callbacks) make inlined SX graphs and their
        # Hessians huge (measured on the Panda domain: 54 s to assemble 119 factors and 0.45 s
        # per ipopt iteration), so "auto" assembles in MX whenever a body uses one.
        mode = self.options.assembly
        use_mx = mode == "MX" or any(cb.symbolic == "MX" for _, cb, _ in compiled) or (
            mode == "auto" and any(cb.primitives for _, cb, _ in compiled))
        # the same structure assembled for another graph: only its numbers differ (shape_cache)
        skey = shape_cache.shape_key(variables, compiled,
                                     [[index[v] for v in graph.factor(r).variables] for r, _, _ in compiled],
                                     [_quat_slices(v) for v in variables], self._shape_options(use_mx))
        shared = shape_cache.lookup(self.compiler, skey) if self.options.shared_assembly else None
        if shared is not None and self._wall_time_holds(shared):
            params, factor_rows = shape_cache.instance_numbers(compiled, use_mx)
            fac = dict(inst)
            lbz, ubz = _z_bounds(variables, shared.n_ineq + 2 * shared.n_eq)
            a = replace(shared, variables=variables, offsets=offsets, factor_rows=factor_rows,
                        params=params, lbx=lbz, ubx=ubz, row_factors=tuple(fac[r] for r, _, _ in factor_rows),
                        root=shared.root or shared)
            self._remember(key, a)
            return a
        S = ca.MX if use_mx else ca.SX
        # ipopt with the exact Hessian gets jac_g and hess_lag from the per-template derivatives
        # below and never differentiates g: g may then evaluate the bodies' fast twins
        # (`CompiledBody.evaluate`: native distance queries), which casadi cannot differentiate
        given_derivatives = self.options.plugin == "ipopt" and self.options.hessian == "exact"
        if use_mx:
            x, P, params, rows, kinds, factor_rows, layout = mapped_rows(graph, compiled, index, offsets, n,
                                                                         given_derivatives)
        else:
            params, factor_rows = shape_cache.instance_numbers(compiled, grouped=False)
            x = S.sym("x", n)
            P = S.sym("P", params.size)
            rows, kinds, p0 = [], [], 0
            for r, cb, p in compiled:
                f = graph.factor(r)
                args = [x[offsets[index[v]]:offsets[index[v]] + v.dim] for v in f.variables]
                h = cb.function(*args, P[p0:p0 + cb.n_params])
                p0 += cb.n_params
                rows.append(h)
                kinds += [k == "eq" for k in cb.kinds]
        h_all = ca.vertcat(*rows) if rows else S(0, 1)
        kinds_arr = np.array(kinds, dtype=bool)
        ineq = np.flatnonzero(~kinds_arr)
        eq = np.flatnonzero(kinds_arr)
        s_in = S.sym("s_in", ineq.size)
        s_p = S.sym("s_p", eq.size)
        s_m = S.sym("s_m", eq.size)
        x0 = S.sym("x0", n)
        rho = S.sym("rho")
        quats = [ca.sumsqr(x[offsets[index[v]] + sl.start:offsets[index[v]] + sl.stop]) - 1
                 for v in variables for sl in _quat_slices(v)]
        g = ca.vertcat(h_all[ineq.tolist()] - s_in if ineq.size else S(0, 1),
                       h_all[eq.tolist()] - s_p + s_m if eq.size else S(0, 1),
                       *quats)
        # pseudo-Huber pull towards the start: curvature rho near x0, gradient bounded by rho,
        # so the L1 penalty stays exact however far the solution is from the start.
        reg = ca.sum1(ca.sqrt(1 + (x - x0) ** 2) - 1) if n else 0
        obj = ca.sum1(ca.vertcat(s_in, s_p, s_m)) + rho * reg
        z = ca.vertcat(x, s_in, s_p, s_m)
        self._built += 1
        opts = self.options.nlpsol_options()
        monitor = None
        early = self.options.early_stop
        if early == "auto":
            early = any(cb.primitives for _, cb, _ in compiled)
        if self.options.plugin == "ipopt" and early:
            monitor = _Monitor(f"monitor_{self._built}", n, ineq.size, eq.size, g.numel(),
                               n + params.size + 1)
            opts["iteration_callback"] = monitor
        if use_mx and self.options.plugin == "ipopt" and self.options.hessian == "exact":
            h_rows = np.empty(kinds_arr.size, dtype=np.int64)
            h_rows[ineq] = np.arange(ineq.size)
            h_rows[eq] = ineq.size + np.arange(eq.size)
            quat_idx = [offsets[index[v]] + i for v in variables for sl in _quat_slices(v)
                        for i in range(sl.start, sl.stop)]
            opts["hess_lag"] = hessian_function(self.compiler, layout, n, z.numel(), params.size, h_rows,
                                                quat_idx, g.numel(), self.options.distance_curvature,
                                                self.kinematic_exact)
            opts["jac_g"] = jacobian_function(self.compiler, layout, n, z.numel(), params.size, h_rows,
                                              quat_idx, ineq.size, eq.size)
        solver = ca.nlpsol(f"elastic_{self._built}", self.options.plugin,
                           {"x": z, "f": obj, "g": g, "p": ca.vertcat(x0, P, rho)}, opts)
        h_fun = ca.Function("h", [x, P], [h_all])
        lbz, ubz = _z_bounds(variables, ineq.size + 2 * eq.size)
        lbg = np.concatenate([np.full(ineq.size, -np.inf), np.zeros(eq.size), np.zeros(len(quats))])
        ubg = np.zeros(ineq.size + eq.size + len(quats))
        fac = dict((r, f) for r, f in inst)
        linearised = "hess_lag" in opts and not self.kinematic_exact and any(
            "fk" in cb.primitives and (self.options.distance_curvature or not DISTANCE_PRIMITIVES & cb.primitives)
            for _, cb, _ in compiled)
        a = _Assembled(solver, h_fun, variables, offsets, n, kinds_arr, factor_rows, params,
                       ineq.size, eq.size, lbz, ubz, lbg, ubg, monitor,
                       tuple(fac[r] for r, _, _ in factor_rows),
                       (f"elastic_{self._built}", self.options.plugin,
                        {"x": z, "f": obj, "g": g, "p": ca.vertcat(x0, P, rho)}, opts),
                       linearised=linearised)
        self._remember(key, a)
        shape_cache.store(self.compiler, skey, a, [cb for _, cb, _ in compiled])
        return a

    def _remember(self, key: tuple, a: _Assembled) -> None:
        self._nlps[key] = a
        while len(self._nlps) > self.options.cache_size:
            self._nlps.popitem(last=False)

    def _shape_options(self, use_mx: bool) -> tuple:
        """What of the options the assembly reads, for `shape_cache` keys. Not ipopt's
        `max_wall_time`: see `_wall_time_holds`."""
        o = self.options
        opts = {k: v for k, v in o.nlpsol_options().items() if k != "ipopt.max_wall_time"}
        return (use_mx, o.plugin, o.hessian, o.distance_curvature, self.kinematic_exact,
                o.early_stop, o.assembly,
                repr(sorted((k, repr(v)) for k, v in opts.items())))

    def _wall_time_holds(self, shared: _Assembled) -> bool:
        """Whether a shared NLP stops in time for this solver: its `max_wall_time` is this
        solver's, or its iteration monitor enforces this solver's deadline and its wall time
        is no shorter than this solver's (a shorter one could cut a run that has time left)."""
        stored = shared.spec[3].get("ipopt.max_wall_time") if shared.spec else None
        wanted = self.options.time_limit
        if stored == (None if wanted is None else float(wanted)):
            return True
        return (shared.monitor is not None and math.isfinite(self.deadline)
                and (stored is None or (wanted is not None and stored >= wanted)))

    # -- starts -----------------------------------------------------------------------------
    def _default_start(self, v: VarInstance, seed: int, attempt: int) -> np.ndarray:
        # One generator per (seed, attempt, variable): unrelated variables never start at the
        # same point (e.g. two single-disc components solved one after the other), whose
        # coincident values would be a stationary point of distance constraints.
        rng = np.random.default_rng([seed, attempt, zlib.crc32(v.name.encode())])
        x = np.zeros(v.dim)
        if v.lower is not None and v.upper is not None:
            lo, up = _bounds(v, v.lower, -np.inf), _bounds(v, v.upper, np.inf)
            finite = np.isfinite(lo) & np.isfinite(up)
            x[finite] = 0.5 * (lo[finite] + up[finite])
        for sl in _quat_slices(v):
            x[sl.stop - 1] = 1.0
        scale = self.options.noise * (1.0 if attempt == 0 else 10.0)
        return x + rng.normal(0.0, scale, v.dim)

    def _start(self, a: _Assembled, graph: GraphNLP, warm_start, initial_guess,
               seed: int, attempt: int) -> np.ndarray:
        x0 = np.zeros(a.n_x)
        guess = initial_guess if initial_guess is not None else graph.initial_guess
        known: dict[VarInstance, np.ndarray] = {}
        if attempt == 0:
            known = {**(guess or {}), **(warm_start or {})}
        elif attempt % 2 == 1:
            known = {**(guess or {}), **graph.restart_guess}
        seen: set[tuple] = set()
        for v, off in zip(a.variables, a.offsets):
            val = known.get(v)
            if val is None and v.waypoints and known:
                val = interpolated_trajectory(v, known)
            if val is None:
                val = self._default_start(v, seed, attempt)
            elif attempt > 0 and not (attempt % 2 == 1 and v in graph.restart_guess):
                # (a placed base starts where it was placed: moved by the restart noise, the
                # pick at 74 degrees of tests/solve/test_solve_mobile_yaw.py drifted back south)
                val = self._perturbed(v, val, seed, attempt)
            elif v.space in ("SE2", "SE3") and not v.waypoints:
                key = (v.kind, v.step, np.asarray(val, float).tobytes())
                if key in seen:
                    val = self._separated(v, val, seed)
                seen.add(key)
            x0[off:off + v.dim] = np.asarray(val, float).reshape(-1)
        return np.clip(x0, a.lbx[:a.n_x], a.ubx[:a.n_x])

    def _separated(self, v: VarInstance, val, seed: int) -> np.ndarray:
        """The first start of a pose variable (SE2/SE3 keyframe) whose guess equals that of
        another variable of its kind at its step (e.g. blocks moved into one region, each at
        the identity relative to it), moved by SEPARATION (quaternions renormalised). Joint
        configurations are left alone: two arms with one home configuration are not coincident
        bodies (their bases differ), and moving them only made Lab 4's runs depend on the seed
        (14 -> 15.6 ± 4.5 NLPs). Why at all: coincident bodies are a
        stationary point of the distance rows between them (no direction to separate along);
        from there a one-start solve of two `no_overlap` factors stalled and was called
        infeasible (planar p4, whose wrong verdicts sent a level through a repeated search:
        14 instead of 10 NLPs). A millimetre gives the rows a direction and leaves every other
        start as the guess made it."""
        return _moved(v, val, np.random.default_rng([seed, zlib.crc32(v.name.encode()), 2]), SEPARATION)

    def _perturbed(self, v: VarInstance, val, seed: int, attempt: int) -> np.ndarray:
        """The odd restarts: the graph's initial guess (not the warm start; a mobile base
        placed next to what it acts on at the step, `GraphNLP.restart_guess`), moved by
        `restart_noise` (quaternions renormalised). Why not only random points: on robot
        domains a random start puts both arms and every object far from anything (Lab:
        200-400 ipopt iterations, often deep in penetrations) and found no solution where one
        existed (Lab 1: a 2-step pick's keyframes infeasible from the warm start, the
        relaxations' solution, and from two random starts, a false conflict; from the initial
        guess, arms at home and objects where they stand, they solve). The even restarts stay
        random."""
        rng = np.random.default_rng([seed, attempt, zlib.crc32(v.name.encode()), 1])
        return _moved(v, val, rng, self.options.restart_noise)

    # -- solving ----------------------------------------------------------------------------
    def _polisher(self, a: _Assembled) -> ca.Function | None:
        """`a`'s NLP as an ipopt solver that starts from given multipliers (warm start of the
        interior point: small barrier, no push off the bounds), built on first use. Why: the
        polish re-solves a convergence point with a weaker pull; from scratch ipopt climbs back
        from its initial barrier (10-18 iterations on planar p5's plans, more than the solve
        itself), warm-started 4-10."""
        a = a.root or a                   # graphs of one structure share it (shape_cache)
        if a.polisher is None and a.spec and a.spec[1] == "ipopt":
            name, plugin, nlp, opts = a.spec
            warm = {"ipopt.warm_start_init_point": "yes", "ipopt.mu_init": 1e-6}
            warm.update({f"ipopt.warm_start_{k}": 1e-9 for k in ("bound_push", "mult_bound_push",
                                                                   "slack_bound_push", "bound_frac",
                                                                   "slack_bound_frac")})
            a.polisher = ca.nlpsol(f"{name}_polish", plugin, nlp, {**opts, **warm})
        return a.polisher

    def _near(self, a: _Assembled) -> ca.Function | None:
        """`a`'s NLP as an ipopt solver that pushes the start only 1e-4 (instead of ipopt's
        1e-2) into the interior of the bounds, built on first use and shared by the graphs of
        one structure. Why: the slacks of an elastic start are the rows' violations, 0 where a
        row holds; ipopt's default push moves each of them to 0.01 and then spends iterations
        driving them back. For a start whose rows already (nearly) hold, a motion between solved
        keyframes started on the straight line between them, that is all the work: measured on
        `bench_komo.py`'s path NLPs (start violation <= 5e-4) 4-5 iterations -> 1 with the same
        verdicts. From a far start (a keyframe NLP from the factory's guess, violation ~1) the
        small push costs iterations (32 -> 36-43), so that start keeps the default solver.
        No gradient-based NLP scaling either: its extra Jacobian evaluation at the start was 1
        of 2-3 (2.3 ms each) in those path NLPs, and it scaled nothing there (no gradient > 100)."""
        a = a.root or a
        if a.near is None and a.spec and a.spec[1] == "ipopt":
            name, plugin, nlp, opts = a.spec
            a.near = ca.nlpsol(f"{name}_near", plugin, nlp,
                               {**opts, "ipopt.bound_push": 1e-4, "ipopt.bound_frac": 1e-4,
                                "ipopt.nlp_scaling_method": "none"})
        return a.near

    def _run(self, a: _Assembled, x0: np.ndarray, rho: float, warm: _Multipliers | None = None,
             limit: int = 0) -> tuple[np.ndarray, float, int, str, _Multipliers | None]:
        """One ipopt run from x0 with the pull rho towards it; `warm` = the multipliers of an
        earlier run from whose point x0 is (a polish): started from its z and multipliers
        (`_polisher`); `limit` > 0: at most that many iterations (an NLP with a monitor)."""
        solver = self._polisher(a) if warm is not None else None
        if a.monitor is not None:
            a.monitor.reset(0.1 * self.options.tolerance, self.options.stall_iterations, self.deadline, limit)
        with interrupt.native():         # a signal stops the run (_Monitor), raised after it
            if solver is not None:
                sol = solver(x0=warm.z, lam_x0=warm.lam_x, lam_g0=warm.lam_g, p=a.p_dm(x0, rho),
                             lbx=a.lbx, ubx=a.ubx, lbg=a.lbg, ubg=a.ubg)
            else:
                z0 = np.nan_to_num(elastic_point(a, x0), nan=1.0, posinf=1e3, neginf=-1e3)
                quats = [z0[o + q.start:o + q.stop] for v, o in zip(a.variables, a.offsets) for q in _quat_slices(v)]
                if a.monitor is not None and a.monitor.start_holds(z0, quats):
                    return x0.copy(), float(np.sum(z0[a.n_x:])), 0, START_HELD, None     # ipopt not run
                # the slacks of z0 are the start's violations (`elastic_point`)
                near = z0.size == a.n_x or float(z0[a.n_x:].max()) <= self.options.near_start_below
                if near and self._project and a.monitor is not None:
                    xp = self._projected(a, x0, rho, a.monitor.stop_below)
                    if xp is not None:
                        return xp, 0.0, 0, START_PROJECTED, None                # ipopt not run
                solver = (self._near(a) if near else None) or a.solver
                sol = solver(x0=z0, p=a.p_dm(x0, rho), lbx=a.lbx, ubx=a.ubx, lbg=a.lbg, ubg=a.ubg)
        st = solver.stats()
        self.solves += 1
        z = np.asarray(sol["x"]).reshape(-1)
        # multipliers of the constraint rows and of x's bounds, with the pull of this run
        lam = _Multipliers(np.asarray(sol["lam_g"]).reshape(-1), np.asarray(sol["lam_x"]).reshape(-1),
                           x0, rho, z)
        status = str(st.get("return_status", ""))
        if a.monitor is not None and a.monitor.stalled and a.monitor.best_z is not None:
            z = a.monitor.best_z          # the best point seen, not where ipopt wandered to
            lam = None                    # ... whose multipliers are not known
        if a.monitor is not None and a.monitor.timed_out:
            status = "Maximum_WallTime_Exceeded"      # the deadline, not a verdict
        elif a.monitor is not None and a.monitor.limit and a.monitor.count > a.monitor.limit:
            status = "Maximum_Iterations_Exceeded"    # the iteration budget's limit
        return z[:a.n_x], float(np.sum(z[a.n_x:])), int(st.get("iter_count", 0)), status, lam

    def _projected(self, a: _Assembled, x0: np.ndarray, rho: float, stop_below: float
                   ) -> np.ndarray | None:
        """A point where every row holds within `stop_below`, found from a near start x0 by at
        most `gauss_newton_steps` Levenberg-Marquardt steps on the rows, or None when they do
        not get there (ipopt then runs from x0, as without them). Each step: the minimum-norm
        correction of the equality rows and of the violated inequality rows (aimed just
        inside), the inequality rows within 1e-3 of their bound kept to first order, the fixed
        variables held; damped by min(1e-2, 1e-2 |residual|); halved until the rows' total or
        largest violation decreases; clipped to the bounds. Given up when neither decreases,
        or the largest violation has not halved in 3 steps; not tried when a free variable
        holds a unit quaternion (the steps know only the rows).

        Why: a motion between solved keyframes started on the straight line between them
        misses by 2e-5 to 6e-4 on `bench_komo.py`, and ipopt's run there is set-up and 1-2
        iterations (7-12 ms); these steps get there in 1-2 (3-6 ms). The verdict is taken on
        the real rows at the point, as for every run (`_verdict`); an infeasible verdict
        always comes from ipopt. Not from far starts: measured on the keyframe NLP (11 of 12
        seeds in 11-15 steps, median 24 -> 12 ms) the points hug the joint bounds and rows
        that ipopt's pull keeps clear of, and on Lab 1 the active set then added two pairs and
        a second NLP (CPU 1.1 -> 1.2-1.6 s)."""
        root = a.root or a
        jac = root.solver.get_function("nlp_jac_g") if root.spec and root.spec[1] == "ipopt" else None
        steps = self.options.gauss_newton_steps
        if jac is None or steps <= 0:
            return None
        lo, up = a.lbx[:a.n_x], a.ubx[:a.n_x]
        free = lo < up
        if any(free[o + sl.start:o + sl.stop].any() for v, o in zip(a.variables, a.offsets)
               for sl in _quat_slices(v)):
            return None
        g_row = g_rows_of(a)
        p = a.p_dm(x0, rho)

        def point(y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
            y = np.clip(y, lo, up)
            hy = a.rows(y)
            return y, hy, np.where(a.kinds, np.abs(hy), np.maximum(hy, 0.0))

        x, h, viol = point(np.array(x0, dtype=float))
        total, worst, best, since = float(viol.sum()), float(viol.max(initial=0.0)), np.inf, 0
        for k in range(steps + 1):
            if not np.isfinite(total):
                return None
            if worst <= stop_below:
                return x
            since = 0 if worst <= 0.5 * best else since + 1
            best = min(best, worst)
            if since >= 3 or k == steps:
                return None
            V = np.flatnonzero(a.kinds | (h > -1e-3))
            J = ca.DM(jac(elastic_point(a, x), p)[1][g_row[V].tolist(), :a.n_x]).full()
            J[:, ~free] = 0.0
            hv = h[V]
            r = np.where(a.kinds[V], -hv, np.where(hv > 0.0, -stop_below * 1e-2 - hv, 0.0))
            damp = max(min(1e-2, 1e-2 * float(np.abs(r).max(initial=0.0))), 1e-12)
            try:
                d = J.T @ np.linalg.solve(J @ J.T + damp * np.eye(r.size), r)
            except np.linalg.LinAlgError:
                return None
            t = 1.0
            while True:
                y, hy, vy = point(x + t * d)
                better = float(vy.sum()) < total or float(vy.max(initial=0.0)) < worst
                if better or t < 0.06:
                    break
                t *= 0.5
            if not better:
                return None
            x, h, viol = y, hy, vy
            total, worst = float(viol.sum()), float(viol.max(initial=0.0))
        return None

    @staticmethod
    def _duals(a: _Assembled, lam: _Multipliers | None) -> Duals | None:
        """The multipliers of one ipopt run (`_run`) per factor and variable (`g_rows_of`; the
        unit-quaternion rows follow in the order of the variables)."""
        if lam is None:
            return None
        lam_g, lam_x, x0, rho = lam.lam_g, lam.lam_x[:a.n_x], lam.x0, lam.rho
        if not (np.all(np.isfinite(lam_g)) and np.all(np.isfinite(lam_x))):
            return None
        lam_h = lam_g[g_rows_of(a)]
        rows = {r: lam_h[i0:i1].copy() for r, i0, i1 in a.factor_rows}
        quats, q = {}, a.n_ineq + a.n_eq
        for v in a.variables:
            k = len(_quat_slices(v))
            quats[v] = lam_g[q:q + k].copy()
            q += k
        bounds = {v: lam_x[off:off + v.dim].copy() for v, off in zip(a.variables, a.offsets)}
        start = {v: np.asarray(x0[off:off + v.dim], float).copy() for v, off in zip(a.variables, a.offsets)}
        return Duals(rows, quats, bounds, start, float(rho))

    def _verdict(self, a: _Assembled, x: np.ndarray) -> tuple[dict, dict[FactorRef, float], float]:
        x = x.copy()
        for v, off in zip(a.variables, a.offsets):
            _unit_quaternions(v, x[off:off + v.dim])        # a view: normalised in place
        h = a.rows(x)
        viol = np.where(a.kinds, np.abs(h), np.maximum(h, 0.0))
        viol = np.where(np.isnan(viol), np.inf, viol)
        per = {r: float(viol[i0:i1].max()) if i1 > i0 else 0.0 for r, i0, i1 in a.factor_rows}
        values = {v: x[off:off + v.dim].copy() for v, off in zip(a.variables, a.offsets)}
        return values, per, max(per.values(), default=0.0)

    def exact_assembly(self, graph: GraphNLP) -> _Assembled:
        """`graph`'s NLP with the forward-kinematics rows' second derivatives in ipopt's
        Hessian whatever `kinematic_curvature` says (the second pass of "auto"; what
        `gnppdsl.nlp.certificate` reads its Hessian from), assembled on first use and cached
        like the other."""
        self._exact_pass = True
        try:
            return self.assemble(graph)
        finally:
            self._exact_pass = False

    def solve(self, graph: GraphNLP, warm_start: Mapping[VarInstance, np.ndarray] | None = None,
              initial_guess: Mapping[VarInstance, np.ndarray] | None = None,
              seed: int = 0, first_attempt: int = 0) -> FeasibilityResult | None:
        """Decide Feas(graph) (Definition 4.3) and return the convergence point.

        `first_attempt` k > 0 runs only the random restarts k..`restarts` (the starts of an
        earlier call with restarts=0 are not repeated): how a verdict found from one start is
        confirmed later. None when no attempt is left.

        With kinematic_curvature "auto", each start is run (and polished) with the forward-
        kinematics rows linearised in the Hessian; when that does not end feasible, the same
        start is run again with the exact Hessian before the next start. So no verdict, and
        no conflict learnt from it, rests on linearised runs alone: an infeasible verdict has
        had every start with the exact Hessian, as with kinematic_curvature true. Why: the
        Gauss-Newton model is faster where it converges (bench_komo keyframe NLP) but stalls
        on some of Lab 3's handover keyframes that the exact model solves. After
        `trial_patience` solves in a row that needed the fallback, the solvers sharing
        `trials` (one loop) run the exact Hessian only: on the Lab's infeasible NLPs a
        linearised run stalls after 75-185 iterations where the exact one ends in 21-56.

        `iteration_budget` > 0 bounds the iterations of all runs together (`SolverOptions`):
        no run starts once it is spent, and a failed linearised run then stands as the result
        (only for NLPs whose infeasible result is never a verdict)."""
        t0 = time.perf_counter()
        tol = self.options.tolerance
        if graph.n_factors == 0:
            return FeasibilityResult(True, {}, {}, 0.0, 0.0, 0.0, 0, "no factors", 0)
        auto = self.options.kinematic_curvature == "auto"
        a = self.exact_assembly(graph) if auto and self.trials.given_up else self.assemble(graph)
        fallback = auto and a.linearised
        exact = None                     # the exact twin of a, once a start needed it
        trials = fallback                # this solve tries linearised runs (trial_patience)
        best = None                      # (values, per, worst, slack, status, x, lam)
        iters, starts = 0, 0
        tried = False                    # the current best is polished, or its polish ran
        budget = self.options.iteration_budget
        left = lambda: {"limit": budget - iters} if budget else {}      # noqa: E731  (`_run`)
        spent = lambda: bool(budget) and iters >= budget     # noqa: E731

        def capped(trial: bool) -> dict:
            """`left()`, and a linearised run of "auto" at most `trial_iterations`."""
            cap = left()
            if trial and self.options.trial_iterations > 0:
                cap = {"limit": min(cap.get("limit", self.options.trial_iterations),
                                    self.options.trial_iterations)}
            return cap
        k, last, undefined_left = first_attempt - 1, max(0, self.options.restarts), UNDEFINED_RESTARTS
        while k < last:
            k += 1
            x0 = self._start(a, graph, warm_start, initial_guess, seed, k)
            for b in (a, None) if fallback else (a,):
                trial = fallback and b is a      # a linearised run of "auto": counts if feasible
                if b is None:
                    if exact is None:
                        exact = self.exact_assembly(graph)
                    b = exact
                if best is not None and spent():
                    break                    # the iteration budget is spent
                # (not the exact twin's run: the near-start steps do not read the Hessian, and
                # from the same start they already failed)
                self._project = b is a
                try:
                    x, slack, it, status, lam = self._run(b, x0, self.options.regularisation, **capped(trial))
                finally:
                    self._project = True
                iters += it
                starts += 1
                values, per, worst = self._verdict(b, x)
                mine = (values, per, worst, slack, status, x, lam), False, False
                if tol < worst <= self.options.polish_below and self.options.polish and not spent():
                    x, slack, it, status, lam = self._run(b, x, self.options.regularisation * 1e-4, lam,
                                                          **capped(trial))
                    iters += it
                    values, per, worst = self._verdict(b, x)
                    # not better: the same unpolished point, whose polish must not run again
                    mine = ((values, per, worst, slack, status, x, lam), True, True) \
                        if worst <= mine[0][2] else (mine[0], False, True)
                if trial and mine[0][2] > tol and not spent():
                    continue                 # not a verdict: the exact run from x0 decides
                if best is None or mine[0][2] < best[2] or (mine[1] and mine[0][2] <= best[2]):
                    best, _, tried = mine
                if best[2] <= tol:
                    break
            if best is not None and (best[2] <= tol or spent()):
                break
            if k == last and best is not None and not math.isfinite(best[2]) and undefined_left > 0:
                last += 1                # every run so far ended where a row is undefined
                undefined_left -= 1
        if best is None:
            return None
        if tol < best[2] < self.options.final_polish_below and self.options.polish and not tried \
                and not spent():
            # The pull towards the start can outweigh the L1 penalty of a badly scaled row
            # (gradient below rho): re-solve the best point with a much weaker pull before
            # believing an infeasible verdict. Not when that polish already ran from it (the
            # same point, multipliers and pull: the same run; measured on work1's repair, a
            # motion's 150-iteration polish, 2.7 s, ran twice).
            b = exact if exact is not None else a
            x, slack, it, status, lam = self._run(b, best[5], self.options.regularisation * 1e-4, best[6],
                                                  **left())
            iters += it
            values, per, worst = self._verdict(b, x)
            # on a tie the polished point: the same violation, and its multipliers show the
            # contradiction without the pull's forces (`gnppdsl.nlp.certificate`)
            if worst <= best[2]:
                best = (values, per, worst, slack, status, x, lam)
        values, per, worst, slack, status, _, lam = best
        if trials:
            fell_back = exact is not None
            self.curvature_fallbacks += fell_back
            self.curvature_rescues += fell_back and worst <= tol
            t = self.trials
            t.failed_in_a_row = t.failed_in_a_row + 1 if fell_back else 0
            patience = self.options.trial_patience
            t.given_up = t.given_up or (patience > 0 and t.failed_in_a_row >= patience)
        _raise_on_nan(graph, per)
        dt = time.perf_counter() - t0
        self.solve_time += dt
        duals = self._duals(a, lam) if worst > tol else None
        # activity: per factor, the largest |multiplier| of its elastic rows
        activity = {r: float(np.abs(m).max()) if m.size else 0.0 for r, m in duals.rows.items()} \
            if duals is not None else {}
        return FeasibilityResult(worst <= tol, values, per, worst, slack, dt, iters, status,
                                 starts, activity, duals)


def solve_feasibility(graph: GraphNLP, warm_start: Mapping[VarInstance, np.ndarray] | None = None,
                      tolerance: float = 1e-6, seed: int = 0, geometry: Geometry | None = None,
                      solver: FeasibilitySolver | None = None, **options) -> FeasibilityResult:
    """One-shot convenience wrapper; loops should keep one `FeasibilitySolver` (caches)."""
    if solver is None:
        solver = FeasibilitySolver(geometry, SolverOptions(tolerance=tolerance, **options))
    return solver.solve(graph, warm_start=warm_start, seed=seed)
