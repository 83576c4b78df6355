"""`SolverOptions.kinematic_curvature = "auto"`: each start is run with the forward-kinematics
rows linearised in ipopt's Hessian and, when that does not end feasible, again from the same
start with the exact Hessian, whose result is the verdict.

A stub makes every linearised run stall at its start (what a Gauss-Newton model stuck on a
handover keyframe looks like to the loop): with `auto` the verdict is still feasible, and an
infeasible verdict is the exact Hessian's own (same point as kinematic_curvature true)."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.errors import UserError
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import ARM_GEOM, arm_reach_graph, discs


class LinearisedStalls(FeasibilitySolver):
    """Every ipopt run of an NLP assembled with linearised FK rows ends where it started."""

    linearised_runs = 0

    def _run(self, a, x0, rho, warm=None, limit=0):
        if a.linearised:
            self.linearised_runs += 1
            return x0.copy(), 1.0, 0, "stub: linearised run stalled", None
        return super()._run(a, x0, rho, warm, limit)


def _solver(mode, cls=LinearisedStalls, **kw) -> FeasibilitySolver:
    return cls(ARM_GEOM, SolverOptions(assembly="MX", kinematic_curvature=mode, **kw))


def test_auto_falls_back_to_the_exact_hessian_when_the_linearised_run_fails():
    g = arm_reach_graph()
    s = _solver("auto", restarts=0)
    assert s.assemble(g).linearised            # the first pass leaves the FK rows out
    r = s.solve(g, seed=1)
    assert s.linearised_runs >= 1              # the stub was hit ...
    assert r.feasible, r.status                # ... and the exact run decided
    assert (s.curvature_fallbacks, s.curvature_rescues) == (1, 1)
    # the same stub without the fallback: the linearised stall is the verdict
    off = _solver(False, restarts=0)
    assert not off.solve(g, seed=1).feasible


def test_a_feasible_linearised_run_is_the_verdict():
    """When the linearised run ends feasible, no exact twin is assembled or run."""
    g = arm_reach_graph()
    solution = _solver(True, cls=FeasibilitySolver, restarts=2).solve(g, seed=1)
    assert solution.feasible

    class LinearisedSolves(FeasibilitySolver):
        def _run(self, a, x0, rho, warm=None, limit=0):
            assert a.linearised, "an exact run after a feasible linearised one"
            x = np.concatenate([solution.values[v] for v in a.variables])
            return x, 0.0, 7, "stub: linearised run solved", None

    s = _solver("auto", cls=LinearisedSolves, restarts=2)
    r = s.solve(g, seed=1)
    assert r.feasible and r.status == "stub: linearised run solved" and r.starts == 1
    assert s.curvature_fallbacks == 0
    assert all(a.linearised for a in s._nlps.values())


def test_an_infeasible_auto_verdict_is_the_exact_hessians():
    """An unreachable target: infeasible from every start. The verdict and its convergence
    point (what the conflict search reads) are those of kinematic_curvature true."""
    from gnppdsl.ir.expr import Constraint, Index, Num

    from nlp_toys import ARM_O, ARM_Q, _arm_tip, factor

    g0 = arm_reach_graph()
    far = factor("toy.reach_far", [ARM_Q, ARM_O], [                # the 2-link arm reaches < 5
        Constraint(Index(_arm_tip(), Num(0)), "==", Num(5.0)),
        Constraint(Index(_arm_tip(), Num(1)), "==", Num(0.9))], 0)
    g = GraphNLP([far, *g0.factor_instances[1:]])
    exact = _solver(True, cls=FeasibilitySolver, restarts=1).solve(g, seed=3)
    s = _solver("auto", restarts=1)
    auto = s.solve(g, seed=3)
    assert not exact.feasible and not auto.feasible
    assert s.curvature_fallbacks == 1 and s.curvature_rescues == 0
    assert auto.max_violation == pytest.approx(exact.max_violation, rel=1e-9, abs=1e-12)
    for v, x in exact.values.items():
        assert np.allclose(auto.values[v], x, atol=1e-9)


def test_no_fk_rows_no_second_pass():
    vs, fs = discs(2, c=0.8, r=1.0)
    s = _solver("auto", restarts=0)
    a = s.assemble(GraphNLP(fs))
    assert not a.linearised                    # nothing to linearise: one pass is the exact one


def test_a_bad_mode_is_refused():
    with pytest.raises(UserError):
        FeasibilitySolver(ARM_GEOM, SolverOptions(kinematic_curvature="sometimes"))


def test_the_setting_and_the_flags_reach_the_solver(tmp_path):
    import argparse

    from test_nlp_distance_curvature import _planar_problem

    from gnppdsl.cli.solver_args import add_curvature_argument
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import Loop
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile(str(_planar_problem(tmp_path, "solver { kinematic_curvature = auto }")))
    opts = SolveOptions.from_settings(c.problem.settings)
    assert opts.kinematic_curvature == "auto"
    assert Loop(c, opts, None).new_solver().options.kinematic_curvature == "auto"
    (tmp_path / "b").mkdir()
    bad = _planar_problem(tmp_path / "b", "solver { kinematic_curvature = sometimes }")
    with pytest.raises(UserError, match="'kinematic_curvature' must be true, false or auto"):
        load_and_compile(str(bad))
    ap = argparse.ArgumentParser()
    ap.add_argument("problem")
    add_curvature_argument(ap)
    for argv, want in ((["p"], None), (["p", "--kinematic-curvature"], True),
                       (["p", "--no-kinematic-curvature"], False), (["--kinematic-curvature", "auto", "p"], "auto"),
                       (["p", "--kinematic-curvature=false"], False), (["p", "--kinematic-curvature", "on"], True)):
        args = ap.parse_args(argv)
        assert args.kinematic_curvature == want and type(args.kinematic_curvature) is type(want), argv
        assert args.problem == "p"
    with pytest.raises(SystemExit):
        ap.parse_args(["p", "--kinematic-curvature", "sometimes"])


def test_auto_gives_up_linearised_runs_that_keep_failing():
    """`trial_patience`: after that many solves in a row whose linearised runs all failed, the
    solvers sharing the record run the exact Hessian only (a Lab 3 handover: every linearised
    run stalls, each one a wasted run before the exact one)."""
    g = arm_reach_graph()
    s = _solver("auto", restarts=0, trial_patience=2)
    for _ in range(2):
        assert s.solve(g, seed=1).feasible
    assert s.trials.given_up and s.linearised_runs == 2 and s.curvature_fallbacks == 2
    other = _solver("auto", restarts=0, trial_patience=2)
    other.trials = s.trials                    # as the solvers of one loop share it
    assert other.solve(g, seed=2).feasible
    assert other.linearised_runs == 0 and other.curvature_fallbacks == 0
    never = _solver("auto", restarts=0, trial_patience=0)
    for _ in range(3):
        never.solve(g, seed=1)
    assert not never.trials.given_up and never.linearised_runs == 3


def test_a_linearised_run_is_capped_at_trial_iterations():
    """`trial_iterations`: a linearised run of "auto" (and its polish) gets at most that many
    ipopt iterations, the exact run none but the iteration budget's. Why: on the Lab rows the
    linearised runs that fail stall after 75-210 iterations before the exact run decides (21-56);
    the ones that succeed take 17-31. The verdict stays the exact run's."""
    from gnppdsl.ir.expr import Constraint, Index, Num

    from nlp_toys import ARM_O, _arm_tip, factor

    class Limits(FeasibilitySolver):
        seen: list = []

        def _run(self, a, x0, rho, warm=None, limit=0):
            self.seen.append((a.linearised, limit))
            return super()._run(a, x0, rho, warm, limit)

    g0 = arm_reach_graph()
    far = factor("toy.reach_far", [g0.factor_instances[0].variables[0], ARM_O], [
        Constraint(Index(_arm_tip(), Num(0)), "==", Num(5.0)),
        Constraint(Index(_arm_tip(), Num(1)), "==", Num(0.9))], 0)
    g = GraphNLP([far, *g0.factor_instances[1:]])
    s = _solver("auto", cls=Limits, restarts=0, trial_iterations=3, early_stop=True)
    r = s.solve(g, seed=3)
    assert not r.feasible
    lin = [lim for l, lim in s.seen if l]
    assert lin and all(lim == 3 for lim in lin)
    assert all(lim == 0 for l, lim in s.seen if not l)
    exact = _solver(True, cls=FeasibilitySolver, restarts=0, early_stop=True).solve(g, seed=3)
    assert r.max_violation == pytest.approx(exact.max_violation, rel=1e-9, abs=1e-12)
    assert r.iterations <= exact.iterations + 3 + 3       # the capped runs cost at most 3 each
