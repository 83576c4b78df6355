"""`SolverOptions`: the settings of one `gnppdsl.nlp.feasibility.FeasibilitySolver` (tolerance,
restarts, polish, ipopt's options, which second derivatives enter ipopt's Hessian) and the
casadi nlpsol options they give. Light: no casadi import.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

from gnppdsl.errors import UserError

#: values of `SolverOptions.kinematic_curvature` (and of the solver setting)
KINEMATIC_CURVATURE_MODES = (True, False, "auto")


@dataclass
class CurvatureTrials:
    """kinematic_curvature "auto": how the linearised runs have fared, shared by the solvers of
    one solve loop (`SolverOptions.trial_patience`)."""

    failed_in_a_row: int = 0       # solves whose linearised runs all failed, since the last success
    given_up: bool = False         # linearised runs no longer tried


@dataclass
class SolverOptions:
    tolerance: float = 1e-6        # max constraint violation accepted as feasible
    regularisation: float = 1e-2   # rho: weight of the pull towards the start point
    max_iter: int = 500
    restarts: int = 2              # extra random restarts after an infeasible verdict: a false
                                   # "infeasible" would prune feasible plans (Theorem 7.1)
    noise: float = 0.1             # std of the default start perturbation (x10 on restarts)
    restart_noise: float = 0.3     # std of the perturbation of the initial guess on odd restarts
    ipopt: dict = field(default_factory=dict)   # extra nlpsol options ("ipopt.xyz": value)
    plugin: str = "ipopt"          # casadi nlpsol plugin: "ipopt" or "sqpmethod" (qrqp)
    time_limit: float | None = None   # wall-clock seconds per ipopt run
    early_stop: bool | str = "auto"   # ipopt: stop once the real rows hold, or on a stall
                                   # (_Monitor); "auto": when geometry primitives appear (the
                                   # Python callback costs ~50 us per iteration, +30 % on toys)
    stall_iterations: int = 60     # ipopt: stop after this many iterations without 1 % progress
    hessian: str = "exact"         # ipopt: "exact" or "limited-memory" (L-BFGS: no Hessian
                                   # construction; on the lab1 full graph with trajectories
                                   # 3.5 s + 30 s (240 it) vs exact 16-26 s + 26-31 s (90 it))
    distance_curvature: bool = True   # ipopt's exact Hessian includes the second derivatives
                                   # of rows querying signed distances; False: they enter the
                                   # Hessian linearised (`elastic_derivatives.hessian_function`: why)
    kinematic_curvature: bool | str = True  # ... and of rows using forward kinematics (`fk`;
                                   # the solve loop's default is "auto": `SolveOptions`);
                                   # False: they enter linearised too (Gauss-Newton-like steps,
                                   # as KOMO takes; `hessian_function`); "auto": each start is
                                   # run linearised first and, when that run does not end
                                   # feasible, again from the same start with the exact Hessian,
                                   # whose result then stands (`FeasibilitySolver.solve`)
    assembly: str = "auto"         # "SX" | "MX" | "auto" (MX when geometry primitives appear)
    cache_size: int = 512          # assembled NLPs kept (LRU) per FeasibilitySolver
    polish: bool = True            # re-solve an infeasible verdict with rho * 1e-4 from x*
    polish_below: float = 1e-3     # polish at once (before random restarts) a start that ends
                                   # this close to feasible: a stall near a solution, which
                                   # restarts from random points only repeat from farther away
    final_polish_below: float = math.inf   # polish the best point after the last start when
                                   # its violation is below this (the solve loop lowers it for
                                   # a one-start verdict that is confirmed later: there the
                                   # confirmation polishes)
    shared_assembly: bool = True   # graphs of one structure share one assembled NLP
                                   # (`shape_cache`; False: each graph assembles its own)
    near_start_below: float = 1e-3  # a first start whose rows all hold within this is run by
                                   # ipopt with a small bound push (`FeasibilitySolver._near`);
                                   # 0 turns it off
    gauss_newton_steps: int = 8    # such a near start (first runs with an iteration monitor,
                                   # no free unit quaternion) first takes up to this many
                                   # Levenberg-Marquardt steps on the rows; when they make every
                                   # row hold, that point is the run's answer and ipopt does not
                                   # run (`FeasibilitySolver._projected`); 0 turns them off
    iteration_budget: int = 0      # ipopt iterations of one `solve` over all its runs (first
                                   # runs, polishes, exact-Hessian fallbacks); 0: none. Once it
                                   # is spent no run starts and a run with an iteration monitor
                                   # stops; for NLPs whose failure is never a verdict
    trial_patience: int = 2        # kinematic_curvature "auto": after this many solves in a row
                                   # whose linearised runs all failed, the solvers sharing the
                                   # record (`CurvatureTrials`: one loop) run only the exact
                                   # Hessian; 0: never give up
    trial_iterations: int = 50     # kinematic_curvature "auto": a linearised run (and its
                                   # polish) stops after this many ipopt iterations and the
                                   # exact run from the same start decides; 0: no cap. Why:
                                   # the linearised runs that end feasible do so in 17-31
                                   # iterations (bench_komo's keyframe NLP, 20 seeds; lab2),
                                   # the ones that fail stall after 75-210 (each Lab row,
                                   # work2, field3: 2 per solve before `trial_patience` gives
                                   # up; lab5_paper 210 + 178 iterations, 4.2 s CPU), where
                                   # the exact run then takes 21-56. A capped run is never a
                                   # verdict: the exact run always follows

    def nlpsol_options(self) -> dict:
        if self.plugin == "sqpmethod":
            opts = {"qpsol": "qrqp", "qpsol_options": {"print_iter": False, "print_header": False,
                                                       "error_on_fail": False},
                    "print_header": False, "print_iteration": False, "print_status": False,
                    "print_time": False, "error_on_fail": False, "max_iter": self.max_iter,
                    "tol_pr": min(1e-8, 0.01 * self.tolerance), "tol_du": 1e-9}
            opts.update(self.ipopt)
            return opts
        if self.plugin != "ipopt":
            raise UserError(f"unknown nlp solver {self.plugin!r} (use ipopt or sqpmethod)")
        opts = {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                "ipopt.max_iter": self.max_iter, "ipopt.tol": 1e-9,
                "ipopt.constr_viol_tol": min(1e-8, 0.01 * self.tolerance),
                "ipopt.mu_strategy": "adaptive", "error_on_fail": False,
                # no multipliers of the parameters, so no `nlp_grad` (a reverse sweep through
                # every body, unused by the verdict): 0.3 s per Panda full-graph NLP
                "calc_lam_p": False, "no_nlp_grad": True,
                # the step of the constraints' multipliers chosen to minimise the dual
                # infeasibility (ipopt's default: the primal step). Measured on the keyframe NLP
                # of `bench_komo.py` (20 seeds, one process, alternating): 246 -> 230 ipopt
                # iterations over 10 seeds, median 41.6 -> 37.9 ms CPU, 20/20 feasible, path NLPs
                # unchanged (14.0 / 13.8 ms); `safer-min-dual-infeas` 40.6 ms, `full` 400 iterations
                "ipopt.alpha_for_y": "min-dual-infeas",
                # no residual of each step's KKT solve (and so no iterative refinement unless
                # the solve fails outright): MUMPS solves these systems to ~1e-12, so the steps,
                # iterates and iteration counts are those of the default within 1e-9. Measured
                # on the keyframe NLP of `bench_komo.py` (20 seeds x 2, alternating, one
                # process, load ~5): median 23.2 -> 21.1 ms CPU, 912 iterations both, 40/40
                # feasible, solutions within 5e-10 of the default's
                "ipopt.fast_step_computation": "yes"}
        if self.time_limit is not None:
            opts["ipopt.max_wall_time"] = float(self.time_limit)
        if self.hessian not in ("exact", "limited-memory"):
            raise UserError(f"unknown Hessian mode {self.hessian!r} (use exact or limited-memory)")
        opts["ipopt.hessian_approximation"] = self.hessian
        opts.update(self.ipopt)
        return opts
