"""to_partial_states: union of generators per step, relative time, empty steps kept."""
from __future__ import annotations

import networkx as nx
import pytest

from conflicts_fixture_factors import HOLDING, PARENT_B1, PARENT_B2, at_spot, grasp, no_overlap, same
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts.mapping import factors_of, to_partial_states


def P(**kw: int) -> PartialState:
    idx = {"b1": PARENT_B1, "b2": PARENT_B2, "h": HOLDING}
    return PartialState.of({idx[k]: v for k, v in kw.items()})


def test_union_per_step_and_renumbering():
    # factors at absolute steps 3 (span 2: steps 3, 4) and 4 (span 1)
    sub = [same("b1", 3, 0), grasp("b2", 4, PARENT_B2, 2)]
    seq = to_partial_states(sub)
    assert seq == (P(b1=0), P(b1=0, b2=2, h=2))


def test_empty_intermediate_steps_are_kept():
    sub = [at_spot("b1", 2, (0.0, 0.0), PARENT_B1, 0), at_spot("b2", 5, (1.0, 0.0), PARENT_B2, 1)]
    seq = to_partial_states(sub)
    assert len(seq) == 4
    assert seq[0] == P(b1=0) and seq[3] == P(b2=1)
    assert seq[1] == PartialState() and seq[2] == PartialState()


def test_always_rule_gives_an_empty_partial_state_step():
    assert to_partial_states([no_overlap(7)]) == (PartialState(),)


def test_disagreeing_generators_raise():
    with pytest.raises(ValueError):
        to_partial_states([at_spot("b1", 0, (0, 0), PARENT_B1, 0), at_spot("b1", 0, (1, 0), PARENT_B1, 1)])


def test_no_factors_raises():
    with pytest.raises(ValueError):
        to_partial_states([])


def test_accepts_graph_shapes():
    fs = [same("b1", 0, 0), no_overlap(1)]

    class GraphLike:
        factors = fs

    g = nx.Graph()
    for i, f in enumerate(fs):
        g.add_node(("h", i), factor=f)
        for v in f.variables:
            g.add_node(v, var=v)
            g.add_edge(("h", i), v)
    assert factors_of(GraphLike()) == tuple(fs)
    assert set(factors_of(g)) == set(fs)
    assert to_partial_states(g) == to_partial_states(fs) == (P(b1=0), P(b1=0))


def test_conflict_holds_in_every_sequence_generating_the_subgraph():
    """Property 4.3 backwards: the states that generated the factors contain the conflict."""
    # a state sequence s_0..s_3 (values of vars 0..2) and factors generated from it
    states = [(0, 1, 0), (2, 1, 1), (2, 1, 1), (1, 1, 0)]
    factors = [grasp("b1", 1, PARENT_B1, 1), grasp("b1", 2, PARENT_B1, 1), at_spot("b1", 3, (1, 0), PARENT_B1, 1)]
    for f in factors:
        for j, p in enumerate(f.generator):
            assert p.holds_in(states[f.step + j])
    seq = to_partial_states(factors)
    assert len(seq) == 3
    assert all(p.holds_in(states[1 + l]) for l, p in enumerate(seq))
