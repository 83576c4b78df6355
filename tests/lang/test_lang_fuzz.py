"""Properties of the front end on mutated inputs.

Mutations of the real example files (domain, problem, stdlib module, scene YAML): truncation,
deletion of a slice, insertion of a token, duplication of a line, swapping two names. On each:
- `check` and loading agree: `check_files` reports no error exactly when `load_problem`
  succeeds (and `load_problem` raises nothing but `DiagnosticError`);
- every error is located in a file that exists, at a line and column inside it, and its
  rendering quotes that line; the rendered text of a failed load names the same locations;
- a mutation that leaves the text unchanged (or only duplicates a comment) loads as the
  original does.
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
from gnppdsl.lang.diagnostics import MAX_ERRORS_PER_FILE, DiagnosticError

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


def _located(diagnostics, rendered: str) -> None:
    """Every diagnostic points into its file; the first MAX_ERRORS_PER_FILE of each file and
    severity are rendered with their location, the rest counted on one line (`render_all`: a
    mutant renaming a letter everywhere gives ~100 errors in one file)."""
    seen: dict[tuple[str, str], int] = {}
    for dg in diagnostics:
        if dg.span is None:
            continue
        path = Path(dg.span.file)
        assert path.is_file(), dg
        lines = path.read_text(encoding="utf-8", errors="replace").splitlines() or [""]
        assert 1 <= dg.span.line <= len(lines) + 1, (dg, len(lines))
        assert dg.span.column >= 1, dg
        key = (dg.span.file, dg.severity)
        seen[key] = seen.get(key, 0) + 1
        if seen[key] <= MAX_ERRORS_PER_FILE:
            assert str(dg.span) in rendered, (str(dg.span), rendered[:500])
    for (file, severity), n in seen.items():
        if n > MAX_ERRORS_PER_FILE:
            left = n - MAX_ERRORS_PER_FILE
            assert f"{file}: ... and {left:,} more {severity}" in rendered, (file, n, rendered[-500:])


def _run(folder: Path, target: str, text: str, problem: str) -> None:
    with tempfile.TemporaryDirectory() as tmp:
        d = Path(tmp)
        for f in folder.iterdir():
            if f.is_file():
                shutil.copy(f, d / f.name)
        (d / target).write_text(text, encoding="utf-8", errors="surrogateescape")
        report = check_files([str(d / "domain.pntc"), str(d / problem)])
        rendered = report.render()
        assert report.summary()
        _located(report.reporter.errors, rendered)
        try:
            load_problem(d / problem)
            loaded = True
        except DiagnosticError as err:
            loaded = False
            assert str(err) and "Traceback" not in str(err)
            _located(err.diagnostics, str(err))
        assert loaded == report.ok, (f"check says {'ok' if report.ok else 'errors'} but loading "
                                     f"{'succeeds' if loaded else 'fails'}:\n{rendered[:2000]}")
        return loaded


# GNPP_FUZZ_EXAMPLES=500 for a long run; the default keeps the suite fast
EXAMPLES = int(os.environ.get("GNPP_FUZZ_EXAMPLES", "15"))
# Suppressed health checks, each for a reason: too_slow (every example runs the whole front end
# on copied files, ~0.1 s) and function_scoped_fixture (the autouse fixture only switches the AST
# cache off, the same for every example). filter_too_much and the rest stay on.
SETTINGS = settings(max_examples=EXAMPLES, deadline=None,
                    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])


@pytest.mark.parametrize("folder,target,problem", [(PLANAR, "domain.pntc", "p3_occupied.pntc"),
                                                    (PLANAR, "p3_occupied.yaml", "p3_occupied.pntc"),
                                                    (LAB, "domain.pntc", "lab1.pntc")])
def test_unchanged_and_comment_duplicated_inputs_load(folder, target, problem):
    text = (folder / target).read_text()
    assert _run(folder, target, text, problem) is True
    lines = text.splitlines(keepends=True)
    k = next(i for i, ln in enumerate(lines) if ln.lstrip().startswith("#"))
    assert _run(folder, target, "".join(lines[: k + 1] + [lines[k]] + lines[k + 1:]), problem) is True


def test_more_errors_than_rendered_are_counted():
    """A mutant hypothesis found (every 'b' of the Lab domain an 'A'): ~100 errors in one file,
    50 rendered with their place, the rest counted; the fuzz oracle once asked for all of them."""
    text = (LAB / "domain.pntc").read_text().replace("b", "A")
    assert _run(LAB, "domain.pntc", text, "lab1.pntc") is False


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
        _located(report.reporter.errors, report.render())
        try:                               # the problem found the edited module next to it
            load_problem(d / "ex" / "p3_occupied.pntc")
            loaded = True
        except DiagnosticError:
            loaded = False
        assert loaded == report.ok, report.render()[:2000]


@settings(max_examples=2 * EXAMPLES, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(st.text(max_size=200))
def test_random_text(text):
    with tempfile.TemporaryDirectory() as tmp:
        p = Path(tmp) / "x.pntc"
        p.write_text("domain d\n" + text, encoding="utf-8", errors="surrogateescape")
        report = check_files([str(p)])
        _located(report.reporter.errors, report.render())
