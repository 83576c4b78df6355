"""`SolverOptions.distance_curvature`: with it off, ipopt's Hessian of the Lagrangian leaves out
the second derivatives of the rows that query signed distances, and nothing else.

Checked against the exact Hessian with those rows' multipliers set to zero (the same Lagrangian
without them), and by solving a toy arm problem both ways and re-evaluating every factor at the
returned point with the independent numpy evaluator."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

from nlp_toys import ARM_GEOM, arm_reach_graph


def _hessian(curvature: bool, z, p, lam) -> np.ndarray:
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX", distance_curvature=curvature))
    return s.assemble(arm_reach_graph()).solver.get_function("nlp_hess_l")(z, p, 1.0, lam).full()


def test_without_curvature_the_hessian_is_the_lagrangian_without_distance_rows():
    g = arm_reach_graph()
    a = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX")).assemble(g)
    # the rows of the distance factor in g's order (inequalities first, then equalities)
    clear_ref = next(r for r in g.factor_refs if g.factor(r).template == "toy.clear")
    real = next((i0, i1) for ref, i0, i1 in a.factor_rows if ref == clear_ref)
    ineq_rows = np.flatnonzero(~a.kinds)
    dist_rows = [int(np.flatnonzero(ineq_rows == i)[0]) for i in range(*real)]
    rng = np.random.default_rng(0)
    for _ in range(5):
        z = rng.normal(0.0, 0.7, a.lbx.size)
        p = np.concatenate([z[:a.n_x] + 0.1, a.params, [0.01]])
        lam = rng.normal(0.0, 1.0, a.lbg.size)
        h_off = _hessian(False, z, p, lam)
        h_exact = _hessian(True, z, p, lam)
        lam0 = lam.copy()
        lam0[dist_rows] = 0.0
        h_zero = _hessian(True, z, p, lam0)
        assert np.allclose(h_off, h_zero, rtol=1e-12, atol=1e-12)
        assert not np.allclose(h_off, h_exact, atol=1e-6)      # the option changes something


@pytest.mark.parametrize("curvature", [True, False])
def test_solves_feasible_either_way(curvature):
    g = arm_reach_graph()
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=1, assembly="MX", distance_curvature=curvature))
    r = s.solve(g, seed=1)
    assert r.feasible
    worst, _ = max_violation(g.factor_instances, r.values, ARM_GEOM)
    assert worst <= 1e-6


def _planar_problem(tmp_path, line: str):
    from pathlib import Path
    planar = Path(__file__).resolve().parents[2] / "examples" / "planar"
    for extra in planar.iterdir():
        (tmp_path / extra.name).write_text(extra.read_text())
    path = tmp_path / "p1_one_block.pntc"
    path.write_text(path.read_text().rstrip("\n") + "\n" + line + "\n")
    return path


def test_the_setting_reaches_the_solver_and_a_bad_value_is_located(tmp_path):
    from gnppdsl.errors import UserError
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import Loop
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile(str(_planar_problem(tmp_path, "solver { distance_curvature = false }")))
    opts = SolveOptions.from_settings(c.problem.settings)
    assert opts.distance_curvature is False
    assert Loop(c, opts, None).new_solver().options.distance_curvature is False
    assert SolveOptions.from_settings(c.problem.settings, distance_curvature=True).distance_curvature
    (tmp_path / "b").mkdir()
    bad = _planar_problem(tmp_path / "b", "solver { distance_curvature = 0 }")
    with pytest.raises(UserError) as e:
        load_and_compile(str(bad))
    line = len(bad.read_text().splitlines())
    assert "'distance_curvature' must be true or false" in str(e.value)
    assert f"p1_one_block.pntc:{line}:" in str(e.value)
