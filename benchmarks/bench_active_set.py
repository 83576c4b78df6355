"""The Lab with and without the active set, and with the domain before / after a change, side by
side in ONE run: for every problem and seed the configurations run in turn (alternating), each
solve's CPU time, NLP count and verdict of the independent verification. A benchmark, not a
test: it prints, it asserts nothing.

    python benchmarks/bench_active_set.py --seeds 3 \\
        --config main:REV:off --config main+as:REV:on --config now:examples/lab/domain.pntc:on

A configuration is LABEL:DOMAIN:ACTIVE_SET. DOMAIN is a file, or a git revision (`main`,
`3fd8e95`) whose examples/lab/domain.pntc is used; ACTIVE_SET `on` repairs a solution the
verification rejects (`SolveOptions.active_set`, as `gnpp solve` does), `off` ends such a solve
as verification_failed (a failure here). The CPU column includes the verification and repairs.
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LAB = ROOT / "examples" / "lab"


def _domain_file(spec: str, tmp: Path) -> str:
    if Path(spec).is_file():
        return str(Path(spec).resolve())
    text = subprocess.run(["git", "-C", str(ROOT), "show", f"{spec}:examples/lab/domain.pntc"],
                          check=True, capture_output=True, text=True).stdout
    out = tmp / f"domain_{spec.replace('/', '_')}.pntc"
    out.write_text(text)
    return str(out)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=3)
    ap.add_argument("--time-limit", type=float, default=100.0)
    ap.add_argument("--problems", nargs="*", default=["lab1", "lab2", "lab3", "lab4", "lab5"])
    ap.add_argument("--config", action="append", required=True, metavar="LABEL:DOMAIN:on|off")
    args = ap.parse_args(argv)

    from dataclasses import replace

    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions

    tmp = Path(tempfile.mkdtemp(prefix="bench_as_"))
    configs = []
    for c in args.config:
        label, dom, mode = c.rsplit(":", 2)
        # a problem file next to a copy of the domain: the problems name their scene relative to it
        configs.append((label, _domain_file(dom, tmp), mode == "on"))
    rows: dict = {}
    for name in args.problems:
        comps = {label: load_and_compile([dom, str(LAB / f"{name}.pntc")]) for label, dom, _ in configs}
        for seed in range(args.seeds):
            for label, _, active in configs:
                comp = comps[label]
                opts = SolveOptions.from_settings(comp.problem.settings, seed=seed, time_limit=args.time_limit,
                                                  jit=False)
                c0 = time.process_time()
                r = solve_compiled(comp, replace(opts, active_set=active))
                ok, why = r.status == "solved", r.message
                cpu = time.process_time() - c0
                rows.setdefault((name, label), []).append((ok, cpu, r.stats.nlp_solves))
                print(f"  {name} seed {seed} {label:12}: {'ok' if ok else 'FAIL'} CPU {cpu:6.2f} s "
                      f"NLP {r.stats.nlp_solves:3} {why[-90:] if 'active set' in why or not ok else ''}",
                      file=sys.stderr, flush=True)
    print(f"Lab, {args.seeds} seeds, alternating configurations, CPU s of this process (solve + "
          f"verification + repairs), mean over verified solves; ok = verified solves / seeds")
    head = f"{'problem':8}" + "".join(f" | {label:>24}" for label, _, _ in configs)
    print(head)
    print(f"{'':8}" + "".join(f" | {'ok':>4} {'NLP':>7} {'CPU s':>11}" for _ in configs))
    for name in args.problems:
        line = f"{name:8}"
        for label, _, _ in configs:
            runs = rows[(name, label)]
            good = [x for x in runs if x[0]]
            nlp = statistics.mean(x[2] for x in good) if good else float("nan")
            cpu = [x[1] for x in good]
            sd = statistics.pstdev(cpu) if len(cpu) > 1 else 0.0
            line += (f" | {len(good)}/{len(runs):<2} {nlp:7.1f} "
                     f"{(statistics.mean(cpu) if cpu else float('nan')):5.2f}±{sd:<5.2f}")
        print(line)
    return 0


if __name__ == "__main__":
    sys.exit(main())
