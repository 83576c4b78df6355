"""Conflict files: DSL syntax resolved against a task, round trip, located errors."""
import pytest

from gnppdsl.compile.sas import PartialState, SASTask, SASVariable
from gnppdsl.errors import UserError
from gnppdsl.logic.conflict_io import format_conflict, parse_conflicts, read_conflicts, write_conflicts
from gnppdsl.logic.generators import tower_task


def test_parse_forms_and_round_trip(tmp_path):
    t = tower_task(3)
    text = """# conflicts found by an earlier run
<{on(b1) = table, on(b2)=b1}, {holding = none, not covered(b3)}>

{covered(b1)} -> {on(b3) = hand}   # the form solver logs print
<{}>
"""
    got = parse_conflicts(text, t, "c.txt")
    f = t.fact
    assert got == [
        (PartialState((f("on(b1)", "table"), f("on(b2)", "b1"))),
         PartialState((f("holding", "none"), f("covered(b3)", "false")))),
        (PartialState((f("covered(b1)", "true"),)), PartialState((f("on(b3)", "hand"),))),
        (PartialState(),),
    ]
    out = write_conflicts(t, got)
    assert out.splitlines()[0] == "<{on(b1) = table, on(b2) = b1}, {holding = none, not covered(b3)}>"
    assert parse_conflicts(out, t) == got
    path = tmp_path / "c.conflicts"
    path.write_text(out)
    assert read_conflicts(path, t) == got
    assert format_conflict(t, got[2]) == "<{}>"


def test_names_ignore_whitespace_and_auxiliary_boolean_names():
    v = [SASVariable("above(b1, b2)", ("false", "true"), 0),
         SASVariable("parent(b1) != s1", ("false", "true"), 0),
         SASVariable("parent(b1)", ("s1", "s2"))]
    t = SASTask(v, (0, 0, 0), PartialState(), [])
    got = parse_conflicts("<{above(b1,b2), not parent(b1) != s1}, {parent(b1) = s2}>", t)
    assert got == [(PartialState(((0, 1), (1, 0))), PartialState(((2, 1),)))]
    assert parse_conflicts(write_conflicts(t, got), t) == got


def test_every_mistake_is_reported_with_file_line_column(tmp_path):
    t = tower_task(3)
    bad = """<{on(b1) = tabel, on(b9) = b1}, {holding = none}>
<{on(b1) = table}
<{covered(b1) = x, holding}>
<{on(b1) = table, on(b1) = b2}>
"""
    with pytest.raises(UserError) as err:
        parse_conflicts(bad, t, "bad.txt")
    msg = str(err.value)
    assert "bad.txt:1:12: error: 'tabel' is not a value of on(b1)" in msg
    assert "did you mean 'table'?" in msg
    assert "bad.txt:1:19: error: unknown variable 'on(b9)'" in msg
    assert "bad.txt:2:18: error: expected '>'" in msg
    assert "bad.txt:3:17:" in msg and "bad.txt:3:20: error: 'holding' is not boolean" in msg
    assert "bad.txt:4:19: error: on(b1) gets two values" in msg
    assert "5 errors" not in msg and "6 errors" in msg
    with pytest.raises(UserError, match="cannot read conflict file"):
        read_conflicts(tmp_path / "missing.txt", t)
