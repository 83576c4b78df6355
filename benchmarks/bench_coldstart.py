"""Cold-process CPU of `gnpp solve` (issue 20: "cold-process overhead at most 0.3 s CPU beyond
the solve"), broken down, optionally side by side with another gnppdsl tree.

Each run is a fresh `python -c` process that runs `gnppdsl.cli.main.main()` with the argv of
`gnpp solve PROBLEM --quiet --no-jit` (as the `gnpp` program and `python -m gnppdsl.cli.main`
do), with `gnppdsl.load_and_compile`
and `gnppdsl.solve_problem` wrapped to note the process's CPU time (`RUSAGE_SELF`) on entry
and exit. The parent takes the child's whole CPU (`RUSAGE_CHILDREN`: interpreter start and
teardown included) and splits it:

- start+imports: until `load_and_compile` is entered (interpreter, `gnppdsl.cli.main`, the
  parser's sub-command modules, the API's first lazy import);
- load+compile: `load_and_compile` (parsing, resolving, grounding);
- between: from there to `solve_problem` (SolveOptions, importing the solve loop);
- solve: `solve_problem` (what the result's own `cpu_time` counts, plus its set-up);
- after: the rest (summary, JSON, teardown);
- overhead = whole - the result's `cpu_time` (bench_komo.py's "process CPU beyond the
  solve's cpu_time").

`--importtime`: one extra `-X importtime` run per tree, the imports' self times summed by
package (wall microseconds of one process, for orientation: the CPU split above is what counts).

Runs alternate tree by tree (A B A B ...); the machine is shared, so read medians and ratios.
Each tree's bytecode is compiled first (`compileall`, as `make setup` does: with
PYTHONDONTWRITEBYTECODE a process would otherwise compile every changed module again), and one
unmeasured run fills the caches (parse cache, template Functions, dataclass code).

    python benchmarks/bench_coldstart.py [PROBLEM.pntc ...] [--runs 10] [--against DIR]
        [--importtime]    # DIR: another tree, e.g. `git archive main | tar -x -C DIR`

Default problem: bench_komo.py's pick-and-place of seed 0 (written to a scratch directory).
Timings are never asserted anywhere (the machine is shared).
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]

CHILD = r"""
import json, os, resource, sys
def cpu():
    r = resource.getrusage(resource.RUSAGE_SELF)
    return r.ru_utime + r.ru_stime
marks = {}
import gnppdsl
_get = gnppdsl.__getattr__
def _wrapped(name):
    fn = _get(name)
    if name not in ("load_and_compile", "solve_problem"):
        return fn
    def call(*a, **k):
        marks[name + "_in"] = cpu()
        try:
            return fn(*a, **k)
        finally:
            marks[name + "_out"] = cpu()
            with open(out, "w") as fh:
                json.dump(marks, fh)
    return call
gnppdsl.__getattr__ = _wrapped
out = sys.argv[2]
sys.argv = ["gnpp", *json.loads(sys.argv[1])]
from gnppdsl.cli.main import main
sys.exit(main())            # as the `gnpp` program: main() without argv
"""


def one_run(tree: Path, argv: list[str], scratch: Path) -> dict:
    out, res = scratch / "marks.json", scratch / "result.json"
    for f in (out, res):
        if f.exists():
            f.unlink()
    env = dict(os.environ, PYTHONPATH=str(tree))
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run([sys.executable, "-c", CHILD, json.dumps(argv + ["--json", str(res)]), str(out)],
                       cwd=tree, env=env, capture_output=True, text=True)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    whole = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    if p.returncode != 0:
        raise SystemExit(f"{tree}: exit {p.returncode}\n{p.stdout}\n{p.stderr}")
    m = json.loads(out.read_text())
    result = json.loads(res.read_text())
    return {
        "whole": whole,
        "start+imports": m["load_and_compile_in"],
        "load+compile": m["load_and_compile_out"] - m["load_and_compile_in"],
        "between": m["solve_problem_in"] - m["load_and_compile_out"],
        "solve": m["solve_problem_out"] - m["solve_problem_in"],
        "after": whole - m["solve_problem_out"],
        "cpu_time": float(result["stats"]["cpu_time"]),
        "overhead": whole - float(result["stats"]["cpu_time"]),
        "solved": bool(result.get("solved")),
    }


def importtime(tree: Path, argv: list[str]) -> dict[str, float]:
    """Self times (ms, wall) of one process's imports, summed by top-level package."""
    env = dict(os.environ, PYTHONPATH=str(tree))
    p = subprocess.run([sys.executable, "-X", "importtime", "-m", "gnppdsl.cli.main", *argv],
                       cwd=tree, env=env, capture_output=True, text=True)
    sums: dict[str, float] = {}
    for line in p.stderr.splitlines():
        if not line.startswith("import time:") or "self [us]" in line:
            continue
        head, _, name = line.split("|")
        self_us = head.split(":", 1)[1]
        top = name.strip().split(".")[0]
        key = "gnppdsl" if top == "gnppdsl" else top
        sums[key] = sums.get(key, 0.0) + int(self_us) / 1000
    return sums


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("problems", nargs="*", type=Path)
    ap.add_argument("--runs", type=int, default=10)
    ap.add_argument("--against", type=Path, default=None, metavar="DIR")
    ap.add_argument("--importtime", action="store_true")
    args = ap.parse_args(argv)
    scratch = Path(tempfile.mkdtemp(prefix="bench_coldstart_"))
    problems = [p.resolve() for p in args.problems]
    if not problems:
        sys.path.insert(0, str(ROOT / "benchmarks"))
        from bench_komo import write_problem
        problems = [ROOT / "examples" / "lab" / "domain.pntc", write_problem(scratch / "s0", 0)]
    cmd = ["solve", *map(str, problems), "--quiet", "--no-jit"]
    trees = {"new": ROOT}
    if args.against is not None:
        trees = {"base": args.against.resolve(), "new": ROOT}
    for t in trees.values():                      # bytecode and the function store warm
        subprocess.run([sys.executable, "-m", "compileall", "-q", "gnppdsl"], cwd=t, check=True,
                       env=dict(os.environ, PYTHONPATH=str(t)))
        one_run(t, cmd, scratch)
    rows: dict[str, list[dict]] = {k: [] for k in trees}
    for i in range(args.runs):
        for k, t in (trees.items() if i % 2 == 0 else reversed(trees.items())):
            r = one_run(t, cmd, scratch)
            rows[k].append(r)
            print(f"run {i} {k:4s} whole {r['whole']:.2f} s, solve {r['solve']:.2f}, "
                  f"overhead {r['overhead']:.2f}", flush=True)
    keys = ["whole", "start+imports", "load+compile", "between", "solve", "after", "cpu_time", "overhead"]
    print(f"\nmedian CPU s over {args.runs} runs ({' '.join(cmd)})")
    print(f"{'':14s}" + "".join(f"{k:>9s}" for k in trees) + ("    ratio" if len(trees) == 2 else ""))
    for key in keys:
        meds = [statistics.median(r[key] for r in rows[k]) for k in trees]
        print(f"{key:14s}" + "".join(f"{m:9.3f}" for m in meds)
              + (f"{meds[1] / meds[0]:9.2f}" if len(meds) == 2 and meds[0] else ""))
    for k in trees:
        print(f"{k}: solved {sum(r['solved'] for r in rows[k])}/{len(rows[k])}")
    if args.importtime:
        print("\n-X importtime self ms by package (one process each, wall)")
        sums = {k: importtime(t, cmd) for k, t in trees.items()}
        names = sorted(set().union(*sums.values()), key=lambda n: -max(s.get(n, 0) for s in sums.values()))
        for n in names[:15]:
            print(f"{n:24s}" + "".join(f"{sums[k].get(n, 0.0):9.1f}" for k in trees))
        print(f"{'total':24s}" + "".join(f"{sum(sums[k].values()):9.1f}" for k in trees))
    return 0


if __name__ == "__main__":
    sys.exit(main())
