"""Bad input of every kind the issue-21 review found: a located diagnostic, never an exception.

Oracles independent of the code under test: the positions are computed here from the text we
wrote (line and column of the offending literal); the "no traceback" property is that
`check_files` returns and `gnpp check` exits 2 with nothing on stderr that Python prints for
an uncaught exception; sizes are bounded by constants of the test, not read from the module.
"""
from __future__ import annotations

import os
import shutil
import subprocess
import sys
from pathlib import Path

import pytest

import gnppdsl.lang.parser as parser_mod
from gnppdsl.ir.resolve import check_files
from gnppdsl.lang.diagnostics import ECHO_WINDOW, MAX_ERRORS_PER_FILE

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "examples" / "planar"


@pytest.fixture(autouse=True)
def _no_ast_cache(monkeypatch):
    monkeypatch.setattr(parser_mod, "_cache_dir", lambda: None)


def _errors(tmp_path, name: str, data: bytes | str):
    p = tmp_path / name
    p.write_bytes(data.encode() if isinstance(data, str) else data)
    report = check_files([str(p)])
    text = report.render()
    errs = report.reporter.errors
    assert errs, "bad input must give an error"
    for e in errs:
        assert e.span is not None and e.span.file == str(p), e.message
    return errs, text


def _pos(text: str, needle: str) -> tuple[int, int]:
    i = text.index(needle)
    return text.count("\n", 0, i) + 1, i - (text.rfind("\n", 0, i) + 1) + 1


@pytest.mark.parametrize("body", [
    "const c = " + "[" * 1000 + "1" + "]" * 1000,
    "const c = " + "-" * 1000 + "1",
    "const c = 1" + " + 1" * 5000,
    "const c = " + "not " * 1000,
    "derived d := " + "not " * 2000 + "x",
])
def test_deep_nesting_is_one_located_error(tmp_path, body):
    errs, text = _errors(tmp_path, "d.pntc", "domain d\n" + body + "\n")
    assert len(errs) == 1 and errs[0].span.line == 2
    assert "nested more than" in errs[0].message or errs[0].kind == "syntax"
    assert "RecursionError" not in text


def test_nesting_below_the_limit_goes_through_every_stage(tmp_path):
    """A template 90 levels deep is checked, compiled and solved (resolver, type checker and
    casadi lowering recurse per level)."""
    from gnppdsl.solve.loop import SolveOptions, load_and_compile, solve_compiled

    d = tmp_path / "ex"
    shutil.copytree(PLANAR, d)
    expr = "q(g)[0]" + " + 0" * 90
    with open(d / "domain.pntc", "a") as fh:
        fh.write(f"\ntemplate deep(g: object) tags robot {{\n  {expr} <= 5\n}}\n"
                 "rule deeprule(g: gripper) : always => deep(g)\n")
    compiled = load_and_compile([str(d / "p1_one_block.pntc")])
    result = solve_compiled(compiled, SolveOptions.from_settings(compiled.problem.settings, time_limit=60))
    assert result.solved


@pytest.mark.parametrize("literal", ["1e400", "9" * 5000])
def test_numbers_out_of_range_are_located(tmp_path, literal):
    text = f"domain d\ncontinuous x(o: object) : R[{literal}]\nconst c = {literal}\n"
    errs, out = _errors(tmp_path, "d.pntc", text)
    assert [(e.span.line, e.span.column) for e in errs] == [(2, _pos(text, literal)[1]), (3, 11)]
    assert len(out) < 4000                   # a 5,000-digit literal is not echoed twice in full


def test_vector_dimension_range(tmp_path):
    errs, _ = _errors(tmp_path, "d.pntc", "domain d\ncontinuous x(o: object) : R[0]\n")
    assert "vector dimension" in errs[0].message and (errs[0].span.line, errs[0].span.column) == (2, 29)


def test_nul_byte_and_invalid_utf8_are_located(tmp_path):
    errs, out = _errors(tmp_path, "n.pntc", b"domain d\ntype a\x00b\n")
    assert (errs[0].span.line, errs[0].span.column) == (2, 7) and "U+0000" in errs[0].message
    assert "\x00" not in out
    errs, _ = _errors(tmp_path, "u.pntc", b"domain d\ntype a\n# caf\xc3\x28\n")
    assert (errs[0].span.line, errs[0].span.column) == (3, 6) and "UTF-8" in errs[0].message


def test_long_use_name(tmp_path):
    errs, out = _errors(tmp_path, "d.pntc", "domain d\nuse " + "m" * 300 + "\n")
    assert errs[0].kind == "unknown-module" and (errs[0].span.line, errs[0].span.column) == (2, 5)
    assert max(len(line) for line in out.splitlines()) < 400


def test_long_line_is_cut_around_the_caret(tmp_path):
    text = "domain d\ntype a\nconst c = [" + "1, " * 30000 + "@ ]\n"
    errs, out = _errors(tmp_path, "d.pntc", text)
    assert len(errs) == 1 and errs[0].span.column == _pos(text, "@")[1]
    lines = out.splitlines()
    src = next(i for i, s in enumerate(lines) if s.lstrip().startswith("3 |"))
    assert len(lines[src]) < ECHO_WINDOW + 20
    caret = lines[src + 1].index("^")
    assert lines[src][caret] == "@"          # the caret still points at the bad character


def test_errors_per_file_are_capped(tmp_path):
    facts = " ".join(f"parent(x{i}) = s1" for i in range(4000))     # 4,000 unknown objects
    text = (PLANAR / "p1_one_block.pntc").read_text().replace("holding(g) = none", f"holding(g) = none {facts}", 1)
    d = tmp_path / "ex"
    shutil.copytree(PLANAR, d)
    (d / "p1_one_block.pntc").write_text(text)
    report = check_files([str(d / "domain.pntc"), str(d / "p1_one_block.pntc")])
    out = report.render()
    assert len(report.reporter.errors) == 4000
    assert out.count("error: unknown object") == MAX_ERRORS_PER_FILE
    assert f"and {4000 - MAX_ERRORS_PER_FILE:,} more errors" in out
    assert len(out) < 400 * MAX_ERRORS_PER_FILE      # each echo is a window, not the 70 KB line


def test_cli_never_prints_a_traceback(tmp_path):
    cases = {"deep.pntc": "domain d\nconst c = " + "[" * 1000, "num.pntc": "domain d\nconst c = 1e400\n",
             "use.pntc": "domain d\nuse " + "x" * 300 + "\n"}
    for name, text in cases.items():
        (tmp_path / name).write_text(text)
    env = dict(os.environ, PYTHONPATH=str(ROOT), GNPP_NO_CACHE="1")
    proc = subprocess.run([sys.executable, "-m", "gnppdsl.cli.main", "check", *sorted(cases)],
                          cwd=tmp_path, env=env, capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2
    assert "Traceback" not in proc.stderr
    for name in cases:
        assert f"{name}:2:" in proc.stderr
