"""`SolverOptions.kinematic_curvature`: with it off, ipopt's Hessian of the Lagrangian leaves out
the second derivatives of every template that uses forward kinematics (`fk`), and nothing else:
the pull's diagonal and the templates without geometry primitives stay.

Checked against the exact Hessian with those templates' multipliers set to zero (the same
Lagrangian without them), and by solving the toy arm problem with it off and re-evaluating
every factor at the returned point with the independent numpy evaluator."""
from __future__ import annotations

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.ir.expr import Constraint, Index, Num, Slot
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import ARM_GEOM, ARM_O, C, arm_hessian, arm_reach_graph, arm_solved_worst, factor, hessian_points

# a factor without geometry primitives whose curvature must stay: (o_x)^2 + (o_y)^2 >= 0.5
EXTRA = factor("toy.ring", [ARM_O], [Constraint(C("add", C("mul", Index(Slot(0), Num(0)), Index(Slot(0), Num(0))),
                                                 C("mul", Index(Slot(0), Num(1)), Index(Slot(0), Num(1)))),
                                               ">=", Num(0.5))], 0)


def _graph() -> GraphNLP:
    return GraphNLP([*arm_reach_graph().factor_instances, EXTRA])


def test_without_kinematic_curvature_the_hessian_is_the_lagrangian_without_fk_rows():
    g = _graph()
    a = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX")).assemble(g)
    g_row = np.empty(a.kinds.size, dtype=np.int64)          # real row -> elastic row of g
    g_row[~a.kinds] = np.arange(a.n_ineq)
    g_row[a.kinds] = a.n_ineq + np.arange(a.n_eq)
    fk_rows = [int(g_row[i]) for ref, i0, i1 in a.factor_rows
               if g.factor(ref).template in ("toy.reach", "toy.clear") for i in range(i0, i1)]
    assert len(fk_rows) == 4                                 # reach: 3 rows, clear: 1
    for z, p, lam in hessian_points(a):
        h_off = arm_hessian(g, z, p, lam, kinematic_curvature=False)
        lam0 = lam.copy()
        lam0[fk_rows] = 0.0
        h_zero = arm_hessian(g, z, p, lam0, kinematic_curvature=True)
        assert np.allclose(h_off, h_zero, rtol=1e-12, atol=1e-12)
        assert not np.allclose(h_off, arm_hessian(g, z, p, lam, kinematic_curvature=True), atol=1e-6)   # it changes something
        # the ring's curvature (on o) is still there: lam of its row moves the Hessian
        ring = [int(g_row[i]) for ref, i0, i1 in a.factor_rows if g.factor(ref).template == "toy.ring"
                for i in range(i0, i1)]
        lam1 = lam.copy()
        lam1[ring] += 1.0
        assert not np.allclose(h_off, arm_hessian(g, z, p, lam1, kinematic_curvature=False), atol=1e-6)


def test_solves_feasible_without_kinematic_curvature():
    assert arm_solved_worst(arm_reach_graph(), kinematic_curvature=False) <= 1e-6


# the setting reaching the solver from a problem file: test_nlp_distance_curvature.py (both settings)


def test_without_kinematic_curvature_unit_quaternion_rows_keep_only_convex_curvature():
    """The unit-quaternion rows (|q|^2 = 1) of an SE3 variable: with kinematic_curvature off
    their Hessian term is 2 max(lam, 0) on the quaternion's diagonal (a negative multiplier
    would make the linearised model indefinite), with it on the exact 2 lam; everything else
    is the same."""
    P = VarInstance("P", (), 0, "SE3", 7)
    held = factor("toy.held", [P], [Constraint(Index(Slot(0), Num(0)), "<=", Num(0.5))], 0)
    g = GraphNLP([*arm_reach_graph().factor_instances, held])
    a = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX")).assemble(g)
    off = next(o for v, o in zip(a.variables, a.offsets) if v == P)
    quat = list(range(off + 3, off + 7))
    q_row = a.lbg.size - 1                      # the one unit-quaternion row, after the factors
    for z, p, lam in hessian_points(a):
        for sign in (-1.0, 1.0):
            lam = lam.copy()
            lam[q_row] = sign * 0.7
            h_off = arm_hessian(g, z, p, lam, kinematic_curvature=False)
            h_on = arm_hessian(g, z, p, lam, kinematic_curvature=True)
            d = np.diag(h_on)[quat] - np.diag(h_off)[quat]
            # exact minus linearised on the quaternion: 2 lam where lam < 0, else nothing
            assert np.allclose(d, 2 * min(sign * 0.7, 0.0), atol=1e-12)
            # the linearised model's quaternion term: 2 max(lam, 0) over the same Hessian at lam = 0
            lam0 = lam.copy()
            lam0[q_row] = 0.0
            h_zero = arm_hessian(g, z, p, lam0, kinematic_curvature=False)
            assert np.allclose(np.diag(h_off)[quat] - np.diag(h_zero)[quat], 2 * max(sign * 0.7, 0.0), atol=1e-12)
            # and nothing else changes
            mask = np.ones_like(h_off, dtype=bool)
            mask[quat, quat] = False
            assert np.allclose(h_off[mask], h_zero[mask], atol=1e-12)
