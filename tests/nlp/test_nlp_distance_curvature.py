"""`SolverOptions.distance_curvature`: with it off, ipopt's Hessian of the Lagrangian leaves out
the second derivatives of the rows that query signed distances, and nothing else.

Checked against the exact Hessian with those rows' multipliers set to zero (the same Lagrangian
without them), and by solving a toy arm problem both ways and re-evaluating every factor at the
returned point with the independent numpy evaluator."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

from nlp_toys import ARM_GEOM, arm_hessian, arm_reach_graph, arm_solved_worst, hessian_points


def test_without_curvature_the_hessian_is_the_lagrangian_without_distance_rows():
    g = arm_reach_graph()
    a = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX")).assemble(g)
    # the rows of the distance factor in g's order (inequalities first, then equalities)
    clear_ref = next(r for r in g.factor_refs if g.factor(r).template == "toy.clear")
    real = next((i0, i1) for ref, i0, i1 in a.factor_rows if ref == clear_ref)
    ineq_rows = np.flatnonzero(~a.kinds)
    dist_rows = [int(np.flatnonzero(ineq_rows == i)[0]) for i in range(*real)]
    for z, p, lam in hessian_points(a):
        h_off = arm_hessian(g, z, p, lam, distance_curvature=False)
        h_exact = arm_hessian(g, z, p, lam, distance_curvature=True)
        lam0 = lam.copy()
        lam0[dist_rows] = 0.0
        h_zero = arm_hessian(g, z, p, lam0, distance_curvature=True)
        assert np.allclose(h_off, h_zero, rtol=1e-12, atol=1e-12)
        assert not np.allclose(h_off, h_exact, atol=1e-6)      # the option changes something


@pytest.mark.parametrize("curvature", [True, False])
def test_solves_feasible_either_way(curvature):
    assert arm_solved_worst(arm_reach_graph(), distance_curvature=curvature) <= 1e-6


def _planar_problem(tmp_path, line: str):
    from pathlib import Path
    planar = Path(__file__).resolve().parents[2] / "examples" / "planar"
    for extra in planar.iterdir():
        (tmp_path / extra.name).write_text(extra.read_text())
    path = tmp_path / "p1_one_block.pntc"
    path.write_text(path.read_text().rstrip("\n") + "\n" + line + "\n")
    return path


# the two curvature settings (`SolverOptions.distance_curvature`, `.kinematic_curvature`, tested
# above and in test_nlp_kinematic_curvature.py): each written as a problem's setting reaches the
# solver's options, a keyword overrides it, and a value of the wrong type is refused at its line
@pytest.mark.parametrize("setting", ["distance_curvature", "kinematic_curvature"])
def test_the_setting_reaches_the_solver_and_a_bad_value_is_located(tmp_path, setting):
    from gnppdsl.errors import UserError
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import Loop
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile(str(_planar_problem(tmp_path, f"solver {{ {setting} = false }}")))
    opts = SolveOptions.from_settings(c.problem.settings)
    assert getattr(opts, setting) is False
    assert getattr(Loop(c, opts, None).new_solver().options, setting) is False
    assert getattr(SolveOptions.from_settings(c.problem.settings, **{setting: True}), setting) is True
    (tmp_path / "b").mkdir()
    bad = _planar_problem(tmp_path / "b", f"solver {{ {setting} = 0 }}")
    with pytest.raises(UserError) as e:
        load_and_compile(str(bad))
    line = len(bad.read_text().splitlines())
    assert f"'{setting}' must be true" in str(e.value)      # "true or false" (and any further values)
    assert f"p1_one_block.pntc:{line}:" in str(e.value)
