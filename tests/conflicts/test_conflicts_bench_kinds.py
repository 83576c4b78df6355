"""benchmarks/bench_conflicts.py's classification of a solve's conflicts (issue 19 item 4): the
kind of a conflict (its subgraph's factor templates, objects and steps left out), how the
conflicts were found, and the ground instances a verified solution holds (a false conflict).
The bench reads a result's DSL text only; these tests build results by hand."""
from __future__ import annotations

import importlib.util
from pathlib import Path

from gnppdsl.solve.result import Conflict, Result, Step

BENCH = Path(__file__).resolve().parents[2] / "benchmarks" / "bench_conflicts.py"


def _bench():
    spec = importlib.util.spec_from_file_location("bench_conflicts", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


REACH = ("start(o=b1) -> manipulation.fixed_world @3", "switch(o=b1, p=table, p2=right_arm) -> "
         "manipulation.kin_switch_rel @3", "held(o=b1, r=right_arm) -> panda.grasp @4")
REACH_B6 = ("held(o=b6, r=left_arm) -> panda.grasp @9", "start(o=b6) -> manipulation.fixed_world @8",
            "switch(o=b6, p=table, p2=left_arm) -> manipulation.kin_switch_rel @8")
COVER = ("start(o=o1) -> manipulation.fixed_world @6", "on(o=b1, s=pad1) -> manipulation.on @6",
         "on(o=o1, s=table) -> manipulation.on @6",
         "apart(a=b1, b=o1, pa=pad1, pb=table) -> manipulation.no_collision @6")


def _conflict(text, factors, source="nlp", instances=(), batched=()):
    return Conflict((), text, factors, source, instances=instances, batched=batched)


def _result(states, conflicts):
    return Result("p", "d", "gnpp", "trn", 0, "solved",
                  steps=[Step(i, None, s) for i, s in enumerate(states)], conflicts=conflicts)


def test_kind_ignores_objects_and_steps():
    bench = _bench()
    assert bench.kind(_conflict("", REACH)) == "fixed_world+grasp+kin_switch_rel"
    assert bench.kind(_conflict("", REACH_B6)) == bench.kind(_conflict("", REACH))
    assert bench.kind(_conflict("", COVER)) == "fixed_world+no_collision+on+on"
    cs = [_conflict("", REACH), _conflict("", COVER), _conflict("", REACH_B6, "batch")]
    assert bench.kinds(cs) == {"fixed_world+grasp+kin_switch_rel": 2, "fixed_world+no_collision+on+on": 1}
    assert bench.found(cs) == "b1 n2"


def test_held_by_solution_finds_exactly_the_contained_instances():
    bench = _bench()
    states = ["{parent(b1) = table, parent(o1) = table, not moved(o1), holding(r) = none}",
              "{parent(b1) = r, parent(o1) = table, not moved(o1), holding(r) = b1}",
              "{parent(b1) = pad1, parent(o1) = table, not moved(o1), holding(r) = none}"]
    held = "{parent(b1) = table} -> {parent(b1) = r} -> {parent(b1) = pad1, not moved(o1)}"
    wrong_order = "{parent(b1) = r} -> {parent(b1) = table}"
    too_long = "{parent(b1) = r} -> {parent(b1) = pad1} -> {}"
    other = "{parent(b2) = pad1, parent(o1) = table, not moved(o1)}"
    r = _result(states, [_conflict(wrong_order, COVER, instances=(held, other)),
                         _conflict(too_long, REACH, batched=("{holding(r) = b1}",))])
    assert bench.held_by_solution(r) == [held, "{holding(r) = b1}"]
    assert bench._facts("{parent(b1) = table, at(b1, p1) = true}") == {"parent(b1) = table", "at(b1, p1) = true"}
