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


def _run_all(commands, tmp_path, monkeypatch, capsys) -> dict[str, str]:
    """Each command's standard output, after asserting it exited 0."""
    (tmp_path / "examples").symlink_to(ROOT / "examples")
    monkeypatch.chdir(tmp_path)
    monkeypatch.setenv("BROWSER", "true")
    outputs = {}
    for cmd in commands:
        code = main(shlex.split(cmd)[1:])
        out = capsys.readouterr()
        assert code == 0, f"`{cmd}` exited {code}:\n{out.out[-1500:]}\n{out.err[-1500:]}"
        outputs[cmd] = out.out
    return outputs


def test_readme_commands_fast(tmp_path, monkeypatch, capsys):
    commands = [c for c in readme_commands() if not any(s in c for s in SLOW) and SWEEP not in c]
    assert len(commands) >= 9 and any(c.startswith("gnpp view") for c in commands)
    _run_all(commands, tmp_path, monkeypatch, capsys)
    assert (tmp_path / "out" / "result.html").is_file()
    assert (tmp_path / "out" / "lab1_csv" / "left_arm.csv").is_file()


@pytest.mark.slow
def test_readme_commands_slow(tmp_path, monkeypatch, capsys, lab1_kernels):
    """The `--jit` command on the users' JIT path: the conftest's GNPP_JIT=0 (which turns `--jit`
    off) removed, a kernel cache seeded with lab1's (same domain) so only lab4's own kernels
    compile; its summary must report kernels run as compiled C."""
    from shared_solves import copy_cache

    monkeypatch.delenv("GNPP_JIT", raising=False)
    monkeypatch.setenv("GNPP_JIT_CACHE", str(copy_cache(lab1_kernels, tmp_path / "jit_cache")))
    outputs = _run_all([c for c in readme_commands() if any(s in c for s in SLOW)], tmp_path, monkeypatch, capsys)
    jit_runs = [out for cmd, out in outputs.items() if "--jit" in cmd]
    assert jit_runs and all(re.search(r"jit: [1-9]\d* derivative kernels as compiled C", out) for out in jit_runs), jit_runs
