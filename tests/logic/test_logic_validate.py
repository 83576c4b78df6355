"""The validator against hand-computed SAS+ semantics (axiom layers, conditional effects, clashes,
goal, forbidden sequences at every offset)."""
from gnppdsl.compile.sas import Axiom, Effect, Operator, PartialState, SASTask, SASVariable
from gnppdsl.logic.validate import derive, find_sequence, plan_cost, validate_plan

B = ("false", "true")


def small_task() -> SASTask:
    # x in {a, b, c}, y bool; d0 := x = c (layer 0); d1 := y and not d0 (layer 1)
    variables = [SASVariable("x", ("a", "b", "c")), SASVariable("y", B),
                 SASVariable("d0", B, 0), SASVariable("d1", B, 1)]
    ops = [
        Operator("go_b", ((0, 0),), (Effect(0, 1), Effect(1, 1, ((1, 0),))), cost=2),
        Operator("go_c", ((3, 1),), (Effect(0, 2),), cost=5),
        Operator("clash", (), (Effect(1, 0), Effect(1, 1, ((0, 0),)))),
        Operator("reset", (), (Effect(0, 0), Effect(1, 0))),
    ]
    axioms = [Axiom(((0, 2),), 2), Axiom(((1, 1), (2, 0)), 3)]
    return SASTask(variables, (0, 0, 1, 1), PartialState(((0, 2),)), ops, axioms,
                   pair_costs={(None, 0): 7, (0, 1): 10}, name="small")


def test_derive_resets_and_uses_layers():
    t = small_task()
    assert derive(t, (0, 0, 1, 1)) == (0, 0, 0, 0)      # stale derived values are recomputed
    assert derive(t, (1, 1, 0, 0)) == (1, 1, 0, 1)      # d1: y and not d0
    assert derive(t, (2, 1, 0, 0)) == (2, 1, 1, 0)      # d0 blocks d1 (negation, lower layer)


def test_valid_plan_states_cost_and_conditional_effect():
    t = small_task()
    r = validate_plan(t, [0, 1])
    assert r.valid, r.error
    assert r.states == [(0, 0, 0, 0), (1, 1, 0, 1), (2, 1, 1, 0)]
    assert r.cost == 2 + 5 + 7 + 10 == plan_cost(t, [0, 1])


def test_condition_evaluated_before_the_operator():
    t = small_task()
    t.initial = (0, 1, 0, 0)           # y already true: conditional effect does not fire, y stays
    r = validate_plan(t, [0])
    assert r.states[-1] == (1, 1, 0, 1)


def test_inapplicable_clash_goal_and_unknown_operator():
    t = small_task()
    r = validate_plan(t, [1])
    assert not r.valid and r.failed_step == 1 and "d1" in r.error
    r = validate_plan(t, [2])           # y := 0 and y := 1 both fire in x = a
    assert not r.valid and r.failed_step == 1 and "two values" in r.error
    r = validate_plan(t, [3, 0])        # applicable, but x = b at the end
    assert not r.valid and "goal" in r.error and r.failed_step is None
    assert not validate_plan(t, [9]).valid


def test_forbidden_sequences_at_every_offset():
    t = small_task()
    states = validate_plan(t, [3, 0, 1]).states   # x: a a b c
    xa, xb, xc = (PartialState(((0, v),)) for v in range(3))
    assert find_sequence(states, [xa, xa]) == 0
    assert find_sequence(states, [xa, xb, xc]) == 1
    assert find_sequence(states, [xc]) == 3
    assert find_sequence(states, [xb, xb]) is None
    assert find_sequence(states, [PartialState()] * 4) == 0
    assert find_sequence(states, [PartialState()] * 5) is None
    r = validate_plan(t, [3, 0, 1], conflicts=[[xb, xb], [xa, PartialState(((3, 1),))]])
    assert not r.valid and r.conflict == (1, 1)
    assert validate_plan(t, [3, 0, 1], conflicts=[[xb, xb]]).valid
