"""`SolverOptions.kinematic_curvature`: with it off, ipopt's Hessian of the Lagrangian leaves out
the second derivatives of every template that uses forward kinematics (`fk`), and nothing else:
the pull's diagonal and the templates without geometry primitives stay.

Checked against the exact Hessian with those templates' multipliers set to zero (the same
Lagrangian without them), and by solving the toy arm problem with it off and re-evaluating
every factor at the returned point with the independent numpy evaluator."""
from __future__ import annotations

import numpy as np

from gnppdsl.ir.expr import Constraint, Index, Num, Slot
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import ARM_GEOM, ARM_O, C, arm_reach_graph, factor

# a factor without geometry primitives whose curvature must stay: (o_x)^2 + (o_y)^2 >= 0.5
EXTRA = factor("toy.ring", [ARM_O], [Constraint(C("add", C("mul", Index(Slot(0), Num(0)), Index(Slot(0), Num(0))),
                                                 C("mul", Index(Slot(0), Num(1)), Index(Slot(0), Num(1)))),
                                               ">=", Num(0.5))], 0)


def _graph() -> GraphNLP:
    return GraphNLP([*arm_reach_graph().factor_instances, EXTRA])


def _hessian(kinematic: bool, z, p, lam) -> np.ndarray:
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX", kinematic_curvature=kinematic))
    return s.assemble(_graph()).solver.get_function("nlp_hess_l")(z, p, 1.0, lam).full()


def test_without_kinematic_curvature_the_hessian_is_the_lagrangian_without_fk_rows():
    g = _graph()
    a = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX")).assemble(g)
    g_row = np.empty(a.kinds.size, dtype=np.int64)          # real row -> elastic row of g
    g_row[~a.kinds] = np.arange(a.n_ineq)
    g_row[a.kinds] = a.n_ineq + np.arange(a.n_eq)
    fk_rows = [int(g_row[i]) for ref, i0, i1 in a.factor_rows
               if g.factor(ref).template in ("toy.reach", "toy.clear") for i in range(i0, i1)]
    assert len(fk_rows) == 4                                 # reach: 3 rows, clear: 1
    rng = np.random.default_rng(0)
    for _ in range(5):
        z = rng.normal(0.0, 0.7, a.lbx.size)
        p = np.concatenate([z[:a.n_x] + 0.1, a.params, [0.01]])
        lam = rng.normal(0.0, 1.0, a.lbg.size)
        h_off = _hessian(False, z, p, lam)
        lam0 = lam.copy()
        lam0[fk_rows] = 0.0
        h_zero = _hessian(True, z, p, lam0)
        assert np.allclose(h_off, h_zero, rtol=1e-12, atol=1e-12)
        assert not np.allclose(h_off, _hessian(True, z, p, lam), atol=1e-6)   # it changes something
        # the ring's curvature (on o) is still there: lam of its row moves the Hessian
        ring = [int(g_row[i]) for ref, i0, i1 in a.factor_rows if g.factor(ref).template == "toy.ring"
                for i in range(i0, i1)]
        lam1 = lam.copy()
        lam1[ring] += 1.0
        assert not np.allclose(h_off, _hessian(False, z, p, lam1), atol=1e-6)


def test_solves_feasible_without_kinematic_curvature():
    g = arm_reach_graph()
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=1, assembly="MX", kinematic_curvature=False))
    r = s.solve(g, seed=1)
    assert r.feasible
    worst, _ = max_violation(g.factor_instances, r.values, ARM_GEOM)
    assert worst <= 1e-6


def test_the_setting_reaches_the_solver(tmp_path):
    from test_nlp_distance_curvature import _planar_problem

    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import Loop
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile(str(_planar_problem(tmp_path, "solver { kinematic_curvature = false }")))
    opts = SolveOptions.from_settings(c.problem.settings)
    assert opts.kinematic_curvature is False
    assert Loop(c, opts, None).new_solver().options.kinematic_curvature is False
    assert SolveOptions.from_settings(c.problem.settings, kinematic_curvature=True).kinematic_curvature
