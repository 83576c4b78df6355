"""Signal latency: how long `gnpp solve` takes to end after SIGINT / SIGTERM (issue 21, target 1 s).

    python benchmarks/bench_signals.py [--trials 8] [--problems lab3 sort4 p7_relay] [--signal INT TERM]

Each trial starts `gnpp solve PROBLEM --json OUT --quiet` in a child process, sends the signal
after a delay drawn uniformly over the problem's run (so it lands in loading, grounding, clingo,
ipopt, JIT compilation ... in proportion to the time spent there), and measures the wall time
from the signal to the child's exit, plus the exit status and the JSON status written. Just
before the signal the child is sent SIGUSR2, which `faulthandler` (a C-level handler: it runs
inside native code too) answers with the Python stack: the report names the frame the late
trials were in. A benchmark, not a test: it prints, it asserts nothing.
"""
from __future__ import annotations

import argparse
import json
import os
import random
import re
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from collections import Counter
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
PROBLEMS = {"lab3": ["examples/lab/domain.pntc", "examples/lab/lab3.pntc"],
            "lab5": ["examples/lab/domain.pntc", "examples/lab/lab5.pntc"],
            "sort4": ["examples/mobile/domain.pntc", "examples/mobile/sort4.pntc"],
            "pick_place": ["examples/mobile/domain.pntc", "examples/mobile/pick_place.pntc"],
            "p7_relay": ["examples/planar/domain.pntc", "examples/planar/p7_relay.pntc"]}
# the `gnpp` program itself (`main()` without argv: a stopped run skips the interpreter's
# teardown, `gnppdsl.cli.main._leave_now`); "main-returned-at" is printed only by runs that
# end normally (those that finished before their signal)
CHILD = ("import faulthandler, signal, sys; faulthandler.register(signal.SIGUSR2, all_threads=False); "
         "from gnppdsl.cli.main import main; sys.argv = ['gnpp'] + sys.argv[1:]; sys.exit(main())")


def _frame(stderr: str) -> str:
    """The innermost gnppdsl frame of the faulthandler dump (where the signal found the run)."""
    frames = re.findall(r'File "([^"]+)", line (\d+) in (\w+)', stderr)
    ours = [(f, n, fn) for f, n, fn in frames if "gnppdsl" in f]
    if not frames:
        return "?"
    f, n, fn = (ours or frames)[0]          # faulthandler prints the innermost frame first
    return f"{Path(f).name}:{n} {fn}" + ("" if frames[0] == (f, n, fn) else f" > {Path(frames[0][0]).name}:{frames[0][2]}")


def trial(paths: list[str], delay: float, sig: int, extra: list[str]) -> dict:
    with tempfile.TemporaryDirectory(prefix="gnpp-sig-") as tmp:
        out = Path(tmp) / "r.json"
        env = {**os.environ, "PYTHONPATH": str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", "")}
        proc = subprocess.Popen([sys.executable, "-c", CHILD, "solve", *paths, "--json", str(out), "--quiet",
                                 *extra], cwd=ROOT, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
                                text=True)
        time.sleep(delay)
        if proc.poll() is not None:
            proc.communicate()
            return {"finished": True}
        proc.send_signal(signal.SIGUSR2)
        time.sleep(0.02)
        t0 = time.perf_counter()
        proc.send_signal(sig)
        try:
            _, err = proc.communicate(timeout=60)
        except subprocess.TimeoutExpired:
            proc.kill()
            _, err = proc.communicate()
        latency = time.perf_counter() - t0
        status = json.loads(out.read_text()).get("status") if out.is_file() else None
        return {"finished": False, "latency": latency, "rc": proc.returncode, "status": status,
                "where": _frame(err), "traceback": "Traceback" in err}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--trials", type=int, default=8)
    ap.add_argument("--problems", nargs="+", default=["lab3", "sort4", "p7_relay"], choices=sorted(PROBLEMS))
    ap.add_argument("--signal", nargs="+", default=["INT", "TERM"], choices=["INT", "TERM"])
    ap.add_argument("--max-delay", type=float, default=20.0, help="signals land in [0.3, this] s")
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("extra", nargs="*", help="more `gnpp solve` options after --, e.g. -- --planner fd")
    args = ap.parse_args(argv)
    rng = random.Random(args.seed)
    print(f"{'problem':11s} {'sig':4s} {'n':>3s} {'median s':>9s} {'max s':>7s}  exit codes / json status / "
          "late (> 1 s) at")
    for name in args.problems:
        for s in args.signal:
            sig = getattr(signal, f"SIG{s}")
            rows = []
            for _ in range(args.trials):
                r = trial(PROBLEMS[name], rng.uniform(0.3, args.max_delay), sig, args.extra)
                if not r["finished"]:
                    rows.append(r)
            if not rows:
                print(f"{name:11s} {s:4s}   0  (every run ended before its signal)")
                continue
            lat = [r["latency"] for r in rows]
            late = Counter(r["where"] for r in rows if r["latency"] > 1.0)
            print(f"{name:11s} {s:4s} {len(rows):3d} {statistics.median(lat):9.2f} {max(lat):7.2f}  "
                  f"{dict(Counter(r['rc'] for r in rows))} {dict(Counter(r['status'] for r in rows))} "
                  f"tracebacks={sum(r['traceback'] for r in rows)} late={dict(late)}", flush=True)
            for r in sorted(rows, key=lambda r: -r["latency"])[:3]:
                print(f"    {r['latency']:.2f} s  {r['where']}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
