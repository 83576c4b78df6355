"""A conflict of two partial states compiled as a forbidden transition (`forbid_transition`)
keeps exactly the plans of Proposition 7.1: checked against brute-force enumeration from the
SAS+ semantics on the original task (tests/logic/logic_brute.py), alone, mixed with Appendix B
and blocked plans, under fd_guidance's copies, and through the Fast Downward planner, whose
compiled task must not put conditional effects on every operator for such a conflict (Appendix
B's b_0 did: 88 per operator on lab5_paper, 3 ms per FF evaluation, issue 19)."""
from __future__ import annotations

import random
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))
from fd_brute import fd_agrees_with_brute_force  # noqa: E402
from logic_brute import all_plans  # noqa: E402

from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.logic.fd_guidance import guide  # noqa: E402
from gnppdsl.logic.generators import grid_task, random_conflicts, random_task, tower_task  # noqa: E402
from gnppdsl.logic.reformulation import forbid_compact, forbid_plan, forbid_transition, transition_conditions  # noqa: E402


def _state_facts_only(task, seq):
    """<p_0, p_1> with p_1's derived facts dropped (a derived p_1 is left to Appendix B)."""
    p0, p1 = seq
    return (p0, PartialState(tuple((v, x) for v, x in p1.facts if not task.variables[v].is_derived)))


def _pick(task, pool, depth, most):
    """Up to `most` conflicts of `pool`, each removing some but not all of the plans left."""
    chosen: list = []
    plans = all_plans(task, depth)
    for seq in pool:
        left = all_plans(task, depth, chosen + [seq])
        if left and left != plans:
            chosen.append(seq)
            plans = left
        if len(chosen) == most:
            break
    return chosen


def cases():
    rng = random.Random(7)
    for k in range(40):
        task = random_task(rng, n_vars=4, n_ops=6, conditional=0.3 if k % 2 else 0.0)
        pool = random_conflicts(task, rng, 16, max_len=2, walk_length=5)
        pairs = [_state_facts_only(task, c) for c in pool if len(c) == 2]
        others = [c for c in pool if len(c) != 2]
        conflicts = _pick(task, others[:1] + pairs if k % 3 == 0 else pairs, 4, rng.randint(1, 3))
        if conflicts:
            yield task, conflicts, 4
    for _ in range(6):
        task = grid_task(3, 2, 1, rng)
        pool = random_conflicts(task, rng, 12, max_len=2, max_facts=2, walk_length=8)
        conflicts = _pick(task, [_state_facts_only(task, c) for c in pool if len(c) == 2], 5, 3)
        if conflicts:
            yield task, conflicts, 5


def test_transitions_keep_exactly_the_plans_of_proposition_7_1():
    transitions = compared = forbidden = 0
    for task, conflicts, depth in cases():
        compiled, heads = forbid_compact(task, conflicts)
        transitions += heads.count(None)
        expected = all_plans(task, depth, conflicts)
        assert all_plans(compiled, depth) == expected
        compared += len(expected)
        forbidden += len(all_plans(task, depth)) - len(expected)
        # alone, the transition form is exactly the conflict
        for seq in conflicts:
            single = forbid_transition(task, seq)
            if single is not None:
                assert all_plans(single, depth) == all_plans(task, depth, [seq])
    assert transitions >= 40 and compared >= 50 and forbidden >= 50


def test_the_transition_form_adds_no_conditional_effect_and_no_state_variable():
    task = tower_task(3)
    pick = next(o for o in task.operators if any(e.conditions == () for e in o.effects))
    v, x = pick.effects[0].var, pick.effects[0].value
    before = next(y for y in range(len(task.variables[v].values)) if y != x)
    seq = (PartialState(((v, before),)), PartialState(((v, x),)))
    compiled = forbid_transition(task, seq)
    assert compiled is not None
    assert [len(op.effects) for op in compiled.operators] == [len(op.effects) for op in task.operators]
    new = compiled.variables[len(task.variables):]
    assert new and all(var.is_derived for var in new)
    assert compiled.goal == task.goal


def test_undecided_transitions_fall_back_to_appendix_b():
    rng = random.Random(3)
    fell_back = 0
    for _ in range(30):
        task = random_task(rng, n_vars=3, n_ops=5, conditional=1.0)
        for seq in random_conflicts(task, rng, 6, max_len=3, walk_length=5):
            decided = transition_conditions(task, seq) is not None
            if len(seq) != 2 or any(task.variables[v].is_derived for v, _ in seq[1].facts):
                assert not decided
            fell_back += not decided
            compiled, heads = forbid_compact(task, [seq])
            assert (heads[0] is None) == decided
            assert all_plans(compiled, 3) == all_plans(task, 3, [seq])
    assert fell_back >= 20


def test_guided_mixed_compilations_keep_exactly_the_plans():
    """Transitions, Appendix B and a blocked plan in one task, then fd_guidance's copies (with
    the heads of each compilation): the plans are still those of the brute force."""
    checked = 0
    for task, conflicts, depth in cases():
        expected = all_plans(task, depth, conflicts)
        if not expected:
            continue
        blocked = min(expected)
        compiled, heads = forbid_compact(forbid_plan(task, blocked), conflicts)
        guided, origin = guide(compiled, conflicts, heads)
        got = {tuple(origin[o] for o in plan) for plan in all_plans(guided, depth)}
        assert got == expected - {blocked}
        checked += 1
    assert checked >= 20


def test_fast_downward_compiles_two_state_conflicts_without_conditional_effects():
    def no_conditional_effects(task, planner):
        pairs = [i for i, c in enumerate(planner.conflicts) if transition_conditions(task, c) is not None]
        if pairs and len(pairs) == len(planner.conflicts) and not any(e.conditions for op in task.operators for e in op.effects):
            assert not any(e.conditions for op in planner._compiled.operators for e in op.effects)

    fd_agrees_with_brute_force(list(cases())[::4], no_conditional_effects)
