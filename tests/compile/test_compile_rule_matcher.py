"""Rules grounded on demand (`RuleMatcher`) against eager grounding (`ground_rules`, every
binding, then filtered by `p ⊆ s_i` and `p' ⊆ s_{i+1}`): the same ground rules, in the same
order, at every step of random state sequences of every bundled example: reachable ones (random
walks through the SAS+ operators) and arbitrary ones (random values, derived variables from the
axioms), which exercise patterns no plan of the examples reaches."""
from __future__ import annotations

import random
from pathlib import Path

import pytest

from gnppdsl.compile.ground import RuleMatcher, ground_rules
from gnppdsl.compile.semantics import applicable, derive, initial_state, successor
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem

ROOT = Path(__file__).resolve().parents[2]
PROBLEMS = sorted(str(p.relative_to(ROOT)) for d in ("planar", "lab", "mobile")
                  for p in (ROOT / "examples" / d).glob("*.pntc") if p.name != "domain.pntc")


def eager_matching(rules, states, i):
    n = len(states) - 1
    out = []
    for gr in rules:
        if gr.post is not None:
            if i == n or not (gr.pre.holds_in(states[i]) and gr.post.holds_in(states[i + 1])):
                continue
        elif not gr.pre.holds_in(states[i]):
            continue
        out.append(gr)
    return out


def random_walk(task, rng, length):
    state = initial_state(task)
    states = [state]
    for _ in range(length):
        ops = [op for op in task.operators if applicable(op, state)]
        if not ops:
            break
        state = successor(task, state, rng.choice(ops))
        states.append(state)
    return states


def random_states(task, rng, length):
    out = []
    for _ in range(length + 1):
        raw = [0 if v.is_derived else rng.randrange(len(v.values)) for v in task.variables]
        out.append(derive(task, raw))
    return out


@pytest.mark.parametrize("path", PROBLEMS)
def test_rules_on_demand_equal_eager_grounding(path):
    problem = load_problem(ROOT / path)
    task = build_task(problem)
    eager = ground_rules(problem, task)
    lazy = RuleMatcher(problem, task)
    rng = random.Random(path)
    checked = 0
    for k in range(6):
        states = random_walk(task, rng, 6) if k % 2 == 0 else random_states(task, rng, 3)
        for i in range(len(states)):
            want = eager_matching(eager, states, i)
            got = [gr for _, gr in lazy.matching(states, i)]
            assert got == want, (path, k, i)
            checked += len(want)
    assert checked > 0
    # a ground rule is made once: the same key gives the same object on every step
    keys = {}
    for i in range(len(states)):
        for key, gr in lazy.matching(states, i):
            assert keys.setdefault(key, gr) is gr
