"""Fast Downward as an independent oracle for the logic layer (skips cleanly when absent).

Why: clingo's shortest plan under conflicts must have the same length as FD's optimal plan on
the Appendix-B-compiled `.sas` (written by the compiler's `.sas` writer). FD shares no code with
the ASP encoding, the reformulation or the validator.
"""
from __future__ import annotations

import importlib.util
import subprocess
import tempfile
from dataclasses import dataclass
from pathlib import Path

import pytest

from gnppdsl.compile.sas import SASTask


def downward_binary() -> Path | None:
    spec = importlib.util.find_spec("up_fast_downward")
    if spec is None or not spec.submodule_search_locations:
        return None
    path = Path(list(spec.submodule_search_locations)[0]) / "downward/builds/release/bin/downward"
    return path if path.is_file() else None


def require_fd() -> Path:
    binary = downward_binary()
    if binary is None:
        pytest.skip("Fast Downward binary (up-fast-downward) not installed")
    return binary


@dataclass
class FDPlan:
    solved: bool
    operators: list[int]       # indices into the task's operators
    cost: int | None


def run_fd(task: SASTask, search: str = "astar(blind(), cost_type=one)", timeout: float = 60) -> FDPlan:
    """Write `task` as .sas, run FD's search, map the plan back to operator indices."""
    from gnppdsl.compile.sas_writer import write_sas

    binary = require_fd()
    by_name = {" ".join(op.name.split()): i for i, op in enumerate(task.operators)}
    assert len(by_name) == len(task.operators), "operator names must be unique for the oracle"
    with tempfile.TemporaryDirectory() as tmp:
        plan_file = Path(tmp) / "sas_plan"
        proc = subprocess.run([str(binary), "--search", search, "--internal-plan-file", str(plan_file)],
                              input=write_sas(task), capture_output=True, text=True, cwd=tmp,
                              timeout=timeout)
        if proc.returncode in (11, 12):
            return FDPlan(False, [], None)
        if proc.returncode != 0:
            raise AssertionError(f"Fast Downward failed (exit {proc.returncode}):\n"
                                 f"{(proc.stdout + proc.stderr)[-3000:]}")
        ops, cost = [], None
        for line in plan_file.read_text().splitlines():
            line = line.strip()
            if line.startswith(";"):
                if "cost" in line:
                    cost = int(line.split("=")[1].split()[0])
            elif line:
                ops.append(by_name[line[1:-1]])
        return FDPlan(True, ops, cost)
