"""Incremental symbolic planner: clingo multi-shot solving with conflicts as blocking constraints.

Why multi-shot: the Graph-NLP Planner (paper 000, Fig. 3) asks for a plan, learns a conflict
<p_0 .. p_L> from the continuous level, and asks again, many times. Regrounding the task each
time would dominate the run time, so one clingo `Control` lives as long as the planner:
- the task is grounded once (`base`), one `step(t)`/`check(t)` per horizon t;
- `add_conflict` adds a step-parameterised program, grounds it for all existing steps at once
  and for every later step together with `step(t)` (a rule grounded once would not constrain
  atoms of later steps);
- `block_plan` forbids one whole plan (the One-way baseline);
- horizons only grow: constraints only remove plans, so a horizon proven empty stays empty.

Results are values, not exceptions: `PlanResult.status` says found / no plan up to H / time
limit, with a message for users; `PlanResult.unwrap()` raises `SolveFailure` when wanted.
"""
from __future__ import annotations

import enum
import math
import time
from dataclasses import dataclass, field, replace
from typing import Sequence

import clingo

from gnppdsl.compile.sas import SASTask
from gnppdsl import interrupt
from gnppdsl.errors import SolveFailure
from gnppdsl.logic.encoding import conflict_program, encode_task, lifted_conflict_program
from gnppdsl.logic.learned import LearnedConstraints
from gnppdsl.logic.lower_bound import LengthBound
from gnppdsl.logic.validate import State, find_sequence, plan_cost

DEFAULT_MAX_HORIZON = 64
# clasp's "trendy" configuration: on the Lab example with 71 learned conflicts it proved the
# horizons 0..15 empty in 1.4 s against 9 s with the default ("auto"); towers are unaffected.
DEFAULT_CLINGO_ARGS = ("--configuration=trendy",)
# clasp conflicts a horizon below the plan-length bound may cost before the search jumps to the
# bound (`lower_bound.plan_length_bound`). Why not jump at once: the horizons a propagation or a
# few conflicts refute cost milliseconds, and the nogoods they leave steer clingo to the same
# first plan as without the bound (work2, field3, lab1/3/4_paper: at most 24 conflicts each
# below N0 = the bound); jumping at once gave other shortest plans there and a different solve
# (work2 8.4 -> 11.1 s CPU, field3 11.4 -> 13.4 s). The expensive ones are skipped (lab5_paper:
# 165 at horizon 6 .. 9556 at 11; work4: 1899 and 27389 at 6 and 7).
CHEAP_CONFLICTS = 100


class Status(enum.Enum):
    FOUND = "found"
    NO_PLAN = "no plan"          # proven: no plan up to the horizon (under all constraints)
    TIMEOUT = "time limit"       # the time limit ran out before an answer


@dataclass(frozen=True)
class Plan:
    """A logic plan: operators a_1..a_n and the full states s_0..s_n (derived values included)."""

    operators: tuple[int, ...]
    names: tuple[str, ...]
    states: tuple[State, ...]
    cost: float
    shortest: bool = False   # proven: no shorter plan exists under the current constraints
    optimal: bool = False    # proven: no cheaper plan (up to the horizon / of this length)

    def __len__(self) -> int:
        return len(self.operators)

    def __bool__(self) -> bool:   # the empty plan is a plan
        return True

    def __str__(self) -> str:
        return "\n".join(f"{i}: {n}" for i, n in enumerate(self.names, start=1)) or "(empty plan)"


@dataclass
class PlanResult:
    status: Status
    plan: Plan | None
    horizon: int              # largest horizon examined
    time: float               # wall time of the call (grounding + solving)
    message: str = ""

    @property
    def found(self) -> bool:
        return self.status is Status.FOUND

    def unwrap(self) -> Plan:
        """The plan, or `SolveFailure` with the message (for the CLI)."""
        if self.plan is None:
            raise SolveFailure(self.message)
        return self.plan


@dataclass
class PlannerStats:
    ground_calls: int = 0                       # calls to Control.ground
    grounded_parts: list[tuple[str, tuple[int, ...]]] = field(default_factory=list)
    solve_calls: int = 0
    ground_time: float = 0.0
    solve_time: float = 0.0                     # wall time inside clingo's solve calls
    clingo_solve_time: float = 0.0              # clingo's own search time (statistics=True)
    conflicts: int = 0                          # clasp conflicts of solve calls under a conflict budget

    def count(self, program: str) -> int:
        """How often program part `program` was grounded (any parameters)."""
        return sum(1 for name, _ in self.grounded_parts if name == program)


class IncrementalPlanner(LearnedConstraints):
    """Shortest plans, plan enumeration and cheapest plans for one SAS+ task.

    Parameters: `max_horizon` bounds the search when a call does not give its own bound;
    `clingo_args` are passed to `clingo.Control` (e.g. `["--configuration=handy"]`);
    `invariants` adds h^2 mutexes to the encoding (sound; faster proofs of "no plan");
    `lower_bound`: `lower_bound.plan_length_bound(task)` is a length no plan of the task is
    shorter than, so the horizons below it need no proof: they are solved while each costs at
    most CHEAP_CONFLICTS clasp conflicts, and the first that costs more jumps to the bound
    (shortest plans stay shortest; a task whose goal the bound finds unreachable has no plan);
    `statistics` sums clingo's own search time into `stats.clingo_solve_time` (reading clingo's
    statistics costs about a millisecond per solve call, so it is off by default).
    """

    def __init__(self, task: SASTask, max_horizon: int = DEFAULT_MAX_HORIZON,
                 clingo_args: Sequence[str] = DEFAULT_CLINGO_ARGS, invariants: bool = True,
                 statistics: bool = False, lower_bound: bool = True, raise_bound: bool = True) -> None:
        self.task = task
        self.max_horizon = max_horizon
        self._statistics = statistics
        self.stats = PlannerStats()
        LearnedConstraints.__init__(self)
        self._step_programs: list[str] = []   # grounded for every step t (conflicts)
        self._waiting_blocks: dict[int, list[tuple[tuple[int, ...], str]]] = {}
        self._cache: list[Plan] = []          # further plans of the last solve (next_plan)
        self._cache_key: tuple[int, int] = (-1, 0)   # (horizon, conflicts known) of the cache
        self._ctl = clingo.Control(["--warn=none", *clingo_args])
        self._ctl.add("base", [], encode_task(task, invariants=invariants))
        self._externals: dict[clingo.Symbol, bool] = {}
        self._horizon = 0            # steps grounded: 1..horizon
        self._lowest = 0             # smallest horizon that may still hold a plan
        self.conflict_budget: int | None = None   # clasp conflicts left for solve calls (None: no limit)
        self._ground([("base", ()), ("check", (0,))])
        self._bound = 0              # no plan is shorter (`lower_bound`); horizons below it are
                                     # solved only while cheap (CHEAP_CONFLICTS)
        self._length: LengthBound | None = None   # the bound, raised by conflicts (`LengthBound.under`)
        self._raised = 0             # ... its value under the conflicts so far
        self.raise_bound = raise_bound   # the horizons start at the raised bound (else only reported)
        if lower_bound:
            # after the encoding: its h^2 mutexes are cached (`mutex.h2_matrix`), the bound reuses them
            self._length = LengthBound(task)
            bound = self._length.bound
            if bound is None:            # a goal value unreachable: no plan at any horizon
                self._lowest = bound = max_horizon + 1
                self._length = None
            self._bound = bound

    # ---- grounding ---------------------------------------------------------------------
    @property
    def no_plan_below(self) -> int:
        """A length no plan under the current constraints is shorter than: the horizons proven
        empty so far, or the plan-length bound (`lower_bound`) raised by the conflicts."""
        self._raise_bound()
        return max(self._lowest, self._bound, self._raised)

    @property
    def raised_by_conflicts(self) -> int | None:
        """The plan-length bound when the conflicts raised it above the task's own bound and
        above every horizon proven empty (the next plan lies at a horizon the search has never
        solved), else None."""
        self._raise_bound()
        if self._length is None or self._raised <= max(self._bound, self._lowest):
            return None
        return self._raised

    def _raise_bound(self) -> None:
        """The plan-length bound under the conflicts learned so far (`LengthBound.under`: e.g.
        a goal pad covered by an obstacle adds the obstacle's pick and place)."""
        if self._length is not None:             # `under` looks at each conflict once
            raised = self._length.under(self.conflicts)
            if raised is not None:
                self._raised = max(self._raised, raised)
                if self.raise_bound:
                    self._bound = max(self._bound, raised)

    @property
    def horizon(self) -> int:
        """The largest grounded step."""
        return self._horizon

    def _ground(self, parts: list[tuple[str, tuple[int, ...]]]) -> None:
        t0 = time.perf_counter()
        self._ctl.ground([(n, [clingo.Number(a) for a in args]) for n, args in parts])
        self.stats.ground_time += time.perf_counter() - t0
        self.stats.ground_calls += 1
        self.stats.grounded_parts.extend(parts)

    def _extend_to(self, h: int, deadline: float | None = None) -> bool:
        """Ground steps up to h; False if the deadline passed first (grounding is not
        interruptible, so the deadline is checked between steps)."""
        for t in range(self._horizon + 1, h + 1):
            if deadline is not None and time.perf_counter() >= deadline:
                return False
            parts = [("step", (t,)), ("check", (t,))]
            parts += [(name, (t,)) for name in self._step_programs]
            self._ground(parts)
            self._horizon = t
            for ops, last in self._waiting_blocks.pop(t, ()):
                self._add_block(ops, last, t)
        return True

    def _add_step_program(self, name: str, text: str, data: str = "") -> None:
        """Add `#program name(t)`, ground it for t = 0..horizon in one call, and for every
        later step together with `step(t)`; `data` (facts the program joins with) is grounded
        once, in the same call."""
        self._ctl.add(name, ["t"], text)
        parts = [(name, (t,)) for t in range(0, self._horizon + 1)]
        if data:
            self._ctl.add(f"{name}_data", [], data)
            parts.insert(0, (f"{name}_data", ()))
        self._step_programs.append(name)
        self._ground(parts)

    # ---- constraints (bookkeeping in LearnedConstraints) ---------------------------------
    def _forbid_conflict(self, seqs) -> None:
        """One step program per learned conflict: `conflict_program` for a single sequence,
        `lifted_conflict_program` (one constraint over a table of instances) for several."""
        name = f"conflict_{sum(1 for n in self._step_programs if n.startswith('conflict_'))}"
        if len(seqs) == 1:
            self._add_step_program(name, conflict_program(name, seqs[0]))
        else:
            data, text = lifted_conflict_program(name, seqs)
            self._add_step_program(name, text, data)

    def _forbid_plan(self, ops: tuple[int, ...]) -> None:
        """The nogoods are added through clingo's backend (no grounding): `occurs(a_1, 1), ...,
        occurs(a_n, n), query(n)` for the horizon n, and `..., idle(n + 1)` for longer
        horizons with idle steps, the latter once step n + 1 exists."""
        n = len(ops)
        for t, last in ((n, "query"), (n + 1, "idle")):
            if t <= self._horizon:
                self._add_block(ops, last, t)
            else:
                self._waiting_blocks.setdefault(t, []).append((ops, last))

    def _add_block(self, ops: tuple[int, ...], last: str, t: int) -> None:
        syms = [clingo.Function("occurs", [clingo.Number(o), clingo.Number(i)])
                for i, o in enumerate(ops, start=1)]
        syms.append(clingo.Function(last, [clingo.Number(t)]))
        lits = []
        for sym in syms:
            atom = self._ctl.symbolic_atoms[sym]
            if atom is None:          # the atom can never be true: nothing to forbid
                return
            lits.append(atom.literal)
        with self._ctl.backend() as backend:
            backend.add_rule([], lits)

    # ---- solving -----------------------------------------------------------------------
    def _set_externals(self, query: int, cut: bool, idle: bool, minimize: bool) -> None:
        want: dict[clingo.Symbol, bool] = {
            clingo.Function("allow_idle"): idle,
            clingo.Function("minimize_cost"): minimize,
        }
        for t in range(0, self._horizon + 1):
            want[clingo.Function("query", [clingo.Number(t)])] = t == query
            if t >= 1:
                want[clingo.Function("after", [clingo.Number(t)])] = cut and t > query
        for sym, val in want.items():
            if self._externals.get(sym, False) != val:
                self._ctl.assign_external(sym, val)
                self._externals[sym] = val
        self._ctl.configuration.solve.opt_mode = "opt" if minimize else "ignore"

    def _solve(self, deadline: float | None, models: int = 1, limit: int | None = None):
        """One solve call; returns (status, list of model symbols (best last), proven optimal).

        Runs asynchronously and polls, so the time limit and Ctrl-C interrupt the search; the
        handle's context manager always closes the solve, leaving the control usable. With a
        `conflict_budget` (set by `shortest_plan`) clasp stops after that many conflicts
        (`--solve-limit`, a TIMEOUT like the time limit) and the budget shrinks by the
        conflicts the call used: a limit that does not depend on the machine's load. `limit`:
        clasp conflicts for this call alone (a TIMEOUT too when reached).
        """
        budget = self.conflict_budget
        cap = budget if limit is None else limit if budget is None else min(budget, limit)
        self._ctl.configuration.solve.solve_limit = "umax,umax" if cap is None else str(max(1, cap))
        found: list = []
        proven = [False]

        def on_model(model: clingo.Model) -> None:
            found.append(model.symbols(shown=True))
            proven[0] = model.optimality_proven

        self.stats.solve_calls += 1
        # when optimising, 0 = run to the proven optimum (each model improves the last)
        optimising = self._externals.get(clingo.Function("minimize_cost"), False)
        self._ctl.configuration.solve.models = 0 if optimising else models
        t0 = time.perf_counter()
        try:
            with interrupt.native(), self._ctl.solve(on_model=on_model, async_=True) as handle:
                while True:
                    wait = 0.05 if deadline is None else max(0.0, min(0.05, deadline - time.perf_counter()))
                    if handle.wait(wait):
                        break
                    if deadline is not None and time.perf_counter() >= deadline or interrupt.pending():
                        handle.cancel()       # a signal too (`gnppdsl.interrupt`): raised below
                        break
                result = handle.get()
        finally:
            self.stats.solve_time += time.perf_counter() - t0
        if self._statistics:
            self.stats.clingo_solve_time += self._ctl.statistics["summary"]["times"]["solve"]
        if cap is not None:
            used = int(self._ctl.statistics["solving"]["solvers"]["conflicts"])
            if budget is not None:
                self.conflict_budget = budget - used
            self.stats.conflicts += used
        if result.interrupted or not (result.satisfiable or result.unsatisfiable):
            return Status.TIMEOUT, found, False
        if result.satisfiable:
            return Status.FOUND, found, proven[0] or result.exhausted
        return Status.NO_PLAN, [], False

    def _plan_from(self, symbols, shortest: bool, optimal: bool) -> Plan:
        occ: dict[int, int] = {}
        holds: dict[int, dict[int, int]] = {}
        for s in symbols:
            if s.name == "occurs":
                occ[s.arguments[1].number] = s.arguments[0].number
            elif s.name == "holds":
                v, x, t = (a.number for a in s.arguments)
                holds.setdefault(t, {})[v] = x
        n = len(occ)
        assert sorted(occ) == list(range(1, n + 1)), f"non-contiguous plan steps {sorted(occ)}"
        ops = tuple(occ[t] for t in range(1, n + 1))
        nv = len(self.task.variables)
        states = tuple(tuple(holds[t][v] for v in range(nv)) for t in range(n + 1))
        return Plan(ops, tuple(self.task.operators[o].name for o in ops), states,
                    plan_cost(self.task, ops), shortest, optimal)

    @staticmethod
    def _deadline(time_limit: float | None) -> float | None:
        return None if time_limit is None else time.perf_counter() + time_limit

    def shortest_plan(self, max_horizon: int | None = None, time_limit: float | None = None,
                      minimize_cost: bool = False) -> PlanResult:
        """The shortest plan under all conflicts and blocked plans (not blocked by this call).

        With `minimize_cost` the cheapest among the shortest plans is returned.
        """
        return self._shortest(max_horizon, time_limit, minimize_cost, models=1)[0]

    def _shortest(self, max_horizon, time_limit, minimize_cost, models):
        start = time.perf_counter()
        deadline = self._deadline(time_limit)
        H = self.max_horizon if max_horizon is None else max_horizon
        self._raise_bound()
        h = self._lowest
        while h <= H:
            if deadline is not None and time.perf_counter() >= deadline \
                    or self.conflict_budget is not None and self.conflict_budget <= 0:
                return self._timeout(h, start, time_limit), []
            if not self._extend_to(h, deadline):
                return self._timeout(h, start, time_limit), []
            self._set_externals(query=h, cut=True, idle=False, minimize=minimize_cost)
            cheap = h < self._bound          # no plan here (the bound): a proof only while it is cheap
            status, found, proven = self._solve(deadline, 1 if minimize_cost else models,
                                                limit=CHEAP_CONFLICTS if cheap else None)
            if status is Status.TIMEOUT and cheap and not (
                    deadline is not None and time.perf_counter() >= deadline
                    or self.conflict_budget is not None and self.conflict_budget <= 0):
                self._lowest = h = self._bound
                continue
            if status is Status.FOUND:
                plans = [self._plan_from(m, shortest=True, optimal=False) for m in found]
                best = plans.pop()  # the last model (the optimum when minimising)
                if minimize_cost and proven:
                    best = replace(best, optimal=True)
                return PlanResult(Status.FOUND, best, h, time.perf_counter() - start,
                                  f"found a plan of length {h}"), plans
            if status is Status.TIMEOUT:
                return self._timeout(h, start, time_limit), []
            self._lowest = h = h + 1
        return PlanResult(Status.NO_PLAN, None, H, time.perf_counter() - start,
                          self._no_plan_message(H)), []

    def next_plan(self, max_horizon: int | None = None, time_limit: float | None = None,
                  minimize_cost: bool = False, batch: int = 32) -> PlanResult:
        """Enumerate plans in order of length, each once: the shortest plan, then blocked.

        One solve call returns up to `batch` distinct plans of the current horizon; the others
        are kept and handed out by later calls unless a conflict added meanwhile or an
        explicit `block_plan` excludes them (checked on their states). `minimize_cost`
        enumerates the cheapest plan of each length first (one plan per solve).
        """
        start = time.perf_counter()
        if not minimize_cost and self._cache_key[0] == self._lowest:
            fresh = self.conflicts[self._cache_key[1]:]
            while self._cache:
                plan = self._cache.pop()
                if plan.operators in self._blocked_set:
                    continue
                if any(find_sequence(plan.states, c) is not None for c in fresh):
                    continue
                self.block_plan(plan)
                return PlanResult(Status.FOUND, plan, len(plan), time.perf_counter() - start,
                                  f"found a plan of length {len(plan)}")
        result, more = self._shortest(max_horizon, time_limit, minimize_cost, batch)
        if result.plan is not None:
            self.block_plan(result.plan)
            self._cache = more[::-1]
            self._cache_key = (result.horizon, len(self.conflicts))
        return result

    def optimal_plan(self, horizon: int, time_limit: float | None = None,
                     cost_bound: float | None = None) -> PlanResult:
        """The cheapest plan of length <= `horizon` (operator costs + pair costs).

        `plan.optimal` says whether clingo proved optimality before the time limit; a plan
        found before the limit is returned even when not proven. `cost_bound` admits only
        plans of cost <= the bound (clasp's initial optimisation bound, `--opt-mode=opt,B`):
        NO_PLAN then proves that no plan of length <= `horizon` costs that little (the anytime
        search of `gnppdsl.solve.anytime` reads it as its proof of optimality). The bound is in
        the task's cost units (`Operator.cost`); clasp sees it in the encoding's integers
        (`SASTask.cost_scale`), widened by the rounding of up to `horizon` operator costs so
        that no plan within the bound is cut.
        """
        start = time.perf_counter()
        deadline = self._deadline(time_limit)
        if self._extend_to(horizon, deadline):
            self._set_externals(query=horizon, cut=False, idle=True, minimize=True)
            if cost_bound is not None:
                scale = self.task.cost_scale()
                slack = 0.0 if scale == 1 else 0.5 * horizon
                self._ctl.configuration.solve.opt_mode = f"opt,{math.floor(cost_bound * scale + slack + 1e-9)}"
            status, found, proven = self._solve(deadline)
        else:
            status, found, proven = Status.TIMEOUT, [], False
        elapsed = time.perf_counter() - start
        if found:
            plan = self._plan_from(found[-1], shortest=False, optimal=status is Status.FOUND and proven)
            note = "optimal" if plan.optimal else "best found before the time limit (not proven optimal)"
            return PlanResult(Status.FOUND, plan, horizon, elapsed,
                              f"plan of length {len(plan)} and cost {plan.cost}, {note}")
        if status is Status.TIMEOUT:
            return PlanResult(Status.TIMEOUT, None, horizon, elapsed,
                              f"time limit of {time_limit:g} s reached before any plan of length "
                              f"<= {horizon} was found for task {self.task.name}")
        bound = "" if cost_bound is None else f" with cost <= {cost_bound}"
        return PlanResult(Status.NO_PLAN, None, horizon, elapsed, self._no_plan_message(horizon) + bound)

    # ---- messages ----------------------------------------------------------------------
    def _no_plan_message(self, H: int) -> str:
        return f"no plan up to horizon {H} for task {self.task.name}{self._under()}"

    def _timeout(self, h: int, start: float, limit: float | None) -> PlanResult:
        what = "the conflict budget ran out" if self.conflict_budget is not None and self.conflict_budget <= 0 \
            else f"time limit of {limit:g} s reached"
        return PlanResult(Status.TIMEOUT, None, h, time.perf_counter() - start,
                          f"{what} at horizon {h} for task {self.task.name} (no plan shorter than {h})")
