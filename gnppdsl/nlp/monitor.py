"""ipopt's iteration callback for the elastic feasibility NLPs (`gnppdsl.nlp.feasibility`), and
the check of the point a run ended at for undefined rows (`raise_on_nan`).

Why its own module: it is the one piece of the solver that runs Python inside ipopt's loop,
and the assembled-NLP caches share one monitor between every graph of a structure
(`gnppdsl.nlp.shape_cache`), so its state is reset before each run and read right after.
"""
from __future__ import annotations

import math
import time
from typing import Any, Mapping

import casadi as ca
import numpy as np

from gnppdsl import interrupt


#: the status of a run decided at its start (`IterationMonitor.start_holds`): ipopt not run
START_HELD = "Start_Holds"


class _IpoptCallback(ca.Callback):
    """What both monitors share: casadi's signature of an nlpsol iteration callback (the
    solver's outputs in, one integer out: 1 stops the run) with the iterate sized `n_x`, the
    rows `n_g` and the parameters' multipliers `n_p`, and the buffer protocol (iterate, objective
    and rows as views of ipopt's memory) handed to the subclass's `_decide(x, f, g)`."""

    def _sizes(self, n_x: int, n_g: int, n_p: int | None = None) -> None:
        self._dense = {"x": n_x, "lam_x": n_x, "g": n_g, "lam_g": n_g}
        if n_p is not None:
            self._dense["lam_p"] = n_p

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        n = ca.nlpsol_out(i)
        if n == "f":
            return ca.Sparsity.scalar()
        if n in self._dense:
            return ca.Sparsity.dense(self._dense[n])
        return ca.Sparsity(0, 0)

    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        """casadi's buffer protocol: the iterate and the rows as views of ipopt's memory, no
        DM per input. Why: through `eval` casadi converted every input to a DM and numpy
        copied it (`np.asarray`), ~0.2 ms per iteration, 18 % of ipopt's time on the
        keyframe NLP of `bench_komo.py` (perf: CallbackInternal::eval_dm under
        intermediate_callback)."""
        out = np.frombuffer(res[0], dtype=np.float64)
        out[0] = self._decide(np.frombuffer(arg[0], dtype=np.float64), float(np.frombuffer(arg[1])[0]),
                              np.frombuffer(arg[2], dtype=np.float64))
        return 0

    def eval(self, arg):
        return [self._decide(np.asarray(arg[0]).reshape(-1), float(arg[1]), np.asarray(arg[2]).reshape(-1))]

    def _decide(self, x: np.ndarray, f: float, g: np.ndarray) -> int:
        raise NotImplementedError


class IterationMonitor(_IpoptCallback):
    """ipopt iteration callback: stops a run as soon as the *real* constraints hold (a
    feasibility verdict needs no optimal regulariser), or when the violation has not improved
    by 1 % for `patience` iterations (nonsmooth distances, e.g. penetrating boxes, make ipopt
    wander until max_iter; measured 500 iterations ~ 0.5-2 s per run); progress is the total
    violation (the L1 norm the elastic objective minimises). The real rows are
    recovered from the elastic ones: h = g + s (inequalities), h = g + s_p - s_m (equalities)."""

    def __init__(self, name: str, n_x: int, n_in: int, n_eq: int, n_g: int, n_p: int):
        ca.Callback.__init__(self)
        self.n_x, self.n_in, self.n_eq, self.n_g, self.n_p = n_x, n_in, n_eq, n_g, n_p
        self.n_z = n_x + n_in + 2 * n_eq
        self._sizes(self.n_z, n_g, n_p)
        self.reset(0.0, 0)
        self.construct(name, {})

    def reset(self, stop_below: float, patience: int, deadline: float = math.inf, limit: int = 0) -> None:
        """`limit` > 0: stop the run after that many iterations (`SolverOptions.iteration_budget`:
        what is left of it, which ipopt's `max_iter`, fixed at assembly, cannot say). `deadline` (time.perf_counter() clock): stop the run at the first iteration after
        it. Why here and not only ipopt's `max_wall_time`: that option is fixed when the NLP
        is assembled, and an assembled NLP is cached and solved again later (restarts, the
        polish, Alg. 1 revisiting a subgraph), when less time is left than at assembly. Only
        NLPs with a monitor (early_stop: by default those with geometry primitives, whose
        iterations are the slow ones) have this check; the others keep `max_wall_time`."""
        self.stop_below, self.patience, self.deadline = stop_below, patience, deadline
        self.best, self.best_z, self.since, self.stalled = np.inf, None, 0, False
        self.timed_out = False
        self.limit, self.count = limit, 0

    def _decide(self, x: np.ndarray, f: float, g: np.ndarray) -> int:
        return self.decide(x, g)

    def start_holds(self, z0: np.ndarray, quaternions: list[np.ndarray]) -> bool:
        """Whether the run about to start (after `reset`) from z0, the elastic start (slacks =
        the rows' violations), would stop at ipopt's iteration 0: every real row (its slacks)
        and every unit quaternion of the start within `stop_below`, as `decide` checks there.
        The caller then returns the start itself, with status START_HELD, instead of running
        ipopt; the start is also that run's answer, the elastic objective's minimum (0 slack,
        0 pull). Why: such a run is all set-up: measured on `bench_komo.py`'s path NLPs whose
        straight-line start holds, ~8 ms of ipopt (first evaluations of g and its Jacobian,
        the least-squares multipliers' factorisation) for 0 iterations. The one difference:
        ipopt pushes a start lying within its bound push (1e-4) of a variable bound into the
        interior before checking the rows; the start is kept here, where they hold."""
        if z0.size > self.n_x and not float(np.max(z0[self.n_x:])) <= self.stop_below:
            return False
        return all(abs(float(np.dot(q, q)) - 1.0) <= self.stop_below for q in quaternions)

    def decide(self, z: np.ndarray, g: np.ndarray) -> int:
        """1 to stop the run at iterate z with elastic rows g, else 0 (`z` may be a view of
        ipopt's memory: copied when kept)."""
        # the real rows' violations in one array (inequalities, equalities, unit quaternions),
        # with as few numpy calls as possible: this runs inside every ipopt iteration
        a, b, n = self.n_in, self.n_in + self.n_eq, self.n_x
        r = g.copy()
        r[:b] += z[n:n + b]                      # h = g + s (inequalities), g + s_p (equalities)
        r[a:b] -= z[n + b:]                      # ... - s_m
        np.maximum(r[:a], 0.0, out=r[:a])
        np.abs(r[a:], out=r[a:])
        worst = float(r.max(initial=0.0))
        total = float(r.sum())                   # what the elastic form minimises
        if time.perf_counter() >= self.deadline or interrupt.pending():
            self.timed_out = True        # a signal too (`gnppdsl.interrupt`): stop this run now
            return 1
        self.count += 1                  # called at iteration 0 too: stops at iteration `limit`
        if self.limit and self.count > self.limit:
            return 1
        if not np.isfinite(total):
            return 0
        if worst <= self.stop_below:
            self.best, self.best_z = total, z.copy()
            return 1
        if total < 0.99 * self.best:
            self.best, self.best_z, self.since = total, z.copy(), 0
        else:
            self.since += 1
            if self.patience and self.since >= self.patience:
                self.stalled = True
                return 1
        return 0


def raise_on_nan(graph: Any, per: Mapping[Any, float]) -> None:
    """`NumericalFault` naming the factors whose rows are NaN or infinite at the best point
    (`_verdict` maps NaN to inf). Why: the elastic NLP cannot satisfy a NaN row, so without
    this the plan was refuted, a conflict learnt and the run ended in "no plan" with only
    casadi's warnings on stderr; an undefined value is a fault of the model, not a verdict."""
    bad = [r for r, v in per.items() if not math.isfinite(v)]
    if not bad:
        return
    from gnppdsl.errors import NumericalFault

    names = [graph.factors[r.index].label for r in bad[:3]]
    more = f" and {len(bad) - 3} more" if len(bad) > 3 else ""
    templates = sorted({graph.factors[r.index].template for r in bad})
    raise NumericalFault(
        f"solver fault: factor {', '.join(names)}{more} evaluates to NaN or infinity where the solver stopped; "
        f"check template {', '.join(templates)} for a square root or a log of a "
        f"negative number, a division by zero or an overflow")


# `ObjectiveMonitor`'s second stall test: stop once PROMISE_PATIENCE consecutive iterates (after
# the run has moved and kept a feasible best), feasible or not, have not lowered the least
# objective of every iterate since then by PROMISE_MARGIN x the best. Why: the first test waits
# `patience` (10) iterations for a feasible iterate PROGRESS below the best, and on the mobile
# domain most iterates lie just outside the feasible set (1e-5..1e-2), so a run whose iterates
# have settled at the best's cost spent those 10 iterations for nothing. Replayed on the 24
# exact-Hessian runs of sort_random instances 0-19 (R-LGP, seed 0, main 68e8da5): 1055 -> 947
# iterations, the kept objective +0.02 % on average (at most +0.15 %); the creep of
# tests/nlp/data/optimise_creep_sort_random_1.json stops at iteration 87 instead of 111, +0.25 %.
# Measured against the best alone (an iterate below the best by 2e-3 promises): 914 iterations,
# but that creep (0.07 % per iteration) stopped at 62, +1.3 %. Recorded: tests/nlp/data/
# optimise_tail_sort_random_0.json (instance 0: stops at iteration 40 instead of 43, same best).
PROMISE_PATIENCE = 3
PROMISE_MARGIN = 2e-4


class ObjectiveMonitor(_IpoptCallback):
    """ipopt iteration callback of the optimisation NLP (`gnppdsl.nlp.optimisation`): keeps the
    feasible iterate (every row within `feasible_below`) of lowest objective, and stops the run
    when that objective has not dropped by `progress` (relative) for `patience` iterations, or
    at the CPU `deadline` (time.process_time()). Why: with signed-distance rows (piecewise
    smooth through their contact models) ipopt's dual infeasibility stalls at 1e-5..1e-4 and it
    wanders at the optimum's cost until its iteration limit; measured on sort2 (R-LGP, seed 0):
    the objective 0.6879 -> 0.05368 within 40 exact-Hessian iterations, then 260 more at
    0.053682-0.053686, ending at a point 7e-8 off the rows."""

    def __init__(self, name: str, n_x: int, lbg: np.ndarray, ubg: np.ndarray):
        ca.Callback.__init__(self)
        self.n_x, self.n_g = n_x, lbg.size
        self.lbg, self.ubg = np.asarray(lbg, float), np.asarray(ubg, float)
        self._sizes(n_x, self.n_g)
        self.reset(0.0, 0)
        self.construct(name, {})

    def reset(self, feasible_below: float, patience: int, progress: float = 1e-4,
              deadline: float = math.inf, promise: int = PROMISE_PATIENCE,
              margin: float = PROMISE_MARGIN) -> None:
        """`promise` > 0 (with `patience` > 0): also stop after that many consecutive
        iterations (once moved, with a best), feasible or not, that do not lower the least
        objective since the first best by `margin` x the best (module constants
        PROMISE_PATIENCE, PROMISE_MARGIN: why there)."""
        self.feasible_below, self.patience, self.progress = feasible_below, patience, progress
        self.deadline, self.promise, self.margin = deadline, promise, margin
        self.best, self.best_x, self.since, self.stalled, self.timed_out = np.inf, None, 0, False, False
        self.ref = np.inf                  # the best objective when the stall count last started
        self.count, self.moved = 0, False
        self.idle = 0                      # consecutive iterations promising no gain (`promise`)
        self.low = np.inf                  # the lowest objective of any iterate since the first best

    def _decide(self, x: np.ndarray, f: float, g: np.ndarray) -> int:
        return self.decide(x, f, g)

    def decide(self, x: np.ndarray, f: float, g: np.ndarray) -> int:
        """1 to stop the run at iterate x (objective f, rows g), else 0 (x may be a view of
        ipopt's memory: copied when kept)."""
        self.count += 1
        if time.process_time() >= self.deadline or interrupt.pending():
            self.timed_out = True
            return 1
        worst = max(np.max(g - self.ubg, initial=0.0), np.max(self.lbg - g, initial=0.0)) if g.size else 0.0
        if not (np.isfinite(f) and np.isfinite(worst)):
            return 0
        if worst <= self.feasible_below and f < self.best:
            self.best, self.best_x = f, x.copy()
            self.moved = self.moved or self.count > 1
            self.low = min(self.low, f)
            if f < self.ref - self.progress * abs(self.ref) or not np.isfinite(self.ref):
                self.ref, self.since, self.idle = f, 0, 0    # progress: the stall counts start again
                return 0
        if self.moved:
            # (not from the start: the iterates leave the feasible set first, sort2's for 45
            # iterations, and come back cheaper)
            self.since += 1
            if self.patience and self.since >= self.patience:
                self.stalled = True
                return 1
            # an iterate, feasible or not, below every objective since the best by the margin
            # still promises a gain
            self.idle = 0 if f < self.low - self.margin * abs(self.best) else self.idle + 1
            self.low = min(self.low, f)
            if self.patience and self.promise and self.idle >= self.promise:
                self.stalled = True
                return 1
        return 0
