"""Memory and CPU of `gnpp solve` on the many-blocks planar problem (benchmarks/planar_many.py),
for two source trees side by side: `python benchmarks/bench_grounding.py --before DIR [--after
DIR] [--blocks 80] [--repeats 3]`. Each run is a fresh process (`gnpp solve --quiet`); its
maximum resident set size and user+system CPU come from its own rusage (os.wait4); runs
alternate before/after. Prints one row per run and the mean ratio after/before.
The problem's domain is the planar one of the `after` tree."""
from __future__ import annotations

import argparse
import os
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def run(tree: Path, problem: Path) -> tuple[float, float, int]:
    """(CPU seconds, max RSS in MB, exit code) of one `gnpp solve` in a child process (its own
    rusage from os.wait4: RUSAGE_CHILDREN's maxrss would be the largest child so far)."""
    env = {**os.environ, "PYTHONPATH": str(tree)}
    proc = subprocess.Popen([sys.executable, "-m", "gnppdsl.cli.main", "solve", str(problem), "--quiet",
                             "--time-limit", "600"], env=env, cwd=tree,
                            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(proc.pid, 0)
    proc.returncode = os.waitstatus_to_exitcode(status)
    return usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024, proc.returncode


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--before", type=Path, required=True, help="source tree of the baseline")
    ap.add_argument("--after", type=Path, default=ROOT, help="source tree to compare (default: this one)")
    ap.add_argument("--blocks", type=int, default=80)
    ap.add_argument("--repeats", type=int, default=3)
    args = ap.parse_args()
    sys.path.insert(0, str(ROOT / "benchmarks"))
    from planar_many import write_problem

    with tempfile.TemporaryDirectory() as tmp:
        problem = write_problem(args.blocks, Path(tmp))
        rows = {"before": [], "after": []}
        for k in range(args.repeats):
            for label, tree in (("before", args.before), ("after", args.after)):
                cpu, rss, code = run(tree, problem)
                rows[label].append((cpu, rss))
                print(f"{label:6s} run {k}: {cpu:7.2f} s CPU  maxrss {rss:7.1f} MB  exit {code}", flush=True)
    for label in ("before", "after"):
        print(f"{label}: CPU mean {_mean([c for c, _ in rows[label]]):.2f} s, "
              f"maxrss mean {_mean([r for _, r in rows[label]]):.1f} MB")
    for k, what in ((0, "CPU"), (1, "maxrss")):
        ratio = _mean([r[k] for r in rows["after"]]) / _mean([r[k] for r in rows["before"]])
        print(f"{what} ratio after/before: {ratio:.3f}")


def _mean(xs: list[float]) -> float:
    return sum(xs) / len(xs)


if __name__ == "__main__":
    main()
