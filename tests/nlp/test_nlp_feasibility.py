"""Elastic feasibility: verdicts, solutions re-checked independently, starts, bounds, MX."""
from __future__ import annotations

import math
import time

import casadi as ca
import numpy as np
import pytest

from gnppdsl.compile.factors import VarInstance
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Vec
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions, solve_feasibility
from gnppdsl.nlp.geometry_protocol import Body
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import C, DiscGeometry, chain, discs, factor, pose

TOL = 1e-6


def confirm_infeasible(graph, starts=8, geometry=None):
    """Multi-start re-solve: no start of a fresh solver finds a feasible point, and neither
    does a different NLP method (SQP with qrqp) from a few more starts. Every candidate point
    is judged by the independent numpy checker, not by the solver's own verdict."""
    for plugin, n in (("ipopt", starts), ("sqpmethod", 3)):
        s = FeasibilitySolver(geometry, SolverOptions(restarts=0, noise=1.0, plugin=plugin))
        for k in range(n):
            r = s.solve(graph, seed=100 + k)
            if r.feasible or max_violation(graph.factor_instances, r.values, geometry)[0] <= TOL:
                return False
    return True


@pytest.mark.parametrize("n,feasible", [(1, True), (2, True), (3, False)])
def test_discs_verdict_and_independent_recheck(n, feasible):
    vs, fs = discs(n)
    g = GraphNLP(fs)
    t = time.perf_counter()
    r = solve_feasibility(g, tolerance=TOL)
    print(f"discs({n}): {r.feasible} in {1e3 * (time.perf_counter() - t):.1f} ms, "
          f"{r.iterations} iterations, {r.starts} start(s)")
    assert r.feasible is feasible
    worst, _ = max_violation(fs, r.values)          # independent numpy evaluation
    assert (worst <= TOL) is feasible
    assert r.max_violation == pytest.approx(worst, abs=1e-9)
    if not feasible:
        assert r.violated(TOL) and confirm_infeasible(g)
        # three unit discs in a 1.6 x 1.6 box (optimum packing of 3 points in a square of side
        # L has min distance about 1.035 L = 1.66): at the convergence point some pair is
        # closer than 2 or some centre is outside the box (where the elastic optimum puts
        # the slack is its choice), checked by geometry
        pos = [r.values[v][:2] for v in vs]
        closest = min(np.linalg.norm(pos[i] - pos[j]) for i in range(3) for j in range(i))
        outside = max(np.abs(p).max() for p in pos) - 0.8
        assert closest < 2 - TOL or outside > TOL


def test_chain_feasible_without_conflict_and_values_cover_all_variables():
    vs, fs = chain(10, conflict_at=None)
    g = GraphNLP(fs)
    r = solve_feasibility(g)
    assert r.feasible and set(r.values) == set(vs)
    assert max_violation(fs, r.values)[0] <= TOL
    assert r.values[vs[0]] == pytest.approx([-3.0, 0.0, 0.0], abs=1e-6)


def test_warm_start_and_initial_guess():
    vs, fs = chain(10, conflict_at=None)
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    cold = s.solve(g)
    warm = s.solve(g, warm_start=cold.values)
    print(f"chain(10): cold {cold.iterations} it {1e3 * cold.solve_time:.1f} ms, "
          f"warm {warm.iterations} it {1e3 * warm.solve_time:.1f} ms")
    assert warm.feasible and max_violation(fs, warm.values)[0] <= TOL
    # a solution used as the start stays (almost) where it is: the pull is towards the start
    assert max(np.abs(warm.values[v] - cold.values[v]).max() for v in vs) < 1e-3
    g.initial_guess = {v: np.array([5.0, 1.0, 0.0]) for v in vs[1:]}
    r = s.solve(g)
    assert r.feasible and r.values[vs[5]][1] == pytest.approx(0.0, abs=1e-6)


def test_restarts_alternate_the_initial_guess_and_random_points():
    """Restart 1 starts from the graph's initial guess moved by `restart_noise`, not from the
    warm start (whose local minimum the first run may have found); restart 2 from a random
    point; quaternions stay unit. Checked on the starts handed to ipopt."""
    vs, fs = chain(4, conflict_at=None)
    P = VarInstance("pose", ("o",), 0, "SE3", 7)
    fz = factor("t.up", [P], [Constraint(Index(Slot(0), Num(2)), ">=", Num(0.0))], 0)
    g = GraphNLP([*fs, fz])
    guess = {v: np.array([5.0, 1.0, 0.0]) for v in vs}
    guess[P] = np.array([0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0])
    g.initial_guess = guess
    warm = {v: np.array([-7.0, -2.0, 0.5]) for v in vs}
    s = FeasibilitySolver(options=SolverOptions(restart_noise=0.3))
    a = s.assemble(g)
    starts = [s._start(a, g, warm, None, seed=4, attempt=k) for k in range(3)]
    for v, off in zip(a.variables, a.offsets):
        x0, x1, x2 = (st[off:off + v.dim] for st in starts)
        if v in warm:
            assert np.allclose(x0, warm[v])
        assert np.abs(x1 - guess[v]).max() < 5 * 0.3 and not np.allclose(x1, guess[v])
        assert not np.allclose(x2, x1)
        if v in warm:                   # a random point, far from the guess and the warm start
            assert np.abs(x2 - guess[v]).max() > 5 * 0.3 and np.abs(x2 - warm[v]).max() > 1.0
        if v is P:
            assert np.linalg.norm(x1[3:]) == pytest.approx(1.0)


def test_se3_unit_quaternion_and_joint_bounds():
    P = VarInstance("pose", ("o",), 0, "SE3", 7)
    J = VarInstance("q", ("r",), 0, "joints", 2, lower=(-0.5, 0.2), upper=(0.5, 0.4))
    # z axis of the pose must point along world x; the joints must sum to 1 (infeasible with
    # the bounds: at most 0.9) -> elastic optimum keeps the joints at their upper bounds
    fz = factor("t.axis", [P], [Constraint(C("axis_se3", Slot(0), Num(2)), "==",
                                           Vec((Num(1.0), Num(0.0), Num(0.0))))], 0)
    fj = factor("t.sum", [J], [Constraint(C("sum", Slot(0)), ">=", Num(1.0))], 0)
    g = GraphNLP([fz, fj])
    r = solve_feasibility(g)
    assert not r.feasible
    assert np.linalg.norm(r.values[P][3:]) == pytest.approx(1.0, abs=1e-9)
    assert r.values[J] == pytest.approx([0.5, 0.4], abs=1e-6)
    assert r.violated(TOL) == [g.factor_refs[1]]
    sub = g.subgraph(factors=[0])
    r2 = solve_feasibility(sub)
    assert r2.feasible and max_violation([fz], r2.values)[0] <= TOL


def test_tolerance_is_configurable():
    v = pose("b", 0)
    f = factor("t.near", [v], [Constraint(C("sqnorm", C("pos_se2", Slot(0))), "<=", Num(-1e-5))], 0)
    g = GraphNLP([f])
    assert not solve_feasibility(g, tolerance=1e-6).feasible
    assert solve_feasibility(g, tolerance=1e-4).feasible


class _Dist2(ca.Callback):
    """Planar distance between disc centres minus radii as an opaque MX node with a Jacobian,
    the way gnppdsl.geometry wraps coal (test stand-in)."""

    def __init__(self, name, radius):
        ca.Callback.__init__(self)
        self.radius = radius
        self.construct(name, {})

    def get_n_in(self):
        return 2

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(3, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(1, 1)

    def eval(self, arg):
        a, b = np.asarray(arg[0]).ravel(), np.asarray(arg[1]).ravel()
        return [float(np.linalg.norm(a[:2] - b[:2])) - self.radius]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, opts):
        a, b, out = ca.MX.sym("a", 3), ca.MX.sym("b", 3), ca.MX.sym("out", 1, 1)
        d = a[:2] - b[:2]
        n = d / ca.sqrt(ca.sumsqr(d) + 1e-18)
        return ca.Function(name, [a, b, out], [ca.horzcat(n.T, 0), ca.horzcat(-n.T, 0)],
                           inames, onames, opts)


class CallbackGeometry(DiscGeometry):
    def __init__(self, radii):
        super().__init__(radii)
        self._cbs = {}

    def needs_mx(self, primitive):
        return primitive == "sdist2"

    def sdist2(self, a, pa, b, pb):
        key = (str(a), str(b))
        if key not in self._cbs:
            self._cbs[key] = _Dist2(f"d_{len(self._cbs)}", self._r(a) + self._r(b))
        return self._cbs[key](pa, pb)


@pytest.mark.parametrize("n,feasible", [(2, True), (3, False)])
def test_mx_callback_geometry_in_assembly(n, feasible):
    geo = CallbackGeometry({f"b{i}": 1.0 for i in range(n)})
    vs = [pose(f"b{i}", 0) for i in range(n)]
    from nlp_toys import in_box
    fs = [in_box(v, 0.8, 0) for v in vs]
    fs += [factor("toy.sd", [vs[i], vs[j]], [Constraint(
        C("sdist2", Obj(f"b{i}"), Slot(0), Obj(f"b{j}"), Slot(1)), ">=", Num(0.0))], 0)
        for i in range(n) for j in range(i + 1, n)]
    s = FeasibilitySolver(geo)
    r = s.solve(GraphNLP(fs))
    assert s.compiler.compile(fs[-1])[0].symbolic == "MX"
    assert r.feasible is feasible
    assert (max_violation(fs, r.values, geo)[0] <= TOL) is feasible


def test_sqpmethod_plugin_gives_same_verdicts():
    s = FeasibilitySolver(options=SolverOptions(plugin="sqpmethod"))
    for n, feasible in [(2, True), (3, False)]:
        vs, fs = discs(n)
        r = s.solve(GraphNLP(fs))
        assert r.feasible is feasible
        assert (max_violation(fs, r.values)[0] <= TOL) is feasible


def test_trajectory_start_interpolates_between_mode_switches():
    from gnppdsl.nlp.feasibility import interpolated_trajectory
    q0 = VarInstance("q", ("r",), 2, "joints", 2)
    q1 = VarInstance("q", ("r",), 3, "joints", 2)
    path = VarInstance("path", ("r",), 2, "joints", 8, waypoints=4)
    got = interpolated_trajectory(path, {q0: np.array([0.0, 3.0]), q1: np.array([3.0, 0.0])})
    assert got == pytest.approx([0, 3, 1, 2, 2, 1, 3, 0])
    assert interpolated_trajectory(path, {q0: np.array([0.0, 3.0])}) is None
    # used as the start: a smoothness factor alone is already satisfied there, and the
    # solver keeps the trajectory (regulariser pulls towards the start)
    smooth = factor("t.smooth", [path], [Constraint(C("norm", C("sub", C("waypoint", Slot(0), Num(k + 1)),
                                                                  C("waypoint", Slot(0), Num(k)))),
                                                    "<=", Num(1.5)) for k in range(3)], 2)
    r = FeasibilitySolver().solve(GraphNLP([smooth]), warm_start={q0: np.array([0.0, 3.0]),
                                                                  q1: np.array([3.0, 0.0])})
    assert r.feasible and r.values[path] == pytest.approx(got, abs=1e-3)


def test_badly_scaled_row_far_from_start_is_not_a_false_conflict():
    """1e-3 * x == 1e-2 needs x = 10: the default pull towards the start (gradient up to rho =
    1e-2) outweighs this row's L1 penalty; the polish re-solve must still find it feasible."""
    v = pose("b", 0)
    f = factor("t.scaled", [v], [Constraint(C("mul", Num(1e-3), Index(Slot(0), Num(0))), "==",
                                            Num(1e-2))], 0)
    r = FeasibilitySolver(options=SolverOptions(restarts=0)).solve(GraphNLP([f]))
    assert r.feasible and r.values[v][0] == pytest.approx(10.0, abs=1e-3)
    r = FeasibilitySolver(options=SolverOptions(restarts=0, polish=False)).solve(GraphNLP([f]))
    assert not r.feasible        # documents why the polish step exists
    # a one-start verdict that is confirmed later (the solve loop's plan graph) skips the final
    # polish of a far-off point: one ipopt run; the confirmation's solve polishes
    s = FeasibilitySolver(options=SolverOptions(restarts=0, final_polish_below=1e-3))
    assert not s.solve(GraphNLP([f])).feasible and s.solves == 1
    s.options.final_polish_below = 1e-1       # the start ends at 1e-2
    assert s.solve(GraphNLP([f])).feasible and s.solves == 3


def test_assembled_nlp_cache_is_bounded():
    s = FeasibilitySolver(options=SolverOptions(cache_size=2))
    vs, fs = chain(4, conflict_at=None)
    g = GraphNLP(fs)
    for k in range(4):
        assert s.solve(g.time_slice(k, k + 1)).feasible
    assert len(s._nlps) == 2


@pytest.mark.parametrize("n,feasible", [(2, True), (3, False)])
def test_early_stop_monitor_same_verdicts(n, feasible):
    """The iteration monitor (stop when the real rows hold / on stalls) changes run lengths,
    never verdicts; a stopped feasible run returns a point the numpy checker accepts."""
    vs, fs = discs(n)
    g = GraphNLP(fs)
    for early in (True, False):
        s = FeasibilitySolver(options=SolverOptions(early_stop=early, stall_iterations=10))
        r = s.solve(g)
        assert r.feasible is feasible
        assert (max_violation(fs, r.values)[0] <= TOL) is feasible
        if early and feasible:
            assert r.status == "User_Requested_Stop"


def test_limited_memory_hessian_same_verdicts():
    for n, feasible in [(2, True), (3, False)]:
        vs, fs = discs(n)
        r = FeasibilitySolver(options=SolverOptions(hessian="limited-memory")).solve(GraphNLP(fs))
        assert r.feasible is feasible
        assert (max_violation(fs, r.values)[0] <= TOL) is feasible


def test_a_near_feasible_start_is_polished_before_random_restarts():
    """1e-4 * x == 1e-4 * 5 (x = 5): the first start stalls with a small violation (the pull
    towards the start outweighs the row's L1 penalty). The polish runs right after that start,
    so the verdict is feasible after one start instead of after every random restart."""
    v = pose("b", 0)
    f = factor("t.scaled", [v], [Constraint(C("mul", Num(1e-4), Index(Slot(0), Num(0))), "==",
                                            Num(5e-4))], 0)
    first = FeasibilitySolver(options=SolverOptions(restarts=0, polish=False)).solve(GraphNLP([f]))
    assert not first.feasible and first.max_violation <= 1e-3     # near-feasible stall
    r = FeasibilitySolver(options=SolverOptions(restarts=3)).solve(GraphNLP([f]))
    assert r.feasible and r.starts == 1 and r.values[v][0] == pytest.approx(5.0, abs=1e-3)
    late = FeasibilitySolver(options=SolverOptions(restarts=3, polish_below=0.0)).solve(GraphNLP([f]))
    assert late.starts == 4          # without the early polish every restart runs first


def test_deadline_stops_a_cached_nlp_at_its_next_iteration():
    """ipopt's max_wall_time is fixed when an NLP is assembled; a cached NLP solved again later
    must still stop at the solver's deadline (the iteration monitor checks it), and say so in
    its status so the loop treats it as a time-out, not a verdict."""
    vs, fs = discs(3)                    # infeasible: runs until the stall detection
    g = GraphNLP(fs)
    s = FeasibilitySolver(None, SolverOptions(restarts=0, early_stop=True, stall_iterations=400,
                                              time_limit=1e6, polish=False))
    first = s.solve(g)
    assert not first.feasible and first.iterations > 5
    s.deadline = time.perf_counter()     # already passed; the cached NLP keeps time_limit=1e6
    late = s.solve(g)
    assert late.iterations <= 1 and "walltime" in late.status.lower()
    s.deadline = math.inf
    again = s.solve(g)
    assert again.iterations == first.iterations and "walltime" not in again.status.lower()
