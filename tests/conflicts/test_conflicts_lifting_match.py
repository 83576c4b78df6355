"""How `Lifter._check` decides that a renamed subgraph is the same NLP as the conflict's M
(issue 19, conflicts/lifting.py): the factors the renaming maps M's onto by name first (a linear
check of that one correspondence), VF2 only when that fails, and then within
`LIFT_MATCH_BUDGET` tested pairs.

Oracle: the plain VF2 enumeration the lifter used before (every label-preserving monomorphism
of M into the renamed factors, the first whose factors alone are isomorphic to M), written out
here; the instances must be the same on every subgraph tried. Why it changed: on clutter_6 with
its obstacles named in another order, that enumeration ran for minutes on one 94-factor conflict
with no monomorphism (the solve hit its time limit at 220 s CPU)."""
from __future__ import annotations

import itertools
from pathlib import Path

import pytest

import gnppdsl
from gnppdsl.compile.semantics import derive
from gnppdsl.conflicts import lifting
from gnppdsl.conflicts.lifting import Lifter, _complete, _same_label, _same_slots
from gnppdsl.conflicts.mapping import to_partial_states
from gnppdsl.conflicts.semantic import anonymous_graph
from gnppdsl.logic.validate import initial_state, successor

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
_LIFTER_CHECK = Lifter._check
PLAN = ("pick(b2, g, s2)", "place(b2, g, side)", "pick(b1, g, s1)", "place(b1, g, target)")


def _vf2_check(lifter, mapping, window, shifted, pattern):
    """The reference: `_check` by VF2 enumeration alone (the lifter's code before the named image)."""
    from networkx.algorithms import isomorphism

    perm = _complete(mapping)
    renamed = [lifter._rename_state(s, perm) for s in window]
    wanted = {(f.rule, tuple((k, perm.get(o, o)) for k, o in f.bindings), f.step) for f in shifted}
    templates = {f.template for f in shifted}
    candidates = [f for f in lifter.factory.rule_factors(renamed, sorted(wanted)) if f.template in templates]
    if len(candidates) < len(shifted):
        return None
    target = anonymous_graph(candidates, lifter.object_key)
    gm = isomorphism.GraphMatcher(target, pattern, node_match=_same_label, edge_match=_same_slots)
    for match in gm.subgraph_monomorphisms_iter():
        image = [candidates[n[1]] for n in match if n[0] == "h"]
        if not isomorphism.GraphMatcher(anonymous_graph(image, lifter.object_key), pattern,
                                        node_match=_same_label, edge_match=_same_slots).is_isomorphic():
            continue
        seq = to_partial_states(image)
        start = min(f.step for f in image)
        derived = [derive(lifter.factory.task, st) for st in renamed]
        if not all(p.holds_in(derived[start + k]) for k, p in enumerate(seq)):
            return None
        lifter._image = tuple(image)
        return seq
    return None


def _subgraphs(compiled):
    """Conflict-like subgraphs of a 4-step plan of p6_clutter: per step window (one or two
    steps) and object, the factors naming it, all of them or those of one rule."""
    task = compiled.task
    states = [initial_state(task)]
    for name in PLAN:
        states.append(successor(task, states[-1], next(o for o in task.operators if o.name == name)))
    full = compiled.factory.factors(states)
    out = []
    for step, width, obj in itertools.product(range(len(PLAN) + 1), (1, 2), ("b1", "b2", "g", "side")):
        near = [f for f in full if step <= f.step < step + width and any(o == obj for _, o in f.bindings)]
        groups = [near] + [[f for f in near if f.rule == r] for r in sorted({f.rule for f in near})]
        out += [(states, g) for g in groups if g]
    return out


@pytest.fixture(scope="module")
def compiled():
    return gnppdsl.load_and_compile(str(PLANAR / "p6_clutter.pntc"))


def test_named_image_gives_the_instances_of_vf2_enumeration_without_vf2(compiled, monkeypatch):
    """Every subgraph: the lifter's instances equal the reference's (renaming by renaming), some
    subgraphs have instances beyond the original, and where the names give the isomorphism no
    VF2 pair is tested (before: every renaming ran VF2)."""
    from networkx.algorithms.isomorphism import GraphMatcher

    tested = {"lifter": 0, "reference": 0}
    plain = GraphMatcher.syntactic_feasibility
    side = "lifter"

    def counting(self, a, b):
        tested[side] += 1
        return plain(self, a, b)

    lifted = 0
    for states, factors in _subgraphs(compiled):
        lifter = Lifter(compiled.factory, compiled.task, compiled.problem.objects, compiled.object_key)
        reference = Lifter(compiled.factory, compiled.task, compiled.problem.objects, compiled.object_key)
        monkeypatch.setattr(GraphMatcher, "syntactic_feasibility", counting)
        side = "reference"
        monkeypatch.setattr(Lifter, "_check", _vf2_check)
        expected = reference.instances(states, factors)
        monkeypatch.setattr(Lifter, "_check", _LIFTER_CHECK)
        side = "lifter"
        got = lifter.instances(states, factors)
        monkeypatch.undo()
        assert got == expected, [f.label for f in factors]
        assert lifter.renamable == reference.renamable
        lifted += len(got) > 1
    assert lifted >= 5, lifted
    # the instances come from the named images; VF2 runs only for renamings that are none (and
    # then its necessary conditions first): a fraction of the pairs the enumeration tested
    assert tested["lifter"] * 2 < tested["reference"], tested


def test_vf2_stays_within_its_budget_and_answers_no_instance(compiled, monkeypatch):
    """With the named image taken away, a renaming goes to VF2; once LIFT_MATCH_BUDGET pairs are
    tested it yields no instance (sound: fewer instances), and with the budget large the same
    instances as the reference."""
    subs = [(s, f) for s, f in _subgraphs(compiled) if len(f) >= 3]
    monkeypatch.setattr(lifting, "_named_image", lambda *a: None)
    lifted = 0
    for states, factors in subs:
        lifter = Lifter(compiled.factory, compiled.task, compiled.problem.objects, compiled.object_key)
        assert lifter.instances(states, factors) == _reference(compiled, states, factors, monkeypatch)
        monkeypatch.setattr(lifting, "LIFT_MATCH_BUDGET", 1)
        starved = Lifter(compiled.factory, compiled.task, compiled.problem.objects, compiled.object_key)
        got = starved.instances(states, factors)
        monkeypatch.setattr(lifting, "LIFT_MATCH_BUDGET", 10**9)
        assert got == got[:1]                    # the original conflict only
        lifted += 1
    assert lifted > 10


def _reference(compiled, states, factors, monkeypatch):
    reference = Lifter(compiled.factory, compiled.task, compiled.problem.objects, compiled.object_key)
    check = Lifter._check
    Lifter._check = _vf2_check
    try:
        return reference.instances(states, factors)
    finally:
        Lifter._check = check
