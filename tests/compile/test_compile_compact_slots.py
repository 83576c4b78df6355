"""`factory._compact_slots` (slots renumbered in order of first use) returns a body that is
already in that order as it is, without rebuilding it, and otherwise the renumbered copy; both
satisfy what a renumbering means (the oracle below, written without the factory's walk) on
every body of Lab and planar plans and on hand-made bodies out of order."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest

from gnppdsl.compile import factory as F
from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Objective, Slot, Vec
from gnppdsl.solve.compiled import load_and_compile

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def _map_slots(node, fn):
    """`node` with every Slot replaced by fn(slot), through tuples and any dataclass (not the
    factory's list of node types)."""
    if isinstance(node, Slot):
        return fn(node)
    if isinstance(node, tuple):
        return tuple(_map_slots(x, fn) for x in node)
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return dataclasses.replace(node, **{f.name: _map_slots(getattr(node, f.name), fn)
                                            for f in dataclasses.fields(node) if f.init and f.name != "span"})
    return node


def oracle(body, got) -> bool:
    """What `_compact_slots(body)` = (new, order) must satisfy, checked without its code: new's
    slots are numbered 0, 1, 2, ... in order of first use, `order` lists distinct old indices,
    one per new slot, and renumbering new's slots back through `order` gives `body`."""
    new, order = got
    uses: list[int] = []
    _map_slots(new, lambda sl: uses.append(sl.index) or sl)
    first = list(dict.fromkeys(uses))
    return (first == list(range(len(first))) and len(order) == len(first) == len(set(order))
            and _map_slots(new, lambda sl: Slot(order[sl.index])) == body)


def test_hand_made_bodies_in_and_out_of_order():
    in_order = (Constraint(Call("add", (Slot(0), Slot(1))), "<=", Num(1.0)),
                Constraint(Index(Slot(1), Num(0)), "==", Slot(2)))
    got = F._compact_slots(in_order)
    assert oracle(in_order, got) and got[0] is in_order and got[1] == (0, 1, 2)
    out_of_order = (Constraint(Call("add", (Slot(2), Slot(0))), "<=", Num(1.0)),
                    Constraint(Vec((Slot(0), Slot(4))), "==", Num(0.0)))
    got = F._compact_slots(out_of_order)
    assert oracle(out_of_order, got) and got[1] == (2, 0, 4)
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
        assert oracle(body, got)
    assert any(got[0] is body for body, got in seen)
