"""Every `gnpp` command of the README's "Using it" block works on a fresh clone: run in order in
an empty directory holding only a link to `examples/` (no `out/`), each exits 0. The long ones
(lab4 with --jit, the planar benchmark) run with GNPP_SLOW=1; the Lab sweep (50 Lab solves on Ray,
hours of CPU) is left to the benchmark helpers' own tests. `BROWSER=true` stands in for a browser."""
from __future__ import annotations

import re
import shlex
from pathlib import Path

import pytest

from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
SLOW = ("--jit", "gnpp bench examples/planar")
SWEEP = "gnpp bench examples/lab"


def readme_commands() -> list[str]:
    text = (ROOT / "README.md").read_text()
    block = re.search(r"## Using it\n\n```\n(.*?)```", text, re.S).group(1)
    return [line.split("  #")[0].strip() for line in block.splitlines() if line.startswith("gnpp ")]


def _run_all(commands, tmp_path, monkeypatch, capsys):
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("BROWSER", "true")
    for cmd in commands:
        code = main(shlex.split(cmd)[1:])
        out = capsys.readouterr()
        assert code == 0, f"`{cmd}` exited {code}:\n{out.out[-1500:]}\n{out.err[-1500:]}"


def test_readme_commands_fast(tmp_path, monkeypatch, capsys):
    commands = [c for c in readme_commands() if not any(s in c for s in SLOW) and SWEEP not in c]
    assert len(commands) >= 9 and any(c.startswith("gnpp view") for c in commands)
    _run_all(commands, tmp_path, monkeypatch, capsys)
    assert (tmp_path / "out" / "result.html").is_file()
    assert (tmp_path / "out" / "lab1_csv" / "left_arm.csv").is_file()


@pytest.mark.slow
def test_readme_commands_slow(tmp_path, monkeypatch, capsys):
    _run_all([c for c in readme_commands() if any(s in c for s in SLOW)], tmp_path, monkeypatch, capsys)
