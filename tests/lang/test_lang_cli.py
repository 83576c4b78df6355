"""`gnpp check`: exit codes, rendered diagnostics, help; never a traceback."""
from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def run(capsys, *args):
    code = main(["check", *map(str, args)])
    out = capsys.readouterr()
    return code, out.out, out.err


def test_examples_and_stdlib_check(capsys):
    code, out, err = run(capsys, ROOT / "examples" / "planar", ROOT / "stdlib")
    assert code == 0, err
    assert out.startswith("ok: 1 domain, ") and "modules checked" in out and err == ""


def test_errors_are_rendered_with_caret_and_hint(tmp_path, capsys):
    (tmp_path / "domain.pntc").write_text("domain d\ntype block\nstate on(o: blok) : block\n")
    code, out, err = run(capsys, tmp_path / "domain.pntc")
    assert code == 2 and out == ""
    lines = err.splitlines()
    assert lines[0] == f"{tmp_path / 'domain.pntc'}:3:13: error: unknown type 'blok'"
    assert lines[1] == " 3 | state on(o: blok) : block"
    assert lines[2] == "   |             ^^^^"
    assert lines[3] == "hint: did you mean 'block'?"
    assert lines[-1] == "1 error in 1 domain" and "Traceback" not in err


def test_several_errors_in_several_files(tmp_path, capsys):
    (tmp_path / "domain.pntc").write_text("domain d\ntype a\nstate s(x: b) : a\nstate t(x: c) : a\n")
    (tmp_path / "m.pntc").write_text("module m\ntemplate t(x: R) { x == y z }\n")
    code, _, err = run(capsys, tmp_path / "domain.pntc", tmp_path / "m.pntc")
    assert code == 2
    assert ":3:12: error: unknown type 'b'" in err and ":4:12: error: unknown type 'c'" in err
    assert "m.pntc:2:" in err and err.splitlines()[-1].startswith("3 errors")


def test_missing_file(tmp_path, capsys):
    code, _, err = run(capsys, tmp_path / "nope.pntc")
    assert code == 2 and "file not found" in err and "Traceback" not in err


def test_broken_scene_yaml_via_problem(tmp_path, capsys):
    src = ROOT / "examples" / "planar"
    (tmp_path / "domain.pntc").write_text((src / "domain.pntc").read_text())
    (tmp_path / "p.pntc").write_text((src / "p1_one_block.pntc").read_text().replace(
        "p1_one_block.yaml", "broken.yaml"))
    (tmp_path / "broken.yaml").write_text("objects:\n  b1: {pose: [0, 0, 0]\n")
    code, _, err = run(capsys, tmp_path / "p.pntc")
    assert code == 2 and "broken.yaml:3:1: error: invalid YAML" in err


def test_help(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["check", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    assert "FILE" in out and "examples:" in out and "Exit status" in out


def test_real_entry_point_exit_code(tmp_path):
    (tmp_path / "x.pntc").write_text("domain d\ntype a b\n")
    proc = subprocess.run([sys.executable, "-m", "gnppdsl.cli.main", "check", str(tmp_path / "x.pntc")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and "x.pntc:2:8: error: unexpected 'b'" in proc.stderr
    assert "Traceback" not in proc.stderr


def test_check_does_not_import_heavy_libraries():
    code = ("import sys\nfrom gnppdsl.cli.main import main\n"
            f"rc = main(['check', {str(ROOT / 'examples' / 'lab')!r}])\n"
            "heavy = [m for m in ('casadi', 'pinocchio', 'coal', 'clingo', 'networkx', 'numpy') if m in sys.modules]\n"
            "print(rc, heavy)\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().endswith("0 []"), proc.stdout + proc.stderr
