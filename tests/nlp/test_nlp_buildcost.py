"""Per-waypoint reuse of derivatives (`lowering.row_groups`, `BodyCompiler._grouped_derivative`):
the Jacobian and Hessian of a body assembled from one differentiated representative per group of
waypoint-identical constraints must equal, value for value and in sparsity, the straightforward
`ca.jacobian` / `ca.hessian` of the whole body (`direct_jacobian`, `direct_hessian`), on random
inputs; and a whole graph-NLP's ipopt derivatives must not change."""
from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

from gnppdsl.compile.factors import VarInstance
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Str, Vec
from gnppdsl.nlp.body_compiler import BodyCompiler, direct_hessian, direct_jacobian
from gnppdsl.nlp.lowering import SlotSignature, abstract_constraint, lift_constants
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import C, DiscGeometry, factor

GEOM = DiscGeometry({"a": 0.3, "b": 0.2, "arm2/l1": 0.1})
WP = 6


def var(name, space, dim, waypoints=0):
    return VarInstance(name, (), 0, space, dim, waypoints=waypoints)


A = var("pathA", "joints", 2 * WP, WP)      # two trajectories of a 2-joint arm
B = var("pathB", "joints", 2 * WP, WP)
P = var("P", "SE3", 7)
S = var("s", "R", 1)


def base(x):
    return Vec((Num(x), Num(0.0), Num(0.0), Num(0.0), Num(0.0), Num(0.0), Num(1.0)))


def fk(q, bx):
    return C("fk", Obj("arm2"), q, Str("tip"), base(bx))


def traj_body():
    """A `forall k` body over two trajectories, a pose and a scalar: FK + distance rows,
    velocity rows on path[k], path[k+1], a two-trajectory distance, a whole-slot use of the
    scalar, a whole-trajectory use overlapping a waypoint of the same slot (cells summed), a
    vector row and a one-off row with a negative waypoint index."""
    a, b, p, s = Slot(0), Slot(1), Slot(2), Slot(3)
    body = []
    for k in range(1, WP - 1):
        wa, wb = C("waypoint", a, Num(k)), Index(b, Num(k))
        body += [
            Constraint(C("sdist", C("link", Obj("arm2"), Str("l1")), fk(wa, -0.4), Obj("a"),
                         C("compose_se3", base(0.1), p)), ">=", Num(0.01 * k)),
            Constraint(C("sqnorm", C("sub", C("waypoint", a, C("add", Num(k), Num(1))), wa)),
                       "<=", Num(0.09)),
            Constraint(C("sdist", C("link", Obj("arm2"), Str("l1")), fk(wa, -0.4),
                         C("link", Obj("arm2"), Str("l1")), fk(wb, 0.4)), ">=", Num(0.05)),
            Constraint(C("mul", s, C("sqnorm", wb)), "<=", Num(1.0 + k)),
            Constraint(C("add", C("sqnorm", a), C("sqnorm", C("sin", wa))), "<=", Num(10.0)),
            Constraint(C("sub", wa, wb), "<=", Vec((Num(1.0), Num(2.0)))),
        ]
    body.append(Constraint(C("waypoint", a, Num(-1)), "==", C("waypoint", b, Num(0))))
    return body


def traj_factor():
    return factor("toy.traj", [A, B, P, S], traj_body(), 0, ("traj",))



def test_waypoint_copies_form_one_group_each():
    f = traj_factor()
    cb, _ = BodyCompiler(GEOM).compile(f)
    sizes = sorted(len(g.members) for g in cb.groups)
    # six per-k constraint forms with WP - 2 copies each, plus the one-off row
    assert sizes == [1] + [WP - 2] * 6
    # members of a group read their own waypoints: the velocity group reads (A, k), (A, k+1)
    key_body, _ = lift_constants(f.body)
    sigs = tuple(SlotSignature.of(v) for v in f.variables)
    _, pts, whole, _ = abstract_constraint(key_body[1], sigs)
    assert pts == ((0, 2), (0, 1)) and whole == ()
    _, pts, whole, _ = abstract_constraint(key_body[4], sigs)     # sqnorm(A) + sin(A[1])
    assert pts == ((0, 1),) and whole == (0,)
    _, pts, _, _ = abstract_constraint(key_body[-1], sigs)        # A[-1] == B[0]
    assert pts == ((0, WP - 1), (1, 0))


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_grouped_derivatives_equal_direct_ones(seed):
    rng = np.random.default_rng(seed)
    comp = BodyCompiler(GEOM)
    cb, params = comp.compile(traj_factor())
    jac, hess = comp.jacobian(cb), comp.hessian(cb)
    jd, hd = direct_jacobian(cb), direct_hessian(cb)
    ji = comp._grouped_derivative(cb, False, inline=True)
    hi = comp._grouped_derivative(cb, True, inline=True)
    assert jac.sparsity_out(0) == jd.sparsity_out(0) == ji.sparsity_out(0)
    assert hess.sparsity_out(0) == hd.sparsity_out(0) == hi.sparsity_out(0)
    xs = [rng.normal(0.0, 0.7, cb.function.size1_in(i)) for i in range(4)]
    lam = rng.normal(0.0, 1.0, cb.n_rows)
    Jd = np.asarray(jd(*xs, params).full())
    Hd = np.asarray(hd(*xs, params, lam).full())
    assert np.count_nonzero(Hd) > 100 and np.count_nonzero(Jd) > 100
    for J in (jac, ji):
        assert np.allclose(np.asarray(J(*xs, params).full()), Jd, rtol=1e-12, atol=1e-12)
    for H in (hess, hi):
        assert np.allclose(np.asarray(H(*xs, params, lam).full()), Hd, rtol=1e-12, atol=1e-12)
    # and the Hessian is the derivative of the Jacobian (independent of both assemblies)
    x = [ca.SX.sym(f"x{i}", cb.function.size1_in(i)) for i in range(4)]
    X = ca.vertcat(*x)
    g = ca.mtimes(ca.DM(lam).T, ca.jacobian(cb.function(*x, params), X)).T
    Hj = ca.Function("hj", x, [ca.jacobian(g, X)])
    assert np.allclose(np.asarray(Hj(*xs).full()), Hd, rtol=1e-9, atol=1e-9)


def test_representatives_are_shared_across_bodies():
    comp = BodyCompiler(GEOM)
    cb1, _ = comp.compile(traj_factor())
    comp.hessian(cb1)
    n = len(comp._reps)
    body2 = traj_body()[:12]                 # the first two waypoints' rows of the same forms
    cb2, _ = comp.compile(factor("toy.traj2", [A, B, P, S], body2, 0, ("traj",)))
    assert cb2 is not cb1
    comp.hessian(cb2)
    assert len(comp._reps) == n              # nothing new to differentiate


def test_body_without_repeats_is_differentiated_directly():
    body = [Constraint(C("sqnorm", C("waypoint", Slot(0), Num(1))), "<=", Num(1.0)),
            Constraint(C("sum", C("waypoint", Slot(0), Num(2))), ">=", Num(0.0))]
    comp = BodyCompiler(GEOM)
    cb, p = comp.compile(factor("toy.two", [A], body, 0))
    assert all(len(g.members) == 1 for g in cb.groups)
    comp.hessian(cb)
    assert comp._reps == {}


def test_graph_nlp_derivatives_unchanged():
    """The assembled ipopt Jacobian and Hessian (two instances of the body, mapped) agree with
    an assembly from whole-body derivatives."""

    class Direct(BodyCompiler):
        def jacobian(self, cb):
            return direct_jacobian(cb)

        def hessian(self, cb):
            return direct_hessian(cb)

    A2 = VarInstance("pathA", (), 1, "joints", 2 * WP, waypoints=WP)
    B2 = VarInstance("pathB", (), 1, "joints", 2 * WP, waypoints=WP)
    fs = [traj_factor(), factor("toy.traj", [A2, B2, P, S], traj_body(), 1, ("traj",))]
    g = GraphNLP(fs)
    rng = np.random.default_rng(3)
    out = []
    for comp in (BodyCompiler(GEOM), Direct(GEOM)):
        s = FeasibilitySolver(options=SolverOptions(restarts=0, assembly="MX"), compiler=comp)
        a = s.assemble(g)
        if not out:
            z = rng.normal(0.0, 0.5, a.lbx.size)
            p = np.concatenate([z[:a.n_x], a.params, [0.01]])
            lam = rng.normal(0.0, 1.0, a.lbg.size)
        jac = a.solver.get_function("nlp_jac_g")(z, p)[1]
        hess = a.solver.get_function("nlp_hess_l")(z, p, 1.0, lam)
        out.append((jac, hess))
    (j1, h1), (j2, h2) = out
    assert j1.sparsity() == j2.sparsity() and h1.sparsity() == h2.sparsity()
    assert np.allclose(j1.full(), j2.full(), rtol=1e-12, atol=1e-12)
    assert np.allclose(h1.full(), h2.full(), rtol=1e-12, atol=1e-12)


def test_blocks_of_one_waypoint_are_differentiated_together():
    """Consecutive constraints reading the same waypoints (one `forall k` step) form one
    block; grouped derivatives still equal the whole-body ones."""
    a, b = Slot(0), Slot(1)
    body = []
    for k in range(1, WP - 1):
        wa, wb = C("waypoint", a, Num(k)), C("waypoint", b, Num(k))
        body += [Constraint(C("sdist", C("link", Obj("arm2"), Str("l1")), fk(wa, -0.4),
                              C("link", Obj("arm2"), Str("l1")), fk(wb, 0.4)), ">=", Num(0.05)),
                 Constraint(C("sqnorm", C("sub", wa, wb)), "<=", Num(4.0)),
                 Constraint(C("sub", wa, wb), ">=", Vec((Num(-1.0), Num(-2.0))))]
    comp = BodyCompiler(GEOM)
    cb, params = comp.compile(factor("toy.block", [A, B], body, 0, ("traj",)))
    assert [(len(g.members), g.n_rows) for g in cb.groups] == [(WP - 2, 4)]
    assert [m.row0 for m in cb.groups[0].members] == [4 * i for i in range(WP - 2)]
    rng = np.random.default_rng(7)
    xs = [rng.normal(0.0, 0.7, 2 * WP) for _ in range(2)]
    lam = rng.normal(0.0, 1.0, cb.n_rows)
    for got, ref, extra in ((comp.jacobian(cb), direct_jacobian(cb), ()),
                            (comp.hessian(cb), direct_hessian(cb), (lam,))):
        assert got.sparsity_out(0) == ref.sparsity_out(0)
        assert np.allclose(np.asarray(got(*xs, params, *extra).full()),
                           np.asarray(ref(*xs, params, *extra).full()), rtol=1e-12, atol=1e-12)
