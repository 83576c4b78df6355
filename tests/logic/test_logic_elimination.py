"""Action elimination (`gnppdsl.logic.elimination`) against brute force and the naive SAS+
interpreter (tests/compile/sas_semantics.py): every plan it returns is a plan of the task,
avoids every conflict (Proposition 7.1) and every blocked plan, is a subsequence of the input
and no longer; redundant detours are dropped; Fast Downward's plans go through it."""
from __future__ import annotations

import random
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from logic_brute import all_plans  # noqa: E402
from logic_fd import require_fd  # noqa: E402
from planner_oracle import naive_check  # noqa: E402

from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.logic.elimination import eliminate_actions  # noqa: E402
from gnppdsl.logic.fd_planner import FastDownwardPlanner  # noqa: E402
from gnppdsl.logic.generators import random_conflicts, random_task, tower_task  # noqa: E402
from gnppdsl.logic.planner import Status  # noqa: E402


def _is_subsequence(short, long) -> bool:
    it = iter(long)
    return all(any(o == p for p in it) for o in short)


def random_cases(rng: random.Random, n: int, max_conflicts: int):
    """`n` random tasks with up to `max_conflicts` random conflicts, each with its plans up to
    length 6 under those conflicts (brute force); tasks without a plan are left out. The caller
    goes on drawing from the same `rng`."""
    for _ in range(n):
        task = random_task(rng, n_ops=6)
        conflicts = random_conflicts(task, rng, rng.randint(0, max_conflicts), walk_length=5)
        plans = all_plans(task, 6, conflicts)
        if plans:
            yield task, conflicts, plans


def test_elimination_against_brute_force_with_conflicts_and_blocked_plans():
    rng = random.Random(19)
    shortened = kept = 0
    for task, conflicts, plans in random_cases(rng, 40, 3):
        # block some of the short plans: elimination must not shorten into them
        shortest = sorted(plans, key=len)
        blocked = set(rng.sample(shortest[:6], min(len(shortest), rng.randint(0, 3))))
        for ops in rng.sample(sorted(plans), min(len(plans), 8)):
            out = eliminate_actions(task, ops, conflicts, blocked)
            naive_check(task, out, conflicts, blocked - {ops})
            assert out in plans                       # a plan under the conflicts (brute force)
            assert len(out) <= len(ops) and _is_subsequence(out, ops)
            assert out == ops or out not in blocked
            # greedy elimination's fixpoint: no single step of the result can be dropped
            # (with the later steps that no longer apply) into another allowed plan
            if out != ops:
                shortened += 1
                assert eliminate_actions(task, out, conflicts, blocked) == out
            else:
                kept += 1
    assert shortened >= 10 and kept >= 10


def test_elimination_keeps_conflicts_that_only_the_shorter_plan_would_meet():
    """The shortened plan passes states the original did not; a conflict on them keeps the
    original (brute force: the only plans left are the long ones)."""
    rng = random.Random(3)
    checked = 0
    for _ in range(60):
        task = random_task(rng, n_ops=6)
        plans = all_plans(task, 5)
        long = [p for p in plans if eliminate_actions(task, p) != p]
        if not long:
            continue
        ops = long[0]
        short = eliminate_actions(task, ops)
        # forbid the shortened plan's final transition states (a conflict of its last two states)
        states = naive_check(task, short)
        seq = tuple(PartialState(tuple(enumerate(s))) for s in states[-2:]) if len(short) else \
            (PartialState(tuple(enumerate(states[0]))),)
        allowed = all_plans(task, 5, [seq])
        out = eliminate_actions(task, ops, [seq])
        assert short not in allowed
        assert out != short
        if ops in allowed:
            assert out in allowed and len(out) <= len(ops)
            naive_check(task, out, [seq])
        checked += 1
    assert checked >= 5


def test_redundant_detour_is_dropped():
    """A 2-block tower plan with an unstack / restack detour inserted: elimination finds the
    shortest plan again."""
    task = tower_task(2)
    plans = all_plans(task, 6)
    best = min(plans, key=len)
    padded = [p for p in plans if len(p) >= len(best) + 2]
    assert padded
    for p in padded:
        out = eliminate_actions(task, p)
        naive_check(task, out)
        assert len(out) < len(p)


def test_fast_downward_plans_are_shortened(monkeypatch):
    """FastDownwardPlanner hands the loop the eliminated plan (fails without elimination: FD's
    plan is replaced here by a valid plan with a detour)."""
    require_fd()
    task = tower_task(2)
    plans = all_plans(task, 6)
    best = min(plans, key=len)
    padded = max(plans, key=len)
    assert len(padded) > len(best)
    planner = FastDownwardPlanner(task, max_horizon=10, tighten=0)
    monkeypatch.setattr(planner, "_run", lambda horizon, limit, cpu_limit=None: (Status.FOUND, list(padded)))
    res = planner.shortest_plan()
    assert res.found
    naive_check(task, res.plan.operators)
    assert len(res.plan) < len(padded)
    assert planner.eliminated == [(len(padded), len(res.plan))]
    # with a blocked plan and a conflict the result stays allowed
    planner.block_plan(res.plan)
    res2 = planner.shortest_plan()
    naive_check(task, res2.plan.operators, blocked=planner.blocked)
    assert len(res2.plan) <= len(padded)


def _first_answer_padded(planner, padded):
    """FD's first search of each call answers `padded`; the bounded searches after it are real."""
    real = planner._run
    calls = []

    def run(horizon, limit, cpu_limit=None, search=None):
        calls.append(horizon)
        if cpu_limit is None:
            return Status.FOUND, list(padded)
        return real(horizon, limit, cpu_limit, search=search)
    planner._run = run
    return calls


def test_bounded_searches_find_the_shortest_plan_and_prove_it():
    """`_tighten`: FD searched again below the plan's length reaches brute force's shortest
    length under conflicts and blocked plans, and its "no plan" proves it (Plan.shortest);
    without it (tighten = 0) the long plan stays."""
    require_fd()
    rng = random.Random(7)
    checked = 0
    for task, conflicts, plans in random_cases(rng, 30, 2):
        shortest = min(len(p) for p in plans)
        blocked = [p for p in plans if len(p) == shortest][:1] if rng.random() < 0.5 else []
        allowed = plans - set(blocked)
        if not allowed:
            continue
        best = min(len(p) for p in allowed)
        padded = max(allowed, key=len)
        if len(padded) == best:
            continue
        for tighten in (0, 5.0):
            planner = FastDownwardPlanner(task, max_horizon=6, eliminate=False, tighten=tighten)
            for c in conflicts:
                planner.add_conflict(c)
            for b in blocked:
                planner.block_plan(b)
            _first_answer_padded(planner, padded)
            res = planner.shortest_plan(time_limit=60)
            naive_check(task, res.plan.operators, conflicts, blocked)
            if tighten:
                assert len(res.plan) == best and res.plan.shortest
                assert planner.tightened[-1][1] == "no plan"
            else:
                assert res.plan.operators == padded and not res.plan.shortest
        checked += 1
    assert checked >= 5


def test_lower_bound_ends_the_bounded_searches():
    """A plan as long as the lower bound (auto: the horizon clingo proved empty below) is
    shortest without another search."""
    require_fd()
    task = tower_task(2)
    best = min(len(p) for p in all_plans(task, 4))
    planner = FastDownwardPlanner(task, max_horizon=10)
    planner.lower_bound = best
    res = planner.shortest_plan()
    assert len(res.plan) == best and res.plan.shortest and planner.tightened == []


def _reference(task, ops, conflicts=(), blocked=()):
    """The elimination as first written: each candidate replayed from s_0, then validated."""
    from gnppdsl.logic.validate import applicable, initial_state, successor, validate_plan

    def without(plan, drop):
        state, kept = initial_state(task), []
        for j, o in enumerate(plan):
            if j == drop:
                continue
            op = task.operators[o]
            if not applicable(op, state):
                continue
            try:
                state = successor(task, state, op)
            except ValueError:
                continue
            kept.append(o)
        return kept

    plan, changed = list(ops), True
    while changed:
        changed, i = False, 0
        while i < len(plan):
            cand = without(plan, i)
            if len(cand) < len(plan) and tuple(cand) not in blocked and validate_plan(task, cand, conflicts).valid:
                plan, changed = cand, True
                continue
            i += 1
    return tuple(plan)


def test_elimination_replays_each_candidate_once_from_its_dropped_step(monkeypatch):
    """Same result as the elimination that replayed every candidate from s_0 and validated it
    again, with fewer derived states (each successor re-derives the axioms; stack_32: 64
    candidates of 32 steps per plan, ~4000 states)."""
    from gnppdsl.compile import semantics

    rng = random.Random(7)
    calls = [0]
    real = semantics.derive

    def counted(*a):
        calls[0] += 1
        return real(*a)

    monkeypatch.setattr(semantics, "derive", counted)
    compared = new = old = 0
    for task, conflicts, plans in random_cases(rng, 30, 2):
        for ops in rng.sample(sorted(plans), min(len(plans), 4)):
            calls[0] = 0
            expected = _reference(task, ops, conflicts)
            old += calls[0]
            calls[0] = 0
            out = eliminate_actions(task, ops, conflicts)
            new += calls[0]
            assert out == expected
            compared += 1
    assert compared >= 20 and new < 0.75 * old, (new, old)


def test_a_bounded_search_that_ran_out_is_not_repeated_at_the_same_bound():
    """`_tighten`: after a bounded search timed out at bound b, the next call whose plan has
    length b + 1 does not search at b again (the base searched again, a second full budget);
    a plan of another length is still tightened."""
    require_fd()
    task = tower_task(3)
    plans = all_plans(task, 6)
    four = min(plans, key=len)
    six = next(p for p in plans if len(p) == 6)
    assert len(four) == 4
    planner = FastDownwardPlanner(task, max_horizon=10, eliminate=False)
    bounded = []

    def run(horizon, limit, cpu_limit=None, search=None):
        if cpu_limit is None:
            planner.fd_cpu += 0.1
            return Status.FOUND, list(answer[0])
        bounded.append(horizon)
        planner.fd_cpu += cpu_limit
        return Status.TIMEOUT, []
    planner._run = run
    answer = [four]
    planner.shortest_plan()
    assert bounded == [3] and planner.tightened[-1] == (4, "time limit", 0)
    planner.shortest_plan()
    assert bounded == [3] and planner.tightened[-1] == (4, "skipped", 0)
    answer[0] = six
    planner.shortest_plan()
    assert bounded == [3, 5]
