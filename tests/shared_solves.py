"""Solves the slow set needs more than once, run once per pytest session (issue 25: CI under 30
minutes without weakening a check). Each is made by the real entry point of the test that needs
the most from it, and the others read the same run:

- `run_cli_capturing`: `gnpp solve ...` through `gnppdsl.cli.main.main` (as a user runs it), with
  the `Compiled` and the `Result` that `gnppdsl.solve_problem` returned inside it recorded, so a
  test that checks the solution object (pinocchio + coal verification, the rebuilt check) and a
  test that checks the command's `--json` file read one solve.
- `compile_lab1_kernels`: lab1's derivative kernels compiled into a fresh cache by `gnpp solve
  --jit` in a child process (the JIT tests of tests/cli and tests/solve start from copies).

The fixtures are in tests/conftest.py; a test that uses one is marked `shared_mobile` there when
the solve is a mobile one, so `.ci/run` runs it in the same process as the mobile problems.
"""
from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
from dataclasses import dataclass
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]


@dataclass
class CliRun:
    """One `gnpp solve` run: its exit code, the parsed `--json` file, and what solve_problem
    was given and returned inside it (the `Result` before the command's `checked()`)."""
    code: int
    json: dict
    compiled: object
    result: object


def run_cli_capturing(argv: list[str], out: Path) -> CliRun:
    """`gnpp solve` with argv (no `--json`: written to `out`), recording solve_problem's
    compiled problem and Result (the command calls `gnppdsl.solve_problem` exactly once)."""
    import gnppdsl
    from gnppdsl.cli.main import main

    calls = []
    real = gnppdsl.solve_problem

    def recording(compiled, *args, **kwargs):
        r = real(compiled, *args, **kwargs)
        calls.append((compiled, r))
        return r

    with pytest.MonkeyPatch.context() as mp:
        mp.setattr(gnppdsl, "solve_problem", recording)
        code = main(["solve", *argv, "--json", str(out), "--quiet"])
    assert len(calls) == 1, f"`gnpp solve {' '.join(argv)}` called solve_problem {len(calls)} times"
    return CliRun(code, json.loads(out.read_text()), *calls[0])


#: pick_place by R-LGP (examples/README.md), the seed and time limit of tests/examples/test_examples_mobile.py
PICK_PLACE_ARGV = [str(ROOT / "examples" / "mobile" / "pick_place.pntc"), "--algorithm", "rlgp",
                   "--seed", "0", "--time-limit", "900"]


def jit_env(cache: Path) -> dict:
    """The environment of a child `gnpp solve` on the users' JIT paths: GNPP_JIT unset (the
    conftest sets it to 0 for every other solve), its own kernel cache."""
    env = {k: v for k, v in os.environ.items() if k != "GNPP_JIT"}
    env.update(GNPP_JIT_CACHE=str(cache), PYTHONPATH=str(ROOT))
    return env


def solve_lab1_child(out: Path, env: dict, *opts: str, timeout: float = 900) -> dict:
    """lab1 by `gnpp solve` in a child process (env from `jit_env`); the parsed --json."""
    p = subprocess.run([sys.executable, "-m", "gnppdsl.cli.main", "solve", str(ROOT / "examples" / "lab" / "lab1.pntc"),
                        *opts, "--json", str(out), "--quiet"], env=env, capture_output=True, text=True,
                       timeout=timeout)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(out.read_text())


@dataclass
class KernelCacheRun:
    cache: Path          # the compiled kernels (`<key>.so`); copy it before solving with it
    first: dict          # the --json of the `--jit` solve that compiled them into an empty cache


def compile_lab1_kernels(tmp: Path) -> KernelCacheRun:
    """lab1 solved with `--jit` in a child process with an empty cache: every kernel compiled
    (a time limit far from the compile deadline, `jit.COMPILE_MARGIN`, even on a busy machine)."""
    cache = tmp / "cache"
    first = solve_lab1_child(tmp / "jit_first.json", jit_env(cache), "--jit", "--time-limit", "900")
    return KernelCacheRun(cache, first)


def copy_cache(run: KernelCacheRun, dest: Path) -> Path:
    """A private copy of the compiled cache (the libraries only: no lock, no jobs)."""
    dest.mkdir(parents=True)
    for lib in sorted(run.cache.glob("*.so")):
        shutil.copy2(lib, dest / lib.name)
    return dest
