"""Logic modes (sequential, fd, auto) against oracles that share no code with them.

- `forbid_plan` (a blocked plan compiled into the task) against brute-force enumeration:
  exactly the blocked operator sequence disappears;
- every plan of every mode, with and without conflicts and blocked plans, is run through the
  naive SAS+ interpreter of tests/compile/sas_semantics.py (applicability, goal) and checked
  for the conflicts by hand (Proposition 7.1: no s_i ⊇ p_0, ..., s_{i+L} ⊇ p_L);
- modes that promise shortest plans (sequential, auto before it switches) agree with brute
  force / uniform-cost search on the compiled task; fd finds a plan within the horizon exactly
  when brute force does (its "no plan up to H" is a proof).
"""
from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "compile"))
import sas_semantics as naive  # noqa: E402
from logic_brute import all_plans  # noqa: E402
from logic_fd import require_fd  # noqa: E402
from planner_oracle import check_answer, naive_check  # noqa: E402

from gnppdsl.logic.generators import grid_task, random_conflicts, random_task, tower_task  # noqa: E402
from gnppdsl.logic.modes import AutoPlanner, make_planner  # noqa: E402
from gnppdsl.logic.reformulation import forbid_plan, forbid_sequences  # noqa: E402

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def test_forbid_plan_removes_exactly_that_plan():
    rng = random.Random(5)
    checked = 0
    for _ in range(15):
        task = random_task(rng, n_ops=5)
        plans = all_plans(task, 4)
        if not plans:
            continue
        for ops in sorted(plans)[:3]:
            assert all_plans(forbid_plan(task, ops), 4) == plans - {ops}
            checked += 1
        # a sequence that is no plan: nothing changes
        assert all_plans(forbid_plan(task, (0, 0, 0, 0, 0)), 4) == plans
    assert checked >= 10


@pytest.mark.parametrize("mode", ["sequential", "fd", "auto"])
def test_modes_agree_with_brute_force_under_conflicts(mode):
    if mode != "sequential":
        require_fd()
    rng = random.Random(11)
    found = none = 0
    for _ in range(25):
        task = random_task(rng, n_ops=6)
        conflicts = random_conflicts(task, rng, rng.randint(0, 3), walk_length=5)
        H = 5
        plans = all_plans(task, H, conflicts)
        planner = make_planner(task, mode, max_horizon=H)
        planner.add_conflicts(conflicts)
        res = check_answer(task, planner, plans, conflicts, exact=mode != "fd")
        if res is None:
            none += 1
            continue
        assert len(res.plan.states) == len(res.plan) + 1
        found += 1
        # block the plan: the next one is another plan, or none if it was the only one
        planner.block_plan(res.plan)
        again = planner.shortest_plan(time_limit=30)
        rest = plans - {res.plan.operators}
        assert again.found == bool(rest)
        if again.found:
            naive_check(task, again.plan.operators, conflicts, [res.plan.operators])
    assert found >= 10 and none >= 1


def test_fd_plans_validate_on_the_compiled_task_too():
    """FD's plan is a plan of the Appendix-B task (checked by the naive interpreter there)."""
    require_fd()
    rng = random.Random(3)
    for _ in range(10):
        task = random_task(rng, n_ops=7)
        conflicts = random_conflicts(task, rng, 2, walk_length=5)
        planner = make_planner(task, "fd", max_horizon=6)
        planner.add_conflicts(conflicts)
        res = planner.shortest_plan(time_limit=30)
        if res.found:
            naive_check(forbid_sequences(task, conflicts), res.plan.operators)


def test_auto_switches_to_fast_downward_and_keeps_the_conflicts():
    require_fd()
    task = grid_task(3, 3, 2)
    auto = AutoPlanner(task, max_horizon=14, switch_after=0.0)
    first = auto.shortest_plan(time_limit=30)
    assert auto.mode == "fd" and first.found
    naive_check(task, first.plan.operators)
    # Fast Downward's plan is shortest only when its bounded searches proved it (`_tighten`)
    assert not first.plan.shortest or len(first.plan) == naive.optimal_cost(task)
    # a conflict that the first plan contains: the facts its first step changes (grid worlds
    # have detours around them)
    from gnppdsl.compile.sas import PartialState

    s0, s1 = first.plan.states[0], first.plan.states[1]
    conflict = (PartialState(tuple((v, s1[v]) for v in range(len(s1)) if s1[v] != s0[v])),)
    assert auto.add_conflict(conflict)
    second = auto.shortest_plan(time_limit=30)
    optimum = naive.optimal_cost(forbid_sequences(task, [conflict]))   # unit costs: a length
    assert second.found == (optimum is not None and optimum <= 14), second.message
    exact = AutoPlanner(task, max_horizon=14, switch_after=60.0)
    exact.add_conflict(conflict)
    best = exact.shortest_plan(time_limit=60)
    assert exact.mode == "sequential" and best.found == second.found
    if second.found:
        naive_check(task, second.plan.operators, [conflict])
        assert best.plan.shortest and len(best.plan) == optimum <= len(second.plan)


def test_unknown_mode_and_missing_fd_are_user_errors(monkeypatch):
    from gnppdsl.errors import UserError
    from gnppdsl.logic import modes

    with pytest.raises(ValueError, match="unknown planner"):
        make_planner(tower_task(2), "fastest")
    monkeypatch.setattr(modes, "downward_binary", lambda: None)
    with pytest.raises(UserError, match="up-fast-downward"):
        make_planner(tower_task(2), "fd")
    assert make_planner(tower_task(2), "auto").shortest_plan().found   # auto: sequential only


def _family_task(name: str):
    from gnppdsl.compile.task import build_task
    from gnppdsl.ir import load_problem

    return build_task(load_problem(EXAMPLES / "scalability" / f"{name}.pntc"))


@pytest.mark.parametrize("name,n0", [("stack_4", 4), ("lab4_paper", 4)])
def test_scalability_family_n0_exact_and_fd(name, n0):
    """The exact mode gives the family's N0 (expected.yaml); Fast Downward a valid plan."""
    require_fd()
    task = _family_task(name)
    res = make_planner(task, "sequential", max_horizon=20).shortest_plan(time_limit=60)
    assert res.found and len(res.plan) == n0 and res.plan.shortest
    naive_check(task, res.plan.operators)
    fd = make_planner(task, "fd", max_horizon=20).shortest_plan(time_limit=60)
    assert fd.found and len(fd.plan) >= n0
    naive_check(task, fd.plan.operators)


FAMILY = ["stack_8", "stack_16", "stack_32", "clutter_1", "clutter_6", "lab5_paper"]


@pytest.mark.slow
@pytest.mark.parametrize("name", FAMILY)
def test_scalability_families_first_plan(name):
    """auto and fd give a plan of the family's N0 length or more, valid under the naive SAS+
    semantics; with a GNPP-style conflict (the first step's changed facts) the next plan avoids it."""
    require_fd()
    import yaml

    from gnppdsl.compile.sas import PartialState

    n0 = yaml.safe_load((EXAMPLES / "scalability" / "expected.yaml").read_text())["problems"][name]["n0"]
    task = _family_task(name)
    for mode in ("auto", "fd"):
        planner = make_planner(task, mode, max_horizon=n0 + 8)
        res = planner.shortest_plan(time_limit=120)
        assert res.found and len(res.plan) >= n0, res.message
        naive_check(task, res.plan.operators)
        s0, s1 = res.plan.states[0], res.plan.states[1]
        conflict = (PartialState(tuple((v, s1[v]) for v in range(len(s1)) if s1[v] != s0[v])),)
        planner.add_conflict(conflict)
        again = planner.shortest_plan(time_limit=120)
        assert again.found, again.message
        naive_check(task, again.plan.operators, [conflict])


class _StalledFD:
    """A Fast Downward planner whose search never answers within its turn (lab5_paper's stall
    before forbidden transitions): every call is a time limit; it records the turns it got."""

    def __init__(self, task, max_horizon=None, **_):
        from gnppdsl.logic.planner import PlannerStats

        self.task, self.stats, self.horizon, self.limits = task, PlannerStats(), 0, []
        self.learned, self.blocked = [], []

    def add_lifted(self, seqs):
        self.learned.append(tuple(seqs))
        return len(self.learned[-1])

    def block_plan(self, ops):
        self.blocked.append(tuple(getattr(ops, "operators", ops)))
        return True

    def shortest_plan(self, max_horizon=None, time_limit=None, tighten_limit=None):
        from gnppdsl.logic.planner import PlanResult, Status

        self.limits.append(time_limit)      # the turn (bounded searches after a plan: none here)
        return PlanResult(Status.TIMEOUT, None, 0, 0.0, "stalled")


def test_auto_alternates_so_a_stalled_fast_downward_cannot_stall_the_solve(monkeypatch):
    """After the switch, a Fast Downward search that never answers gets one turn, then clingo
    (holding every conflict) answers with a shortest plan; turns double while both time out,
    and the call's time limit caps the last turn. Before the alternation the call returned
    Fast Downward's time limit (a whole solve lost, issue 19)."""
    from gnppdsl.compile.sas import PartialState
    from gnppdsl.logic import modes
    from gnppdsl.logic.planner import Status

    monkeypatch.setattr(modes, "downward_binary", lambda: Path("downward"))
    monkeypatch.setattr(modes, "FastDownwardPlanner", _StalledFD)
    task = grid_task(3, 3, 2)
    auto = AutoPlanner(task, max_horizon=14, switch_after=0.0)
    first = auto.shortest_plan(time_limit=60)
    assert auto.mode == "fd" and first.found and first.plan.shortest, first.message
    assert auto.fd.limits == [modes.FD_SLICE] and "clingo" in first.message
    s0, s1 = first.plan.states[0], first.plan.states[1]
    conflict = (PartialState(tuple((v, s1[v]) for v in range(len(s1)) if s1[v] != s0[v])),)
    assert auto.add_conflict(conflict) and auto.fd.learned[-1] == (conflict,)
    second = auto.shortest_plan(time_limit=60)
    optimum = naive.optimal_cost(forbid_sequences(task, [conflict]))
    assert second.found == (optimum is not None and optimum <= 14), second.message
    if second.found:
        naive_check(task, second.plan.operators, [conflict])
        assert second.plan.shortest and len(second.plan) == optimum

    # both time out for a while: turns double (FD, clingo, FD, clingo, ...), the limit caps them
    real = auto.sequential.shortest_plan
    calls = []

    def slow_clingo(max_horizon=None, time_limit=None, minimize_cost=False):
        calls.append(time_limit)
        if len(calls) <= 2:
            return modes.PlanResult(Status.TIMEOUT, None, 0, 0.0, "slow")
        return real(max_horizon, time_limit, minimize_cost)

    monkeypatch.setattr(auto.sequential, "shortest_plan", slow_clingo)
    auto.fd.limits.clear()
    auto.fd_slice = 1.0
    third = auto.shortest_plan(time_limit=1000)
    assert third.status is second.status
    assert auto.fd.limits == [1.0, 2.0, 4.0] and calls == [1.0, 2.0, 4.0]
    calls.clear()
    auto.fd.limits.clear()
    fourth = auto.shortest_plan(time_limit=0.0)         # no time left: no turn at all
    assert fourth.status is Status.TIMEOUT and not calls and not auto.fd.limits
