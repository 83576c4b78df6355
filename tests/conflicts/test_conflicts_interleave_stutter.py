"""Stretching across a kinematic switch (`gnppdsl.conflicts.interleave`, "Stutters", issue 24):
"mm picks o1 at site_a and places it on station_n, parked in between" learned on a plan where the
place follows the pick forbids the plans with other actions between them too, and never one with
a drive between them.

Oracles independent of the stretching code: the factory's own factors of field4 plans (M is the
subgraph the loop learns, as field3/field4's conflict #4 prints it) and the NLP solver on the
relaxed graph of the interleaved plan (infeasible: the forbidden plan is rightly forbidden)."""
from __future__ import annotations


import pytest

from gnppdsl.conflicts.interleave import bridges, chain_link, stretched
from gnppdsl.conflicts.mapping import to_partial_states
from gnppdsl.logic.validate import find_sequence
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.plan_graph import plan_graph
from gnppdsl.solve.timing import result_states


# mm drives first (from its initial base pose it reaches no site), picks o1 at site_a, ...
DIRECT = ["start_move(mm)", "end_move(mm)", "pick(o1, mm, site_a)", "place(o1, mm, station_n)"]
# ... while arm1 moves o2, mm holding o1 and parked
BETWEEN = ["start_move(mm)", "end_move(mm)", "pick(o1, mm, site_a)",
           "pick(o2, arm1, station_s)", "place(o2, arm1, station_n)", "place(o1, mm, station_n)"]
# ... mm drives to station_n before the place
DRIVE = ["start_move(mm)", "end_move(mm)", "pick(o1, mm, site_a)",
         "start_move(mm)", "end_move(mm)", "place(o1, mm, station_n)"]


def pick_place(compiled):
    """M on the DIRECT plan: o1 at its scene pose, the pick (2 -> 3), the grasp, the parked base
    (3 -> 4), the place (3 -> 4), o1 on station_n."""
    states = result_states(compiled.task, DIRECT)
    fs = compiled.factory.factors(states)
    keep = {("start", 2), ("switch", 2), ("held", 3), ("switch", 3), ("on", 4)}
    M = [f for f in fs if ("o1" in f.label and (f.rule, f.step) in keep)
         or (f.rule == "parked" and f.template == "field.parked" and f.step == 3)]
    return states, M


def stutter_of(compiled, states):
    """The chain links the factory builds on s_j -> s_j (as `Run.stutter`)."""
    def links(j):
        s = tuple(states[j])
        return [f.shifted(j) for f in compiled.factory.factors([s, s])
                if f.step == 0 and f.span == 2 and chain_link(f)]
    return links


def test_the_place_transition_is_stretched_with_the_held_object_and_the_parked_base(field4):
    task = field4.task
    states, M = pick_place(field4)
    assert len(M) == 6
    plain = bridges(M)
    assert plain == [None, None]                 # the pick and the place cross both transitions
    b = bridges(M, stutter=stutter_of(field4, states))
    assert b[0] is None                          # the first transition: a delayed start only
    assert b[1] is not None
    text = task.partial_state_str(b[1])
    assert "parent(o1) = mm" in text and "not driving(mm)" in text


def test_stretched_instances_forbid_actions_between_pick_and_place_not_a_drive(field4):
    states, M = pick_place(field4)
    between, drive = result_states(field4.task, BETWEEN), result_states(field4.task, DRIVE)
    before = stretched(M, max_length=12)
    assert all(find_sequence(between, s) is None for s in before)     # what the loop relearned
    out = stretched(M, max_length=12, stutter=stutter_of(field4, states))
    assert out[0] == to_partial_states(M)
    assert any(find_sequence(between, s) is not None for s in out)
    assert all(find_sequence(drive, s) is None for s in out)          # the base drives: not parked


@pytest.mark.slow
def test_the_forbidden_interleaving_is_infeasible(field4):
    """The NLP oracle: M and the BETWEEN plan's graph without collisions and motions (the
    relaxation the Field conflicts come from) are infeasible; the DRIVE plan's is feasible."""
    _, M = pick_place(field4)
    solver = FeasibilitySolver(field4.geometry, SolverOptions(tolerance=1e-6, restarts=2))
    assert not solver.solve(GraphNLP(list(M)), seed=0).feasible

    def relaxed(names):
        return GraphNLP([f for f in plan_graph(field4.factory, result_states(field4.task, names)).factor_instances
                         if not f.tags & {"collision", "traj"}])
    assert not solver.solve(relaxed(BETWEEN), seed=0).feasible
    assert solver.solve(relaxed(DRIVE), seed=0).feasible
