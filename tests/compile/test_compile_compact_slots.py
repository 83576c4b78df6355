"""`factory._compact_slots` (slots renumbered in order of first use) returns a body that is
already in that order as it is, without rebuilding it, and otherwise the renumbered copy; both
equal the straightforward rebuild (the oracle below, the function before the shortcut) on every
body of Lab and planar plans and on hand-made bodies out of order."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.compile import factory as F
from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Objective, Slot, Vec
from gnppdsl.solve.compiled import load_and_compile

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def oracle(body):
    order: dict[int, int] = {}

    def walk(node):
        if isinstance(node, Slot):
            if node.index not in order:
                order[node.index] = len(order)
            return Slot(order[node.index], span=node.span)
        if isinstance(node, tuple):
            return tuple(walk(x) for x in node)
        if isinstance(node, (Call, Vec, Index, Constraint, Objective)):
            return type(node)(**{k: walk(getattr(node, k)) for k in node.__dataclass_fields__ if k != "span"},
                              span=node.span)
        return node

    new = walk(body)
    return new, tuple(sorted(order, key=order.get))


def test_hand_made_bodies_in_and_out_of_order():
    in_order = (Constraint(Call("add", (Slot(0), Slot(1))), "<=", Num(1.0)),
                Constraint(Index(Slot(1), Num(0)), "==", Slot(2)))
    got = F._compact_slots(in_order)
    assert got == oracle(in_order) and got[0] is in_order and got[1] == (0, 1, 2)
    out_of_order = (Constraint(Call("add", (Slot(2), Slot(0))), "<=", Num(1.0)),
                    Constraint(Vec((Slot(0), Slot(4))), "==", Num(0.0)))
    got = F._compact_slots(out_of_order)
    assert got == oracle(out_of_order) and got[1] == (2, 0, 4)
    assert got[0][0].lhs.args == (Slot(0), Slot(1)) and got[0][1].lhs.items == (Slot(1), Slot(2))


@pytest.mark.parametrize("path,plan", [
    (EXAMPLES / "lab" / "lab1.pntc", "pick(b1, left_arm, table); handover(b1, left_arm, right_arm); "
                                     "place(b1, right_arm, table); pick(b2, left_arm, table); stack(b2, left_arm, b1)"),
    (EXAMPLES / "planar" / "p3_occupied.pntc", "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)"),
], ids=["lab1", "planar_p3"])
def test_grounded_bodies_equal_the_rebuild(path, plan, monkeypatch):
    seen = []
    real = F._compact_slots

    def spy(body):
        got = real(body)
        seen.append((body, got))
        return got

    monkeypatch.setattr(F, "_compact_slots", spy)
    c = load_and_compile(str(path))
    c.factory.factors(plan_states(c.task, parse_plan(c.task, plan)))
    assert len(seen) > 10
    for body, got in seen:
        assert got == oracle(body)
    assert any(got[0] is body for body, got in seen)
