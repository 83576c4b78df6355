"""`lowering.structure_key`, the template compiler's one-walk cache key, against the two walks it
replaces (the oracle: `map_objs(lift_constants(body))`, what `BodyCompiler` keyed Functions by
before): over every factor of planar and Lab plans, two bodies get equal keys exactly when the
oracle's keys are equal, and the parameter values are the oracle's, in its order."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.lowering import lift_constants, map_objs, structure_key
from gnppdsl.solve.compiled import load_and_compile

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
CASES = [
    (EXAMPLES / "planar" / "p3_occupied.pntc",
     ["pick(b1, g, s1); place(b1, g, target)",
      "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)"]),
    (EXAMPLES / "lab" / "lab1.pntc",
     ["pick(b2, left_arm, table); stack(b2, left_arm, b1)",
      "pick(b1, left_arm, table); handover(b1, left_arm, right_arm); place(b1, right_arm, table); pick(b2, left_arm, table); stack(b2, left_arm, b1)"]),
]


@pytest.mark.parametrize("path,plans", CASES, ids=["planar_p3", "lab1"])
def test_structure_key_partitions_bodies_like_the_two_walks(path, plans):
    c = load_and_compile(str(path))
    rename = BodyCompiler(c.geometry)._structure_of
    bodies = {id(f.body): f for p in plans for f in c.factory.factors(plan_states(c.task, parse_plan(c.task, p)))}
    new_keys, old_keys = {}, {}
    for f in bodies.values():
        key, params = structure_key(f.body, rename)
        old_body, old_params = lift_constants(f.body)
        assert params == old_params, f.label
        new_keys.setdefault((f.template, key), []).append(id(f.body))
        old_keys.setdefault((f.template, map_objs(old_body, rename)), []).append(id(f.body))
    assert len(bodies) > 20
    assert sorted(map(sorted, new_keys.values())) == sorted(map(sorted, old_keys.values()))
    assert len(new_keys) < len(bodies)          # some bodies share a Function (the key is not trivial)
