"""Anytime optimal TAMP: after the first verified solution, cheaper logical plans under a cost
bound, until the bound proves the incumbent optimal or the time budget (`SolveOptions.anytime`,
`--anytime SECONDS`) ends.

The cost of a solution is c(plan) + f(x): the plan's symbolic action costs (`Operator.cost`)
plus the objective, the `minimize` terms at the returned (optimised, verified) solution. The
lower bound of a plan is c(plan) + f_lb, where f_lb = 0 when every `minimize` statement of the
domain is a sum of squares, norms or absolute values (`objective_lower_bound`); otherwise no
lower bound is known, the search still runs in order of c(plan) but never claims a proof.

With an incumbent of cost C, each round:
  1. the cheapest plan by c(plan) (clingo's `#minimize`, `IncrementalPlanner.optimal_plan`,
     idle steps allowed up to horizon H) under every conflict learned so far, every plan already
     evaluated blocked, and the bound c(plan) <= ceil(C - f_lb) - 1 (clasp's initial
     optimisation bound): only plans whose lower bound is below C;
  2. its graph-NLP evaluated like any plan of the loop (`Loop.attempt`: Algorithm 1, conflicts,
     the active set, the independent verification, the optimisation phase);
  3. a verified solution of lower cost becomes the incumbent (the history gets time and cost);
     the plan is blocked; an infeasible plan leaves its conflict in the planner.
"No plan" in step 1 proves that no plan of length <= H has a lower bound below C. With operator
costs >= c_min > 0, a plan of length n costs at least n * c_min, so H = ceil(C / c_min) - 1
covers every length when it is at most `max_horizon` (the proof's `scope` says which).

What a proof means: no other logical plan can beat the incumbent given the conflicts (the NLP
solver's infeasibility verdicts, confirmed by restarts as in the loop); the incumbent's motion
itself is a local optimum of its graph-NLP. Why a second clingo planner on the task without
R-LGP's pair costs: those are heuristic end-effector travel (Eq. 3, weighted orientation and
joint terms), not lower bounds of the objective, so under them a bound would prune plans that
might be cheaper. Action costs that call `travel(r, a, b)` are different: they are part of
c(plan), as numbers the solve took from the graph at its start (`rlgp.with_travel_costs`), so
the bound and the proof are exact for them; `travel_lb(r, a, b)`, the straight-line bound from
the scene, is <= `travel` for every action, so the compiled task's c(plan) is a lower bound of
the solve's (docs/design.md, "Travel in action costs"). Why clingo rather than Fast Downward: clasp's optimisation bound turns
"no cheaper plan" into an unsatisfiability proof of one solve call.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field, fields, replace
from typing import Any, Iterable

from gnppdsl import interrupt
from gnppdsl.ir.expr import Call, Forall, Num, Objective
from gnppdsl.solve.coverage import Coverage
from gnppdsl.solve.deadline import TimeUp
from gnppdsl.solve.result import Result

# the solution-specific fields of Stats: restored from the incumbent when a later candidate
# (whose solution() overwrote them) is not kept
SOLUTION_FIELDS = ("N", "max_violation", "cost", "cost_feasible", "optimised", "factors", "variables",
                   "plan_cost")
IMPROVEMENT = 1e-9        # a candidate must be cheaper by more than this (relative to the cost)


@dataclass
class AnytimeReport:
    """What the anytime phase did (Result.anytime, JSON `anytime`)."""

    budget: float                         # seconds allowed after the first solution
    objective_bound: float | None         # f_lb (None: unknown, no proof possible)
    cost: float = math.inf                # the incumbent's cost = plan_cost + objective
    plan_cost: float = 0.0
    objective: float = 0.0
    proved_optimal: bool = False
    scope: str = ""                       # the plans the proof covers
    stopped: str = ""                     # why the phase ended
    plans: int = 0                        # candidate plans evaluated in the phase
    seconds: float = 0.0                  # wall time of the phase
    history: list[dict[str, Any]] = field(default_factory=list)   # each incumbent: time, cost, ...

    def to_json(self) -> dict[str, Any]:
        d = {f.name: getattr(self, f.name) for f in fields(self)}
        d["history"] = [dict(h) for h in self.history]
        return d


def nonnegative(expr) -> bool:
    """True when `expr` is >= 0 for every value of its variables, by its form alone: a
    constant >= 0, norm / sqnorm / abs / sqrt, dot(a, a), an even power, a sum or product of
    such terms. Conservative: False means "not shown", not "negative"."""
    if isinstance(expr, Num):
        return expr.value >= 0
    if not isinstance(expr, Call):
        return False
    fn, args = expr.fn, expr.args
    if fn in ("norm", "sqnorm", "abs", "sqrt", "exp", "quat_dist"):
        return True
    if fn in ("dot", "mul") and len(args) == 2 and args[0] == args[1]:
        return True
    if fn == "pow":
        e = args[1] if len(args) == 2 else None
        return isinstance(e, Num) and float(e.value).is_integer() and int(e.value) % 2 == 0 \
            or nonnegative(args[0])
    if fn in ("add", "mul", "div", "max", "min"):
        return all(nonnegative(a) for a in args)
    return False


def _objectives(body: Iterable) -> Iterable[Objective]:
    for st in body:
        if isinstance(st, Objective):
            yield st
        elif isinstance(st, Forall):
            yield from _objectives(st.body)


def objective_lower_bound(domain) -> float | None:
    """0.0 when every `minimize` statement of the domain's templates is non-negative by its
    form (`nonnegative`), so any plan's objective is >= 0; None otherwise."""
    terms = [st for t in getattr(domain, "templates", {}).values() for st in _objectives(t.body)]
    return 0.0 if all(nonnegative(st.expr) for st in terms) else None


class Anytime(Coverage):
    """The anytime phase of a GNPP / R-LGP solve (module docstring), over `attempt`, which the
    loop (`Loop`, deriving from this class) defines."""

    def attempt(self, plan) -> Result | None:
        """Evaluate one logical plan exactly as the loop does (its graph-NLP, Alg. 1, conflicts,
        active set, verification, optimisation): the verified result, or None when infeasible.
        Declared here because `improve` calls it; `Loop.attempt` is the implementation."""
        raise NotImplementedError("Anytime.attempt is Loop.attempt: use Loop")

    def improve(self, first: Result) -> Result:
        """Search cheaper plans from the verified first solution `first` for
        `options.anytime` seconds (within the time limit); the best verified result."""
        from gnppdsl.logic.planner import IncrementalPlanner, Status

        t_phase = time.perf_counter()
        end = min(self.deadline, t_phase + self.options.anytime)
        saved_deadline, self.deadline = self.deadline, end
        if self.kernels is not None:
            self.kernels.deadline = end
        lb = objective_lower_bound(self.compiled.problem.domain)
        report = AnytimeReport(self.options.anytime, lb)
        best, best_stats = first, self._solution_stats()
        self._record(report, first)
        task = replace(self.task, pair_costs={})
        costs = [op.cost for op in task.operators]
        c_min = min(costs, default=0)
        integral = task.cost_scale() == 1
        planner = IncrementalPlanner(task, max_horizon=self.options.max_horizon)
        planner.add_conflicts(self.planner.conflicts)
        for ops in self.planner.blocked:
            planner.block_plan(ops)
        planner.block_plan(first.extras["plan"].operators)
        main_planner, self.planner = self.planner, planner
        self.db = None                    # closed by the first result; the phase solves without it
        try:
            while True:
                left = end - time.perf_counter()
                if left <= 0:
                    report.stopped = f"budget of {self.options.anytime:g} s used"
                    break
                H, scope = self._horizon(report.cost, c_min, lb)
                below = report.cost - (lb or 0.0) - IMPROVEMENT * max(1.0, abs(report.cost))
                # integer costs: the largest integer below; costs with decimals: the value itself
                bound = None if lb is None else (math.ceil(below) - 1 if integral else below)
                t0 = time.perf_counter()
                res = planner.optimal_plan(H, time_limit=left, cost_bound=bound)
                self.stats.logic_time += time.perf_counter() - t0
                if res.status is Status.NO_PLAN:
                    if bound is not None:
                        report.proved_optimal, report.scope = True, scope
                        report.stopped = f"no logical plan ({scope}) has a lower bound below {report.cost:.6g}"
                    else:
                        report.stopped = f"every plan of {scope} evaluated (objective without a known lower bound)"
                    break
                if res.status is Status.TIMEOUT or res.plan is None:
                    report.stopped = f"budget of {self.options.anytime:g} s used (planner)"
                    break
                plan = res.plan
                report.plans += 1
                self.say(f"anytime: plan cost {plan.cost} (bound {bound}), incumbent {report.cost:.6g}")
                out = self.attempt(plan)
                planner.block_plan(plan)          # evaluated: never proposed again
                if out is None or not out.solved:
                    continue
                cost = (self.stats.plan_cost or 0) + (self.stats.cost or 0.0)
                if cost < report.cost - IMPROVEMENT * max(1.0, abs(report.cost)):
                    best, best_stats = out, self._solution_stats()
                    self._record(report, out)
                    self.say(f"anytime: cost {cost:.6g} (improved)")
                else:
                    self.say(f"anytime: cost {cost:.6g} (not cheaper)")
        except TimeUp:
            report.stopped = f"budget of {self.options.anytime:g} s used"
        except interrupt.Interrupted as stop:
            report.stopped = stop.describe()
        finally:
            self.planner, self.deadline = main_planner, saved_deadline
            if self.kernels is not None:
                self.kernels.deadline = saved_deadline
        for name, value in best_stats.items():
            setattr(self.stats, name, value)
        report.seconds = time.perf_counter() - t_phase
        self.finish_stats()
        best.anytime = report.to_json()
        best.message += (f"; anytime: {report.plans} plans in {report.seconds:.1f} s, cost "
                         f"{report.history[0]['cost']:.6g} -> {report.cost:.6g}, "
                         + ("optimal (proved)" if report.proved_optimal else "not proved optimal"))
        return best

    def _horizon(self, cost: float, c_min: float, lb: float | None) -> tuple[int, str]:
        """The longest plan that may beat `cost`, and the scope of a proof at that horizon."""
        H = self.options.max_horizon
        if lb is not None and c_min > 0:
            longest = math.ceil((cost - lb) / c_min) - 1
            if longest <= H:
                return max(0, longest), "all plans"
        return H, f"plans up to length {H}"

    def _solution_stats(self) -> dict[str, Any]:
        return {name: getattr(self.stats, name) for name in SOLUTION_FIELDS}

    def _record(self, report: AnytimeReport, res: Result) -> None:
        report.plan_cost = self.stats.plan_cost or 0
        report.objective = self.stats.cost or 0.0
        report.cost = report.plan_cost + report.objective
        report.history.append({"time": time.perf_counter() - self.start,
                               "cpu_time": time.process_time() - self.cpu_start,
                               "cost": report.cost, "plan_cost": report.plan_cost,
                               "objective": report.objective, "length": len(res.plan),
                               "plan": list(res.plan)})


__all__ = ["Anytime", "AnytimeReport", "nonnegative", "objective_lower_bound"]
