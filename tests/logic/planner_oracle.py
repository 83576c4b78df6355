"""A planner's answer checked against brute force and the naive SAS+ interpreter
(tests/compile/sas_semantics.py), which share no code with the encodings or the validator:
what every mode test (plain conflicts, lifted conflicts, blocked plans) asserts the same way."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "compile"))
import sas_semantics as naive  # noqa: E402

from logic_brute import shortest_length  # noqa: E402

from gnppdsl.logic.planner import Status  # noqa: E402


def naive_check(task, ops, conflicts=(), blocked=()):
    """The plan reaches the goal under the naive semantics and avoids every conflict."""
    states = [naive.initial(task)]
    for o in ops:
        nxt = naive.successor(task, states[-1], o)
        assert nxt is not None, f"{task.operators[o].name} not applicable"
        states.append(nxt)
    assert naive.is_goal(task, states[-1])
    for seq in conflicts:
        for i in range(len(states) - len(seq) + 1):
            assert not all(all(states[i + l][v] == x for v, x in p.facts) for l, p in enumerate(seq)), \
                f"conflict {seq} occurs at {i}"
    assert tuple(ops) not in set(blocked)
    return states


def check_answer(task, planner, plans, conflicts, exact: bool, time_limit: float = 30):
    """Ask `planner` for a plan and check it against `plans` (brute force, conflicts applied):
    "no plan" exactly when there is none; else a plan under the naive semantics that avoids
    every conflict, of the shortest length when the mode is `exact`. The result, or None when
    no plan exists."""
    res = planner.shortest_plan(time_limit=time_limit)
    if not plans:
        assert res.status is Status.NO_PLAN
        return None
    assert res.found, res.message
    naive_check(task, res.plan.operators, conflicts)
    if exact:
        assert len(res.plan) == shortest_length(plans)
    return res
