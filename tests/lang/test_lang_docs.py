"""Every ```pntc block of docs/reference.md parses; complete files also resolve and type-check.

Why: the reference must stay in step with the grammar. Blocks that start with `domain`,
`problem` or `module` are complete files (checked with `gnpp check`'s machinery, problems only
together with the complete example domain `doc_*` of the page); other blocks are fragments of a domain.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from gnppdsl.ir.resolve import check_files
from gnppdsl.lang.diagnostics import Reporter
from gnppdsl.lang.parser import parse_text

DOC = Path(__file__).resolve().parents[2] / "docs" / "reference.md"
BLOCKS = re.findall(r"^```pntc\n(.*?)^```", DOC.read_text(encoding="utf-8"), re.M | re.S)
HEADER = re.compile(r"^(domain|problem|module)\s+(\w+)(?:\s+for\s+(\w+))?", re.M)


def _first_code_line(text: str) -> str:
    for line in text.splitlines():
        if line.split("#", 1)[0].strip():
            return line
    return ""


def test_the_reference_has_blocks():
    assert len(BLOCKS) >= 15


@pytest.mark.parametrize("i", range(len(BLOCKS)))
def test_block_parses(i):
    text = BLOCKS[i]
    if not HEADER.match(_first_code_line(text)):
        text = "domain doc_fragment\n" + text
    r = Reporter()
    tree = parse_text(text, f"reference.md#block{i}", r)
    assert tree is not None, r.render()
    assert not r.diagnostics


def test_complete_blocks_check(tmp_path):
    domains = {}
    paths = []
    problems = []
    for i, text in enumerate(BLOCKS):
        m = HEADER.match(_first_code_line(text))
        if not m:
            continue
        kind, name, dom = m.groups()
        p = tmp_path / f"{kind}_{name}.pntc"
        if kind == "module":
            p = tmp_path / f"{name}.pntc"
        p.write_text(text)
        if kind == "domain":
            domains[name] = p
            paths.append(p)
        elif kind == "module":
            paths.append(p)
        else:
            problems.append((p, dom))
    # problems of the page's complete example (domains named doc_*)
    checked = [p for p, dom in problems if dom in domains and dom.startswith("doc_")]
    assert checked, "the reference should contain a complete domain + problem"
    report = check_files([str(p) for p in paths + checked])
    assert report.ok, report.render()
    assert report.counts["problem"] == len(checked)
