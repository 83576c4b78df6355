"""Lifted conflicts in every logic mode (`LearnedConstraints.add_lifted`): a group of instances
learned as one conflict forbids exactly the plans brute force finds forbidden by the instances
one by one (Proposition 7.1 per instance), in clingo (one parameterised constraint over a table
of instances, `lifted_conflict_program`) and Fast Downward (Appendix B per instance)."""
from __future__ import annotations

import random
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from logic_brute import all_plans  # noqa: E402
from logic_fd import require_fd  # noqa: E402
from planner_oracle import check_answer  # noqa: E402

from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.logic.encoding import lifted_conflict_program  # noqa: E402
from gnppdsl.logic.generators import random_conflicts, random_task  # noqa: E402
from gnppdsl.logic.modes import make_planner  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner  # noqa: E402


def groups(task, rng, count):
    """Random groups of instances of one length (the shape of a lifted conflict), facts drawn
    from random walks as the Graph-NLP Planner's conflicts are."""
    pool = random_conflicts(task, rng, 12, walk_length=5)
    by_len: dict[int, list] = {}
    for c in pool:
        by_len.setdefault(len(c), []).append(c)
    out = []
    for seqs in by_len.values():
        rng.shuffle(seqs)
        out.append(seqs[:rng.randint(1, 4)])
    return out[:count]


@pytest.mark.parametrize("mode", ["sequential", "fd"])
def test_lifted_groups_forbid_exactly_their_instances(mode):
    if mode != "sequential":
        require_fd()
    rng = random.Random(19)
    found = none = lifted = 0
    for _ in range(30):
        task = random_task(rng, n_ops=6)
        learned = groups(task, rng, rng.randint(1, 2))
        instances = [c for g in learned for c in g]
        H = 5
        plans = all_plans(task, H, instances)
        planner = make_planner(task, mode, max_horizon=H)
        for g in learned:
            before = set(planner.conflicts)
            assert planner.add_lifted(g) == len(set(g) - before)
            lifted += len(g) > 1
        assert len(planner.learned) == len(learned)
        assert set(planner.conflicts) == set(instances)
        assert planner.add_lifted(learned[0]) == 0                # known: nothing new, not counted
        assert len(planner.learned) == len(learned)
        if check_answer(task, planner, plans, instances, exact=mode == "sequential") is None:
            none += 1
            continue
        found += 1
    assert found >= 8 and none >= 1 and lifted >= 5


def test_lifted_program_is_one_rule_per_shape():
    a = (PartialState(((0, 1),)), PartialState(((2, 0),)))
    b = (PartialState(((1, 1),)), PartialState(((3, 0),)))
    c = (PartialState(((1, 1), (4, 2))), PartialState())
    data, text = lifted_conflict_program("k", [a, b, c])
    assert data.splitlines() == ["k_0(0,1,2,0).", "k_0(1,1,3,0).", "k_1(1,1,4,2)."]
    rules = [line for line in text.splitlines() if line.startswith(":-")]
    assert len(rules) == 2
    assert rules[0] == ":- k_0(V0,X0,V1,X1), holds(V0,X0,t-1), holds(V1,X1,t), not idle(t), t >= 1."
    with pytest.raises(ValueError):
        lifted_conflict_program("k", [a, (PartialState(),)])


def test_lifted_conflict_grounds_like_one_conflict():
    rng = random.Random(3)
    task = random_task(rng, n_vars=5, n_ops=10)
    planner = IncrementalPlanner(task)
    planner.shortest_plan(max_horizon=4)
    g = [c for c in random_conflicts(task, rng, 10, walk_length=6) if len(c) == 1][:3]
    assert len(g) >= 2
    calls = planner.stats.ground_calls
    assert planner.add_lifted(g) == len(g)
    assert planner.stats.ground_calls == calls + 1            # data and all steps in one call
