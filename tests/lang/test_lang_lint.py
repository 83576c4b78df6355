"""Layout warnings: text that parses, but not as it reads (gnppdsl.lang.lint)."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.lang.diagnostics import Reporter
from gnppdsl.lang.parser import parse_file, parse_text

ROOT = Path(__file__).resolve().parents[2]

HEAD = "domain d\ncontinuous p : R[2] tags object\ntemplate t(lo: R, hi: R) tags object {\n"


def warnings(body: str) -> list[tuple[int, int, str]]:
    r = Reporter()
    tree = parse_text(HEAD + body + "}\n", "t.pntc", r)
    assert tree is not None and not r.errors, r.render()
    return [(d.span.line, d.span.column, d.message) for d in r.diagnostics if d.severity == "warning"]


def test_line_starting_with_minus_continues_the_line_above():
    w = warnings("  p[0] >= lo\n  -p[1] >= -hi\n")
    assert [(line, col) for line, col, _ in w] == [(5, 3)]
    assert "starts with '-'" in w[0][2]


def test_line_starting_with_bracket_or_paren_continues_the_line_above():
    w = warnings("  p[0] >= lo\n  [1][0] >= 0\n  p[1] >= hi\n  (p[0]) >= 0\n")
    assert [(line, col) for line, col, _ in w] == [(5, 3), (7, 3)]
    assert "'['" in w[0][2] and "calls `hi`" in w[1][2]


def test_with_on_a_constant_side():
    w = warnings("  p[0] >= lo with p = [1, 2]\n")
    assert [(line, col) for line, col, _ in w] == [(4, 11)]
    assert "`with` applies only to `lo`" in w[0][2]


@pytest.mark.parametrize("body", [
    "  p[0] >= lo;\n  -p[1] >= -hi\n",                  # terminated: a new constraint
    "  p[0] + p[1] >=\n    lo -\n    hi\n",             # operator at the end of the line
    "  (p[0] with p = [1, 2]) >= lo\n",                 # with on the intended side
    "  p[0] >= lo  # a comment - [ (\n  p[1] <= hi\n",
])
def test_intended_layouts_give_no_warning(body):
    assert warnings(body) == []


def test_bundled_files_have_no_layout_warnings():
    for f in sorted([*ROOT.glob("examples/*/*.pntc"), *ROOT.glob("stdlib/*.pntc")]):
        r = Reporter()
        assert parse_file(f, r) is not None
        assert [d for d in r.diagnostics if d.severity == "warning"] == [], f


def test_warnings_survive_the_parse_cache():
    body = "  p[0] >= lo\n  -p[1] >= -hi\n"
    assert warnings(body) == warnings(body)
