"""The batch's reachability screen (`gnppdsl.conflicts.batch.Reachable`): a renamed candidate
whose partial states no plan reaches is dropped without an NLP. Dropping must never hit a
partial state that a plan does reach (then a conflict the batch could learn would be lost, and,
worse, a screen that said "unreachable" for reachable states would be wrong about the task).

Oracle independent of h^2: every state reachable from the initial state, by breadth-first
search with the SAS+ semantics of the validator; a pair of facts held together in one of them
must pass the screen.
"""
from __future__ import annotations

import itertools
import sys
from pathlib import Path

from gnppdsl.compile.sas import Effect, Operator, PartialState, SASTask, SASVariable
from gnppdsl.conflicts.batch import Batcher, Reachable
from gnppdsl.conflicts.lifting import Lifter
from gnppdsl.logic.validate import applicable, initial_state, successor
from gnppdsl.solve.compiled import load_and_compile

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "logic"))
from test_logic_mutex import reachable_states  # noqa: E402  (the explicit search of the h^2 tests)

FIELD = Path(__file__).resolve().parents[2] / "examples" / "field"


def moved_task() -> SASTask:
    """pos in {a, b, c}, moved in {false, true}; `go_ab` sets pos = b and moved = true,
    `go_bc` sets pos = c. (pos = b, not moved) and (pos = c, not moved) are never reached."""
    variables = [SASVariable("pos", ("a", "b", "c")), SASVariable("moved", ("false", "true"))]
    ops = [Operator("go_ab", ((0, 0),), (Effect(0, 1), Effect(1, 1))),
           Operator("go_bc", ((0, 1),), (Effect(0, 2),))]
    return SASTask(variables, (0, 0), PartialState(((0, 2),)), ops)


def test_screen_on_a_hand_built_task():
    r = Reachable(moved_task())
    assert r.state(PartialState(((0, 0), (1, 0))))
    assert r.state(PartialState(((0, 1), (1, 1)))) and r.state(PartialState(((0, 2), (1, 1))))
    assert not r.state(PartialState(((0, 1), (1, 0))))
    assert not r.state(PartialState(((0, 2), (1, 0))))
    assert not r.state(PartialState(((0, 0), (1, 1))))      # never back at a
    # a sequence is dropped when one of its states is
    assert not r([PartialState(((0, 0), (1, 0))), PartialState(((0, 1), (1, 0)))])
    assert r([PartialState(((0, 0),)), PartialState(((0, 1),))])


def test_screen_never_drops_a_reachable_pair_on_field1():
    """Every pair of state facts that a reachable state of field1 holds passes the screen, and
    the screen does drop pairs (the renamings it exists for: an object at another place while
    not moved), each of which no reachable state holds."""
    compiled = load_and_compile(str(FIELD / "field1.pntc"))
    task = compiled.task
    r = Reachable(task)
    states = reachable_states(task, limit=200_000)
    state_vars = [i for i, v in enumerate(task.variables) if not v.is_derived]
    held = set()
    for s in states:
        facts = [(v, s[v]) for v in state_vars]
        held.update(itertools.combinations(facts, 2))
    for f, g in held:
        assert r.state(PartialState((f, g))), (task.fact_str(f), task.fact_str(g))
    dropped = 0
    for v, w in itertools.combinations(state_vars, 2):
        for x, y in itertools.product(range(len(task.variables[v].values)), range(len(task.variables[w].values))):
            if not r.state(PartialState(((v, x), (w, y)))):
                dropped += 1
                assert ((v, x), (w, y)) not in held
    assert dropped
    moved = {name for name in (v.name for v in task.variables) if name.startswith("moved(")}
    assert moved, "field1 has moved(o) facts"
    o = sorted(moved)[0][len("moved("):-1]
    init = initial_state(task)
    parent = task.var_index(f"parent({o})")
    other = next(x for x in range(len(task.variables[parent].values)) if x != init[parent])
    assert not r.state(PartialState(((parent, other), task.fact(f"moved({o})", "false"))))


def test_batcher_skips_unreachable_candidates_on_field1():
    """The candidates of a conflict about the initial place of an object: with the screen, none
    of the yielded ones is unreachable, and the ones it dropped are exactly those the screen
    rejects (counted in `stats.unreachable`)."""
    compiled = load_and_compile(str(FIELD / "field1.pntc"))
    task = compiled.task
    from gnppdsl.solve.plan_graph import plan_graph

    plan = [op for op in task.operators if op.action == "pick"]
    init = initial_state(task)
    first = next(op for op in plan if applicable(op, init))
    states = [init, successor(task, init, first)]
    factors = [f for f in plan_graph(compiled.factory, states).factors]
    lifter = Lifter(compiled.factory, task, compiled.problem.objects, compiled.object_key)
    plain = list(Batcher(lifter).candidates(states, factors, [first.name]))
    screen = Reachable(task)
    batcher = Batcher(lifter, reachable=screen)
    kept = list(batcher.candidates(states, factors, [first.name]))
    assert plain and batcher.stats.unreachable > 0
    assert all(screen(c.conflict) for c in kept)
    assert {c.key for c in plain} - {c.key for c in kept} == {c.key for c in plain if not screen(c.conflict)}
