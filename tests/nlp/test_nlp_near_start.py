"""The near-start solver (`FeasibilitySolver._near`: a start whose rows already hold within
`near_start_below`, such as a motion on the straight line between solved keyframes) skips
ipopt's gradient-based NLP scaling: that scaling evaluates the constraint Jacobian and the
objective gradient once more at the start, before the first iteration (measured on
`bench_komo.py`'s path NLPs: 2 of the 2-3 Jacobian evaluations of a 0-1 iteration solve, 2.3 ms
each), and with every gradient of the elastic NLP below its threshold (100) it scaled nothing
there: the iterations were the same."""
from __future__ import annotations

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

from nlp_toys import ARM_GEOM, arm_reach_graph


def test_a_start_that_nearly_holds_is_solved_without_the_scalings_jacobian():
    g = arm_reach_graph()
    # (without the Gauss-Newton steps that decide such a start first, test_nlp_projected_start.py)
    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=1, assembly="MX", gauss_newton_steps=0))
    first = s.solve(g, seed=1)
    assert first.feasible
    # every row holds at the start within ~1e-4 (not within 0.1 tolerance: a start that holds
    # that well is not run at all, `test_nlp_start_holds.py`)
    start = {v: x + 1e-4 for v, x in first.values.items()}
    worst0, _ = max_violation(g.factor_instances, start, ARM_GEOM)
    assert 1e-7 < worst0 <= 1e-3
    again = s.solve(g, warm_start=start, seed=1)
    assert again.feasible
    a = s.assemble(g)
    near = (a.root or a).near
    assert near is not None, "the start that holds was not given to the near-start solver"
    st = near.stats()
    # one Jacobian (and gradient) evaluation per iteration and one at the start for the initial
    # multipliers, none for the scaling
    assert st["n_call_nlp_jac_g"] == again.iterations + 1
    worst, _ = max_violation(g.factor_instances, again.values, ARM_GEOM)
    assert worst <= 1e-6
