"""`SolverOptions.kinematic_curvature`: with it off, ipopt's Hessian of the Lagrangian leaves out
the second derivatives of every template that uses forward kinematics (`fk`), and nothing else:
the pull's diagonal and the templates without geometry primitives stay.

Checked against the exact Hessian with those templates' multipliers set to zero (the same
Lagrangian without them), and by solving the toy arm problem with it off and re-evaluating
every factor at the returned point with the independent numpy evaluator."""
from __future__ import annotations

import numpy as np

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
