"""Fast Downward as an independent test oracle for the compiler's outputs.

Why: a `.sas` or PDDL file is only correct if a planner that shares no code with us reads it and
finds the plans we expect. `up-fast-downward` ships FD's search binary and its Python translator;
these helpers run them in a temporary directory and return the plan. Tests call `require_fd()`
(or `require_translator()`) first so they are skipped cleanly where the package is missing.
"""
from __future__ import annotations

import importlib.util
import os
import re
import subprocess
import sys
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest


def _fd_root() -> Path | None:
    # find_spec locates the package without importing it (its __init__ needs unified_planning)
    spec = importlib.util.find_spec("up_fast_downward")
    if spec is None or not spec.submodule_search_locations:
        return None
    return Path(list(spec.submodule_search_locations)[0]) / "downward" / "builds" / "release" / "bin"


def downward_binary() -> Path | None:
    root = _fd_root()
    if root is None or not (root / "downward").is_file():
        return None
    return root / "downward"


def require_fd() -> Path:
    binary = downward_binary()
    if binary is None:
        pytest.skip("Fast Downward binary (up-fast-downward) not installed")
    return binary


def require_translator() -> Path:
    root = _fd_root()
    if root is None or not (root / "fast_downward" / "translate").is_dir():
        pytest.skip("Fast Downward translator (up-fast-downward) not installed")
    return root


@dataclass
class FDResult:
    solved: bool
    plan: list[str]          # operator names as FD prints them (without parentheses)
    cost: int | None
    output: str

    @property
    def length(self) -> int:
        return len(self.plan)


def run_fd_on_sas(sas_text: str, search: str = "astar(blind())", timeout: float = 60) -> FDResult:
    """Run FD's search on `.sas` text; FD exits 11 (proved) or 12 (incomplete search) without a plan."""
    binary = require_fd()
    with tempfile.TemporaryDirectory() as tmp:
        plan_file = Path(tmp) / "plan"
        proc = subprocess.run(
            [str(binary), "--search", search, "--internal-plan-file", str(plan_file)],
            input=sas_text, capture_output=True, text=True, cwd=tmp, timeout=timeout)
        out = proc.stdout + proc.stderr
        if proc.returncode in (11, 12):
            return FDResult(False, [], None, out)
        if proc.returncode != 0:
            raise AssertionError(f"Fast Downward rejected the task (exit {proc.returncode}):\n{out[-3000:]}")
        return FDResult(True, *_read_plan(plan_file.read_text()), out)


def _read_plan(text: str) -> tuple[list[str], int | None]:
    plan, cost = [], None
    for line in text.splitlines():
        line = line.strip()
        if line.startswith("(") and line.endswith(")"):
            plan.append(line[1:-1])
        m = re.match(r";\s*cost\s*=\s*(\d+)", line)
        if m:
            cost = int(m.group(1))
    return plan, cost


def translate_pddl(domain: str, problem: str, timeout: float = 60) -> str:
    """Run FD's own translator on PDDL text and return the `.sas` text it produces."""
    root = require_translator()
    with tempfile.TemporaryDirectory() as tmp:
        d, p, out = Path(tmp, "domain.pddl"), Path(tmp, "problem.pddl"), Path(tmp, "output.sas")
        d.write_text(domain)
        p.write_text(problem)
        env = dict(os.environ, PYTHONPATH=str(root))
        proc = subprocess.run(
            [sys.executable, "-m", "fast_downward.translate", str(d), str(p), "--sas-file", str(out)],
            capture_output=True, text=True, cwd=tmp, env=env, timeout=timeout)
        if proc.returncode != 0:
            raise AssertionError(f"FD translator rejected the PDDL (exit {proc.returncode}):\n"
                                 f"{(proc.stdout + proc.stderr)[-3000:]}")
        return out.read_text()
