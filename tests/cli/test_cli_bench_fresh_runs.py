"""`gnpp bench` times every run alike, serial or on Ray: no run starts with what an earlier run of
the same process instantiated, and no run pays the import of the solver's modules.

Why these matter: a serial sweep used to solve every seed on one `Compiled`, whose factory keeps
the factor instances a solve instantiated, so seeds after the first read about half the CPU of
the same run on Ray (lab2: 0.78 vs 0.39 s), where every run is a new process; and an isolated run
imported the solver's modules inside its timed solve. The oracles are object identity (a fresh
`Compiled` per run) and `sys.modules` (nothing of the solver imported during a solve).
"""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

from gnppdsl.cli import sweep
from gnppdsl.cli.sweep import Cell, RunSettings, run_serial

ROOT = Path(__file__).resolve().parents[2]
P1 = str(ROOT / "examples" / "planar" / "p1_one_block.pntc")
LAB2 = str(ROOT / "examples" / "lab" / "lab2.pntc")


def test_serial_runs_each_get_a_fresh_compiled_problem(monkeypatch):
    seen: list = []

    def record(cell, settings, compiled=None, progress=None):
        seen.append((cell.seed, compiled, compiled.factory))
        return {"seed": cell.seed}

    monkeypatch.setattr(sweep, "solve_cell", record)
    rows: list = []
    cells = [Cell(P1, "gnpp_trn", s) for s in range(3)]
    run_serial(cells, RunSettings(time_limit=10), rows.append, lambda f, e: None)
    assert [r["seed"] for r in rows] == [0, 1, 2]
    assert len({id(c) for _, c, _ in seen}) == 3          # one Compiled per run
    assert len({id(f) for _, _, f in seen}) == 3          # and so one factory (factor cache) per run
    assert all(c.problem is seen[0][1].problem for _, c, _ in seen)   # the file parsed once


_CHILD = """
import json, sys
from gnppdsl.cli.sweep import Cell, RunSettings, preload_solver, solve_cell
import gnppdsl
import gnppdsl.cli.algorithms   # solve_cell's, read before the solve's clock starts
compiled = gnppdsl.load_and_compile([sys.argv[1]])
preload_solver()
before = set(sys.modules)
row = solve_cell(Cell(sys.argv[1], "gnpp_trng", 0), RunSettings(time_limit=60), compiled)
late = sorted(m for m in set(sys.modules) - before if m.startswith(("gnppdsl", "clingo")))
print(json.dumps({"solved": row["solved"], "late": late}))
"""


def test_a_solve_after_preload_imports_nothing_of_the_solver():
    out = subprocess.run([sys.executable, "-c", _CHILD, LAB2], capture_output=True, text=True,
                         cwd=ROOT, timeout=300)
    assert out.returncode == 0, out.stderr[-2000:]
    got = json.loads(out.stdout.strip().splitlines()[-1])
    assert got["solved"] in (True, "True")
    assert got["late"] == [], got["late"]


def test_the_isolated_child_preloads_before_its_run(monkeypatch):
    from gnppdsl.cli import sweep_child

    order: list[str] = []
    monkeypatch.setattr(sweep_child, "preload_solver", lambda: order.append("preload"))
    monkeypatch.setattr(sweep_child, "solve_cell", lambda c, s: order.append("run") or {"ok": 1})
    request = {"cell": {"file": P1, "algorithm": "gnpp_trn", "seed": 0},
               "settings": {"time_limit": 5}}
    monkeypatch.setattr(sys, "stdin", __import__("io").StringIO(json.dumps(request)))
    assert sweep_child.main() == 0
    assert order == ["preload", "run"]
