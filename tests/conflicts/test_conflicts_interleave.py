"""Interleaved (stretched and contracted) conflicts (`gnppdsl.conflicts.interleave`, issue 19 / 24): a conflict
is not tied to one interleaving of the steps that leave its subgraph alone.

Oracles independent of the stretching code:
- the factory's own factors on Field plans (which rules are chain equalities, which are not);
- the NLP solver on whole plans of field4: a plan a stretched instance forbids (the mobile
  base parked from the start while the fixed arm works, then the pick at the far site) is
  infeasible, and the same plan with a drive in between -- which no instance may forbid, since
  the base is not parked across it -- is feasible. Without the bridge facts (`not driving(mm)`)
  in the inserted steps the instance would match the feasible plan and the test fails.
"""
from __future__ import annotations


import pytest

from gnppdsl.conflicts.mapping import conflict_str, to_partial_states
from gnppdsl.conflicts.interleave import bridges, chain_equality, contracted, merged, stretched
from gnppdsl.logic.validate import find_sequence
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.solve.timing import result_states
from gnppdsl.solve.plan_graph import plan_graph



FAR_PICK = ["pick(o3, arm1, station_n)", "place(o3, arm1, station_s)", "pick(o1, mm, site_a)",
            "pick(o2, arm1, station_s)", "place(o1, mm, station_n)"]


def far_pick_subgraph(compiled):
    """M: mm picks o1 at site_a two steps after the start with its base parked since the
    initial state (home pose, parked chain, o1 at its scene pose, the pick, the grasp), and
    places it at station_n two steps later without driving."""
    fs = compiled.factory.factors(result_states(compiled.task, FAR_PICK))

    def keep(f):
        if f.rule == "parked" and f.template == "field.parked":
            return f.step <= 4
        if f.rule == "home":
            return "mm" in f.label
        if "o1" not in f.label:
            return False
        return (f.rule, f.step) in {("start", 2), ("switch", 2), ("held", 3), ("switch", 4)}
    return [f for f in fs if keep(f)]


def test_chain_equalities_are_the_parked_base_and_the_staying_object(field4):
    fs = field4.factory.factors(result_states(field4.task, FAR_PICK))
    chains = {(f.rule, f.template) for f in fs if chain_equality(f)}
    assert chains == {("parked", "field.parked"), ("stay", "manipulation.same")}
    # a pick, the trajectory's ends, its velocity bound and the parked path do not compose
    others = {(f.rule, f.template) for f in fs if not chain_equality(f)}
    assert {("switch", "manipulation.kin_switch_rel"), ("motion", "manipulation.boundary"),
            ("motion", "manipulation.velocity"), ("parked", "field.parked_path")} <= others


def test_contraction_and_stretching_of_a_parked_base(field4):
    task = field4.task
    M = far_pick_subgraph(field4)
    seq = to_partial_states(M)
    text = conflict_str(task, seq)
    assert text.startswith("{not driving(mm), initial} -> {not driving(mm)} -> {parent(o1) = site_a")
    b = bridges(M)
    # 0 -> 1, 1 -> 2: parked only; 2 -> 3 the pick; 3 -> 4 parked; 4 -> 5 the place
    assert [None if x is None else task.partial_state_str(x) for x in b] == \
        ["{not driving(mm)}", "{not driving(mm)}", None, "{not driving(mm)}", None]
    short = to_partial_states(contracted(M))
    assert len(short) == len(seq) - 1            # step 1 passes the base on and nothing else
    # steps 3 and 4 (o1 held, the base parked) are equal and tied only by the parked chain:
    # they merge (the pick right before the place), besides the unmerged one
    assert [len(to_partial_states(m)) for m in merged(contracted(M))] == [len(seq) - 1, len(seq) - 2]
    assert conflict_str(task, short).startswith("{not driving(mm), initial} -> {parent(o1) = site_a")
    out = stretched(M, max_length=12)
    assert out[0] == seq and short in out and len(set(out)) == len(out)
    pick = [p for p in seq if "parent(o1) = site_a" in task.partial_state_str(p)][0]
    for inst in out:
        assert len(inst) <= 12
        i = inst.index(pick)
        # nothing is ever inserted across the pick or the place (they do not compose)
        assert "parent(o1) = mm" in task.partial_state_str(inst[i + 1])
        assert "parent(o1) = station_n" in task.partial_state_str(inst[-1])
        assert "parent(o1) = mm" in task.partial_state_str(inst[-2])
        # inserted steps carry the bridge: the base stays parked
        assert all("not driving(mm)" in task.partial_state_str(p) for p in inst)


def test_a_transition_with_a_non_chain_factor_is_not_stretched(field4):
    M = far_pick_subgraph(field4)
    fs = field4.factory.factors(result_states(field4.task, FAR_PICK))
    # add the velocity bound of mm's motion 0 -> 1 (a trajectory at step 0): no longer stretchable
    extra = [f for f in fs if f.rule == "motion" and f.template == "manipulation.velocity"
             and "mm" in f.label and f.step == 0]
    assert extra
    assert bridges(M + extra)[0] is None and bridges(M)[0] is not None
    # ... nor is step 1 removed: the velocity bound relates step 0 and step 1 through the path
    assert len(to_partial_states(contracted(M + extra))) == len(to_partial_states(M + extra))
    assert len(to_partial_states(contracted(M))) == len(to_partial_states(M)) - 1


@pytest.mark.slow
def test_a_stretched_instance_forbids_the_infeasible_interleaving_not_the_drive(field4):
    """Graph-NLPs of field4 prefixes: the far pick after three actions of the fixed arm with the
    base parked (matched by a stretched instance of the conflict, M found at distance 2) is
    infeasible; with a drive first the whole graph-NLP is feasible, and no instance matches it."""
    M = far_pick_subgraph(field4)
    base = [f for f in M if f.step <= 3 and not (f.rule in ("parked", "switch") and f.step == 3)
            and not (f.rule == "switch" and f.step == 4)]
    out = stretched(base, max_length=10)
    parked = result_states(field4.task, ["pick(o3, arm1, station_n)", "place(o3, arm1, station_s)",
                                "pick(o2, arm1, station_s)", "pick(o1, mm, site_a)"])
    drive = result_states(field4.task, ["pick(o3, arm1, station_n)", "start_move(mm)", "end_move(mm)",
                               "pick(o1, mm, site_a)"])
    assert any(find_sequence(parked, s) is not None for s in out)
    assert all(find_sequence(drive, s) is None for s in out)
    solver = FeasibilitySolver(field4.geometry, SolverOptions(tolerance=1e-6, restarts=2))
    assert not solver.solve(GraphNLP(list(base)), seed=0).feasible          # M itself
    # the parked plan without its collision and trajectory factors (the relaxation the Field
    # conflicts are found in): infeasible already, so the whole graph-NLP is too
    relaxed = [f for f in plan_graph(field4.factory, parked).factor_instances
               if not f.tags & {"collision", "traj"}]
    assert not solver.solve(GraphNLP(relaxed), seed=0).feasible
    assert solver.solve(plan_graph(field4.factory, drive), seed=0).feasible
