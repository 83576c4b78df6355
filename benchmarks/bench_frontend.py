"""Front-end timings: `gnpp check` and `gnpp compile` as a user runs them (interpreter start
included), plus an in-process breakdown of compile (load, SAS+ task, .sas text, graph-NLP of s_0).

Target (issue): under 1 s each on the Lab example, including interpreter start.

    /work/venv/bin/python benchmarks/bench_frontend.py [PROBLEM.pntc ...] [--repeat N]

Prints a table; timings are never asserted anywhere (the machine is shared).
"""
from __future__ import annotations

import argparse
import shutil
import statistics
import subprocess
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = [ROOT / "examples" / "lab" / "lab1.pntc", ROOT / "examples" / "planar" / "p3_occupied.pntc"]


def gnpp_command() -> list[str]:
    exe = Path(sys.executable).with_name("gnpp")
    if exe.exists():
        return [str(exe)]
    found = shutil.which("gnpp")
    return [found] if found else [sys.executable, "-m", "gnppdsl.cli.main"]


def wall(cmd: list[str], repeat: int) -> tuple[float, int, str]:
    times, rc, err = [], 0, ""
    for _ in range(repeat):
        t0 = time.perf_counter()
        proc = subprocess.run(cmd, capture_output=True, text=True, cwd=ROOT)
        times.append(time.perf_counter() - t0)
        rc, err = proc.returncode, proc.stderr.strip().splitlines()[-1:]
    return statistics.median(times), rc, (err[0] if err else "")


def breakdown(path: Path) -> dict[str, float]:
    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.sas_writer import write_sas
    from gnppdsl.compile.semantics import initial_state
    from gnppdsl.compile.task import build_task
    from gnppdsl.ir import load_problem

    out = {}
    t0 = time.perf_counter()
    problem = load_problem(str(path))
    out["load"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    task = build_task(problem)
    out["task"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    text = write_sas(task)
    out["sas"] = time.perf_counter() - t0
    from gnppdsl.cli.compile_cmd import _robot_dims

    t0 = time.perf_counter()
    dims = _robot_dims(problem)          # loads robot models (pinocchio) for URDF robots
    out["robot models"] = time.perf_counter() - t0
    t0 = time.perf_counter()
    factors = GraphNLPFactory(problem, task, robot_dims=dims).factors([initial_state(task)])
    out["factors(s0)"] = time.perf_counter() - t0
    out["size"] = f"{len(task.variables)} vars, {len(task.operators)} ops, {len(task.axioms)} axioms, " \
                  f"{len(text) // 1024} KiB .sas, {len(factors)} factors at s0"
    return out


def main() -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("problems", nargs="*", type=Path, default=DEFAULT)
    ap.add_argument("--repeat", type=int, default=3, help="runs per command (median reported)")
    args = ap.parse_args()
    gnpp = gnpp_command()
    rows = []
    for path in args.problems:
        for label, extra in [("check", ["check"]), ("compile sas", ["compile", "--emit", "sas"]),
                             ("compile pddl", ["compile", "--emit", "pddl"]),
                             ("compile factors", ["compile", "--emit", "factors"])]:
            cmd = gnpp + [extra[0], str(path)] + extra[1:]
            t, rc, err = wall(cmd, args.repeat)
            rows.append((path.name, label, f"{t:.3f}", "ok" if rc == 0 else f"exit {rc}: {err[:60]}"))
    w = [max(len(r[i]) for r in rows + [("problem", "command", "wall [s]", "status")]) for i in range(4)]
    print(f"gnpp front end, median of {args.repeat} runs (interpreter start included; target < 1 s)")
    for r in [("problem", "command", "wall [s]", "status")] + rows:
        print("  ".join(str(c).ljust(n) for c, n in zip(r, w)))
    print()
    print("in-process breakdown [s]:")
    for path in args.problems:
        try:
            b = breakdown(path)
        except Exception as exc:  # a benchmark reports, it does not crash
            print(f"  {path.name}: {type(exc).__name__}: {exc}")
            continue
        size = b.pop("size")
        print(f"  {path.name}: " + "  ".join(f"{k} {v:.3f}" for k, v in b.items()) + f"   ({size})")
    return 0


if __name__ == "__main__":
    sys.exit(main())
