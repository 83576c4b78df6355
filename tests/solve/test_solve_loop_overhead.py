"""The loop's work around the NLPs: what it builds once instead of again (semantic graphs of
the database, labels, generating partial states). Same verdicts and results; fewer builds."""
from __future__ import annotations

import pickle
from dataclasses import replace

from solve_toy import occupied_problem
from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts import database
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions


def test_a_checked_graph_gets_one_semantic_graph_for_lookup_and_record(monkeypatch):
    """`FeasibilityCheck.__call__` asks the database about g, solves it and records the verdict:
    one semantic graph of g for both (it was built twice)."""
    built: list[int] = []
    real_build = database.semantic_graph

    def counting(subgraph, *args, **kw):
        built.append(id(subgraph))
        return real_build(subgraph, *args, **kw)

    monkeypatch.setattr(database, "semantic_graph", counting)
    real_call = FeasibilityCheck.__call__
    per_call: list[int] = []

    def call(self, g):
        before = len(built)
        out = real_call(self, g)
        per_call.append(sum(1 for x in built[before:] if x == id(g)))
        return out

    monkeypatch.setattr(FeasibilityCheck, "__call__", call)
    res = solve_compiled(occupied_problem(), SolveOptions(switches="trng", time_limit=60, max_horizon=6))
    assert res.solved and res.stats.N == 4
    assert [c.text for c in res.conflicts] == ["{parent(b1) = target, parent(b2) = s2}"]
    assert per_call and max(per_call) == 1


def test_an_empty_database_is_not_searched_for_a_known_conflict(monkeypatch):
    """A plan's graph is matched against the database's infeasible records only when there is
    one (the match builds the whole plan graph's semantic graph); the records learned from the
    first plan are still searched for the next."""
    seen: list[int] = []
    real = database.SubgraphDatabase.infeasible_inside

    def inside(self, subgraph):
        seen.append(len(self.infeasible))
        return real(self, subgraph)

    monkeypatch.setattr(database.SubgraphDatabase, "infeasible_inside", inside)
    res = solve_compiled(occupied_problem(), SolveOptions(switches="trng", time_limit=60, max_horizon=6))
    assert res.solved and res.stats.plans == 2
    assert seen and all(n > 0 for n in seen)


def test_labels_are_computed_once_and_leave_equality_alone():
    v = VarInstance("pose", ("b1",), 3, "R", 1)
    assert v.key == "pose(b1)" and v.name == "pose(b1)@3"
    assert v.key is v.key                         # kept, not formatted again
    w = replace(v, step=4)
    assert w.key == "pose(b1)" and w != v and hash(replace(w, step=3)) == hash(v)
    u = replace(v, kind="q", args=("r",))
    assert u.key == "q(r)"                        # a replace never inherits the kept label
    f = FactorInstance("t", "rule", (("o", "b1"),), frozenset(), 3, 1, (PartialState(),), (v,), ())
    assert f.label == "rule(o=b1) -> t @3" and f.label is f.label
    g = pickle.loads(pickle.dumps(f))
    assert g == f and hash(g) == hash(f) and g.label == f.label
    assert replace(f, step=5).label == "rule(o=b1) -> t @5"


def test_factory_reuses_the_generating_partial_states():
    """Two state sequences sharing their first state get step-0 factor instances whose
    generators are the same objects (built once per cached resolution), and equal to what a
    fresh factory builds."""
    import gnppdsl
    from gnppdsl.compile.semantics import applicable, initial_state, successor

    compiled = gnppdsl.load_and_compile(["examples/lab/lab1.pntc"])
    task = compiled.task
    s0 = initial_state(task)
    nexts = [successor(task, s0, op) for op in task.operators if applicable(op, s0)][:2]
    assert len(nexts) == 2
    first = compiled.factory.factors([s0, nexts[0]])
    second = compiled.factory.factors([s0, nexts[1]])
    key = lambda f: (f.rule, f.bindings, f.template)            # noqa: E731
    at0 = {key(f): f for f in first if f.step == 0 and f.span == 1}
    shared = [f for f in second if f.step == 0 and f.span == 1 and key(f) in at0]
    assert shared
    assert all(f.generator is at0[key(f)].generator for f in shared)
    fresh = gnppdsl.load_and_compile(["examples/lab/lab1.pntc"]).factory.factors([s0, nexts[0]])
    assert [f.generator for f in fresh] == [f.generator for f in first]
