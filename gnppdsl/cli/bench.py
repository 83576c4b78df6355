"""`gnpp bench`: algorithms x problems x seeds, printed like Table I of paper 000 and saved as CSV.

Each cell of the table is `mean ± std` over the successful runs of NLP solves and seconds, with
the success rate; N0 (first logical plan) and N (returned solution) per problem. Runs are done
one after another in this process; every run builds its own solver (its own casadi function
cache and its own subgraph database), so no run profits from an earlier one.
"""
from __future__ import annotations

import argparse
import csv
import math
import re
import sys
from dataclasses import dataclass
from pathlib import Path

from gnppdsl.cli.solver_args import (add_curvature_argument, add_jit_argument,   # light imports
                                     add_order_argument, check_outputs, check_ranges)
from gnppdsl.solve.result import algorithm_title   # light as well

DEFAULT_ALGORITHMS = "oneway,gnpp_t,gnpp_tr,gnpp_trn,gnpp_trng"
CSV_FIELDS = ("problem", "algorithm", "seed", "status", "solved", "nlp_solves", "ipopt_runs", "nlp_time",
              "logic_time", "total_time", "cpu_time", "plans", "conflicts", "db_feasible_hits",
              "db_infeasible_hits", "reused_solutions", "N0", "N", "max_violation", "kernels_native",
              "kernels_compiled", "message")


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("paths", nargs="*", default=["examples/planar"], metavar="PATH",
                        help="problem files or directories of them (default: examples/planar)")
    parser.add_argument("--algorithms", default=DEFAULT_ALGORITHMS,
                        help=f"comma-separated: oneway, gnpp, gnpp_<switches>, rlgp[_<switches>] (default: {DEFAULT_ALGORITHMS})")
    parser.add_argument("--seeds", type=int, default=3, help="runs per algorithm and problem (seeds 0..N-1)")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S", help="seconds per run")
    parser.add_argument("--max-horizon", type=int, default=None, metavar="H", help="longest plan to try")
    add_order_argument(parser)
    add_jit_argument(parser, default="off (no run's time depends on what background compilers have "
                                     "finished; --jit counts each compile in the run that needs it)")
    add_curvature_argument(parser)
    parser.add_argument("--csv", default=None, metavar="FILE", help="write one row per run")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


@dataclass(frozen=True)
class AlgorithmSpec:
    label: str          # as given, e.g. "gnpp_trn"
    algorithm: str      # "gnpp" | "oneway" | "rlgp"
    switches: str | None

    @property
    def title(self) -> str:
        return algorithm_title(self.algorithm, self.switches)


def parse_algorithms(text: str) -> list[AlgorithmSpec]:
    from gnppdsl.errors import UserError

    specs = []
    for raw in (t.strip() for t in text.split(",")):
        if not raw:
            continue
        low = raw.lower().replace("-", "_")
        if low in ("oneway", "one_way"):
            specs.append(AlgorithmSpec(raw, "oneway", ""))
            continue
        m = re.fullmatch(r"(gnpp|rlgp)(?:_([trng]*))?", low)
        if not m or (m.group(2) is not None and len(set(m.group(2))) != len(m.group(2))):
            raise UserError(f"--algorithms: unknown algorithm '{raw}' "
                            f"(use oneway, gnpp, rlgp or gnpp_<subset of trng>, e.g. gnpp_trn)")
        specs.append(AlgorithmSpec(raw, m.group(1), m.group(2)))
    if not specs:
        raise UserError("--algorithms: no algorithm given")
    return specs


_PROBLEM_RE = re.compile(r"^\s*problem\s+\w+\s+for\s+\w+", re.MULTILINE)


def find_problems(paths: list[str]) -> list[Path]:
    """Problem files among `paths` (directories: every *.pntc declaring a problem, sorted)."""
    from gnppdsl.errors import UserError

    found: list[Path] = []
    for p in map(Path, paths):
        if p.is_dir():
            for f in sorted(p.glob("*.pntc")):
                if _PROBLEM_RE.search(f.read_text(errors="replace")):
                    found.append(f)
        elif p.is_file():
            found.append(p)
        else:
            raise UserError(f"{p}: no such file or directory")
    if not found:
        raise UserError(f"no problem files found in {', '.join(paths)}")
    return found


def mean_std(xs: list[float]) -> tuple[float, float]:
    if not xs:
        return math.nan, math.nan
    m = sum(xs) / len(xs)
    if len(xs) < 2:
        return m, 0.0
    return m, math.sqrt(sum((x - m) ** 2 for x in xs) / (len(xs) - 1))


def _cell(xs: list[float], fmt: str) -> str:
    if not xs:
        return "-"
    m, s = mean_std(xs)
    return f"{m:{fmt}}±{s:{fmt}}"


def format_table(problems: list[str], specs: list[AlgorithmSpec], rows: list[dict]) -> str:
    """Table I layout: problem | N0 | N | per algorithm: NLP, time, success."""
    by = {}
    for r in rows:
        by.setdefault((r["problem"], r["algorithm"]), []).append(r)
    head1 = ["", "", ""]
    head2 = ["problem", "N0", "N"]
    for s in specs:
        head1 += [s.title, "", "", ""]
        head2 += ["NLP", "runs", "cpu[s]", "succ"]
    body = []
    for p in problems:
        runs = [r for r in rows if r["problem"] == p]
        n0 = sorted({r["N0"] for r in runs if r["N0"] not in (None, "")})
        n = sorted({r["N"] for r in runs if r["N"] not in (None, "")})
        line = [p, "/".join(map(str, n0)) or "-", "/".join(map(str, n)) or "-"]
        for s in specs:
            rs = by.get((p, s.label), [])
            ok = [r for r in rs if r["solved"]]
            line += [_cell([r["nlp_solves"] for r in ok], ".1f"), _cell([r.get("ipopt_runs", 0) for r in ok], ".1f"),
                     _cell([r.get("cpu_time", r["total_time"]) for r in ok], ".2f"), f"{len(ok)}/{len(rs)}"]
        body.append(line)
    widths = [max(len(str(x)) for x in col) for col in zip(head1, head2, *body)]
    out = []
    for line in (head1, head2):
        out.append("  ".join(str(x).ljust(w) for x, w in zip(line, widths)).rstrip())
    out.append("  ".join("-" * w for w in widths))
    for line in body:
        out.append("  ".join(str(x).ljust(w) for x, w in zip(line, widths)).rstrip())
    out.append("NLP: feasibility problems solved; runs: solver runs behind them (restarts, polish); "
               "cpu: CPU seconds of the whole solve (wall time in the CSV); mean±std over the solved runs; succ: solved/runs")
    return "\n".join(out)


def run(args: argparse.Namespace) -> int:
    from gnppdsl.errors import UserError
    from gnppdsl.solve.loop import SolveOptions, load_and_compile, solve_compiled

    specs = parse_algorithms(args.algorithms)
    if not 1 <= args.seeds <= 10_000:
        raise UserError("--seeds must be from 1 to 10,000")
    check_ranges(args)
    check_outputs(args)          # say so before minutes of benchmarking, not after
    files = find_problems(args.paths)
    rows: list[dict] = []
    names: list[str] = []
    skipped: list[str] = []
    for f in files:
        try:
            compiled = load_and_compile([str(f)])
        except UserError as err:            # one broken problem does not stop the benchmark
            print(f"gnpp bench: skipping {f}:\n{err}", file=sys.stderr)
            skipped.append(str(f))
            continue
        name = compiled.problem.name
        names.append(name)
        for spec in specs:
            for seed in range(args.seeds):
                options = SolveOptions.from_settings(
                    compiled.problem.settings, algorithm=spec.algorithm, switches=spec.switches,
                    time_limit=args.time_limit, seed=seed, max_horizon=args.max_horizon,
                    order=args.order, jit=args.jit if args.jit is not None else False,
                    distance_curvature=args.distance_curvature,
                )
                # every run compiles its own templates: runs share nothing, so no algorithm
                # or seed is timed with the templates an earlier one compiled (and jit is off
                # unless --jit: no run's time depends on background compiles)
                compiled.compilers.clear()
                try:
                    res = solve_compiled(compiled, options)
                except UserError as err:
                    print(f"gnpp bench: {name} {spec.title} seed {seed}: {err}", file=sys.stderr)
                    rows.append({"problem": name, "algorithm": spec.label, "seed": seed, "status": "error",
                                 "solved": False, "nlp_solves": 0, "ipopt_runs": 0, "nlp_time": 0.0,
                                 "logic_time": 0.0, "total_time": 0.0, "cpu_time": 0.0, "plans": 0,
                                 "conflicts": 0, "db_feasible_hits": 0, "db_infeasible_hits": 0,
                                 "reused_solutions": 0, "N0": None,
                                 "N": None, "max_violation": None, "kernels_native": 0,
                                 "kernels_compiled": 0, "message": str(err)})
                    continue
                s = res.stats
                row = {
                    "problem": name, "algorithm": spec.label, "seed": seed, "status": res.status,
                    "solved": res.solved, "nlp_solves": s.nlp_solves, "ipopt_runs": s.ipopt_runs,
                    "nlp_time": round(s.nlp_time, 4),
                    "logic_time": round(s.logic_time, 4), "total_time": round(s.total_time, 4),
                    "cpu_time": round(s.cpu_time, 4),
                    "plans": s.plans, "conflicts": s.conflicts, "db_feasible_hits": s.db_feasible_hits,
                    "db_infeasible_hits": s.db_infeasible_hits, "reused_solutions": s.reused_solutions, "N0": s.N0, "N": s.N,
                    "max_violation": s.max_violation, "kernels_native": s.kernels_native,
                    "kernels_compiled": s.kernels_compiled, "message": res.message,
                }
                rows.append(row)
                if not args.quiet:
                    print(f"{name:16s} {spec.title:10s} seed {seed}: {res.status:14s} NLP {s.nlp_solves:4d} "
                          f"cpu {s.cpu_time:6.2f} s wall {s.total_time:6.2f} s  N0 {s.N0} N {s.N}",
                          file=sys.stderr, flush=True)
    if not names:
        raise UserError("gnpp bench: no problem could be loaded")
    print(format_table(names, specs, rows))
    from gnppdsl.geometry import native
    print(f"distance queries: {native.describe()}")
    if skipped:
        print(f"skipped (load errors): {', '.join(skipped)}")
    if args.csv:
        from gnppdsl.outputs import atomic_open

        with atomic_open(args.csv, "--csv", newline="") as fh:
            w = csv.DictWriter(fh, fieldnames=CSV_FIELDS)
            w.writeheader()
            for r in rows:
                w.writerow({k: ("" if r[k] is None else r[k]) for k in CSV_FIELDS})
        print(f"wrote {len(rows)} runs to {args.csv}")
    return 2 if skipped else 0
