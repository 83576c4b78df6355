"""Property: mutated or truncated inputs never raise anything but diagnostics.

Mutations of the real example files (domain, problem, stdlib module, scene YAML): truncation,
deletion of a slice, insertion of a token, duplication of a line, swapping two names. The
whole front end runs on each (`check_files` must not raise; `load_problem` may raise only
`DiagnosticError`, whose rendering must work).
"""
from __future__ import annotations

import os
import shutil
import tempfile
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import gnppdsl.lang.parser as parser_mod
from gnppdsl.ir import load_problem
from gnppdsl.ir.resolve import check_files
from gnppdsl.lang.diagnostics import DiagnosticError

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "examples" / "planar"
LAB = ROOT / "examples" / "lab"

TOKENS = ["(", ")", "{", "}", "'", ",", ":", "=", ":=", "->", "=>", "==", "<=", "not", "rule",
          "state", "traj", "x", "1.5", '"', "[", "]", "with", "forall", "tags", "#", "\n", "-",
          "world(", "exists", "none", "object", "; ", ".", "..", "\t", "é", "\x00", "1e99999",
          "- ", ": [", "{a: ", "&x", "*x", "!!python/object:os.system", "\"\n"]


@st.composite
def mutation(draw, text: str):
    kind = draw(st.sampled_from(["truncate", "delete", "insert", "dupline", "swap"]))
    n = len(text)
    if kind == "truncate":
        return text[: draw(st.integers(0, n))]
    if kind == "delete":
        i = draw(st.integers(0, n))
        j = draw(st.integers(i, min(n, i + 40)))
        return text[:i] + text[j:]
    if kind == "insert":
        i = draw(st.integers(0, n))
        return text[:i] + draw(st.sampled_from(TOKENS)) + text[i:]
    lines = text.splitlines(keepends=True)
    if kind == "dupline" and lines:
        k = draw(st.integers(0, len(lines) - 1))
        return "".join(lines[: k + 1] + [lines[k]] + lines[k + 1:])
    words = sorted(set(w for w in text.replace("(", " ").replace(")", " ").split() if w.isidentifier()))
    if len(words) >= 2:
        a, b = draw(st.sampled_from(words)), draw(st.sampled_from(words))
        return text.replace(a, b)
    return text


@pytest.fixture(autouse=True)
def _no_ast_cache(monkeypatch):
    monkeypatch.setattr(parser_mod, "_cache_dir", lambda: None)


def _run(folder: Path, target: str, text: str, problem: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for f in folder.iterdir():
            if f.is_file():
                shutil.copy(f, d / f.name)
        (d / target).write_text(text, encoding="utf-8", errors="surrogateescape")
        report = check_files([str(d / "domain.pntc"), str(d / problem)])
        report.render()
        report.summary()
        try:
            load_problem(d / problem)
        except DiagnosticError as err:
            assert str(err)


# GNPP_FUZZ_EXAMPLES=500 for a long run; the default keeps the suite fast
EXAMPLES = int(os.environ.get("GNPP_FUZZ_EXAMPLES", "15"))
SETTINGS = settings(max_examples=EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))


@SETTINGS
@given(st.data())
def test_mutated_planar_domain(data):
    text = (PLANAR / "domain.pntc").read_text()
    _run(PLANAR, "domain.pntc", data.draw(mutation(text)), "p3_occupied.pntc")


@SETTINGS
@given(st.data())
def test_mutated_planar_problem(data):
    text = (PLANAR / "p3_occupied.pntc").read_text()
    _run(PLANAR, "p3_occupied.pntc", data.draw(mutation(text)), "p3_occupied.pntc")


@SETTINGS
@given(st.data())
def test_mutated_scene(data):
    text = (PLANAR / "p3_occupied.yaml").read_text()
    _run(PLANAR, "p3_occupied.yaml", data.draw(mutation(text)), "p3_occupied.pntc")


@SETTINGS
@given(st.data())
def test_mutated_lab_domain(data):
    text = (LAB / "domain.pntc").read_text()
    _run(LAB, "domain.pntc", data.draw(mutation(text)), "lab1.pntc")


@SETTINGS
@given(st.data())
def test_mutated_stdlib_module(data):
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        shutil.copytree(PLANAR, d / "ex")
        (d / "ex" / "planar.pntc").write_text(data.draw(mutation((ROOT / "stdlib" / "planar.pntc").read_text())))
        report = check_files([str(d / "ex" / "planar.pntc"), str(d / "ex" / "domain.pntc"),
                              str(d / "ex" / "p3_occupied.pntc")])
        report.render()


@settings(max_examples=2 * EXAMPLES, deadline=None, suppress_health_check=list(HealthCheck))
@given(st.text(max_size=200))
def test_random_text(text):
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "x.pntc"
        p.write_text("domain d\n" + text, encoding="utf-8", errors="surrogateescape")
        check_files([str(p)]).render()
