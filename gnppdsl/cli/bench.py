"""`gnpp bench`: algorithms x problems x seeds, printed like Table I of paper 000 and saved as CSV.

Each cell of the table is `mean ± std` over the successful runs of NLP solves and seconds, with
the success rate; N0 (first logical plan) and N (returned solution) per problem. Every run builds its
own solver (its own casadi function cache and its own subgraph database), so no run profits from
an earlier one. Where the runs go (this process, or Ray tasks on this machine or a cluster) and
how an interrupted sweep resumes: `gnppdsl.cli.sweep`.
"""
from __future__ import annotations

import argparse
import math
import re
import sys
from pathlib import Path

from gnppdsl.cli.solver_args import (add_curvature_argument, add_jit_argument,   # light imports
                                     add_order_argument, add_planner_argument, check_outputs,
                                     check_ranges)
from gnppdsl.cli.algorithms import AlgorithmSpec, parse_algorithms   # light as well

DEFAULT_ALGORITHMS = "oneway,gnpp_t,gnpp_tr,gnpp_trn,gnpp_trng"


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("paths", nargs="*", default=["examples/planar"], metavar="PATH",
                        help="problem files or directories of them (default: examples/planar)")
    parser.add_argument("--algorithms", default=DEFAULT_ALGORITHMS,
                        help=f"comma-separated: oneway, gnpp, gnpp_<switches>, rlgp[_<switches>] (default: {DEFAULT_ALGORITHMS})")
    parser.add_argument("--seeds", type=int, default=None,
                        help="runs per algorithm and problem (seeds 0..N-1; default 3, with --instances 1)")
    parser.add_argument("--instances", type=int, default=None, metavar="N",
                        help="randomised instances per problem: the scene's `random_xy` objects drawn "
                             "with seeds S..S+N-1 (--seed S; docs/scene.md); every solution is verified")
    parser.add_argument("--seed", type=int, default=0, metavar="S",
                        help="seed of the first randomised instance (with --instances; default 0)")
    parser.add_argument("--anytime", type=float, default=None, metavar="SECONDS",
                        help="each run looks this long for cheaper logical plans after its first "
                             "solution (`gnpp solve --anytime`)")
    parser.add_argument("--time-limit", type=float, default=60.0, metavar="S", help="seconds per run")
    parser.add_argument("--max-horizon", type=int, default=None, metavar="H", help="longest plan to try")
    add_order_argument(parser)
    add_jit_argument(parser, default="off (no run's time depends on what background compilers have "
                                     "finished); --jit: the kernels are compiled first, in an untimed "
                                     "warm-up solve per problem and algorithm (said in the output), "
                                     "and a kernel a timed run still compiles counts in its CPU time")
    add_curvature_argument(parser)
    add_planner_argument(parser)
    parser.add_argument("--csv", default=None, metavar="FILE",
                        help="one row per run, appended as each run ends; an existing file of an "
                             "earlier sweep is resumed (only the runs it lacks are run)")
    parser.add_argument("--markdown", default=None, metavar="FILE",
                        help="also write the table as markdown, the paper's Table I CPU times beside "
                             "each measured problem that has a paper name (lab4 -> Lab_4)")
    parser.add_argument("--plot", default=None, metavar="PNG",
                        help="bar plot of CPU time per problem, this project beside the paper's Table I "
                             "(needs matplotlib)")
    parser.add_argument("--workers", type=int, default=1, metavar="N",
                        help="run N runs at a time on a local Ray (each in its own process with "
                             "--run-timeout and --memory-limit); 1 (default): one after another "
                             "in this process, no Ray needed")
    parser.add_argument("--address", default=None, metavar="ADDR",
                        help="join an existing Ray cluster (e.g. 'auto' or HOST:PORT) instead of "
                             "starting one; the problem files must be at the same paths on its nodes")
    parser.add_argument("--run-timeout", type=float, default=None, metavar="S",
                        help="with Ray: wall-clock cap of one run, killed and recorded as "
                             "killed_timeout (default: 2 x --time-limit + 60)")
    parser.add_argument("--memory-limit", type=int, default=None, metavar="MB",
                        help="with Ray: address-space cap of one run, recorded as killed_memory "
                             "when exceeded (default: none)")
    parser.add_argument("--quiet", action="store_true", help="no progress lines")


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


_INT_FIELDS = ("seed", "instance", "steps", "nlp_solves", "ipopt_runs", "plans", "conflicts", "db_feasible_hits",
               "db_infeasible_hits", "reused_solutions", "N0", "N", "kernels_native", "kernels_compiled")
_FLOAT_FIELDS = ("nlp_time", "logic_time", "total_time", "cpu_time", "max_violation", "cost", "plan_cost",
                 "base_path_length")


def typed(row: dict) -> dict:
    """A row read back from the CSV with the types a fresh run gives (for the table)."""
    out = dict(row)
    for k in _INT_FIELDS:
        v = out.get(k)
        out[k] = None if v in (None, "") else int(float(v))
    for k in _FLOAT_FIELDS:
        v = out.get(k)
        out[k] = None if v in (None, "") else float(v)
    out["solved"] = out.get("solved") in (True, "True", "true", "1")
    return out


def format_family_table(problems: list[str], specs: list[AlgorithmSpec], rows: list[dict]) -> str:
    """Paper 002's measures per problem family and algorithm over its randomised instances:
    success (solved and verified), CPU seconds, base path length, steps and cost (mean±std over
    the solved runs), and the base path on the instances every algorithm solved (a fair
    comparison of path lengths)."""
    out = ["problem           algorithm     succ     cpu[s]        base[m]       steps       cost         "
           "base[m] where all solved"]
    for p in problems:
        runs = [r for r in rows if r["problem"] == p]
        ok_by = {s.label: {r.get("instance"): r for r in runs if r["algorithm"] == s.label and r["solved"]}
                 for s in specs}
        common = set.intersection(*(set(v) for v in ok_by.values())) if ok_by else set()
        for s in specs:
            rs = [r for r in runs if r["algorithm"] == s.label]
            ok = list(ok_by[s.label].values())
            base = [r["base_path_length"] for r in ok if r.get("base_path_length") is not None]
            both = [ok_by[s.label][k]["base_path_length"] for k in sorted(common, key=str)
                    if ok_by[s.label][k].get("base_path_length") is not None]
            out.append(f"{p:17s} {s.title:13s} {len(ok):>3}/{len(rs):<3}  "
                       f"{_cell([r.get('cpu_time') or 0.0 for r in ok], '.2f'):13s} {_cell(base, '.2f'):13s} "
                       f"{_cell([r['steps'] for r in ok if r.get('steps') is not None], '.1f'):11s} "
                       f"{_cell([r['cost'] for r in ok if r.get('cost') is not None], '.3f'):12s} "
                       f"{_cell(both, '.2f')} ({len(common)} instances)")
    return "\n".join(out)


def _check_numbers(args: argparse.Namespace) -> None:
    from gnppdsl.errors import UserError

    if args.seeds is None:
        args.seeds = 1 if args.instances else 3
    if args.seeds < 1:
        raise UserError("--seeds must be >= 1")
    if args.instances is not None and args.instances < 1:
        raise UserError("--instances must be >= 1")
    if not math.isfinite(args.time_limit) or args.time_limit <= 0:
        raise UserError("--time-limit must be positive and finite")
    if args.workers < 1:
        raise UserError("--workers must be >= 1")
    if args.run_timeout is not None and (not math.isfinite(args.run_timeout) or args.run_timeout <= 0):
        raise UserError("--run-timeout must be positive and finite")
    if args.memory_limit is not None and args.memory_limit < 64:
        raise UserError("--memory-limit must be at least 64 (MB)")


def _check_planner(args: argparse.Namespace, specs: list[AlgorithmSpec]) -> None:
    """`--planner fd` serves the Graph-NLP Planner only (One-way enumerates plans by length, R-LGP
    minimises costs: both need clingo): refused before any run rather than one error row per cell."""
    from gnppdsl.errors import UserError

    if args.planner == "fd":
        other = [s.label for s in specs if s.algorithm != "gnpp"]
        if other:
            raise UserError(f"--planner fd serves the gnpp algorithms only, not {', '.join(other)} "
                            f"(choose --algorithms gnpp_..., or --planner auto / sequential)")
    if args.anytime:
        # the anytime search improves a GNPP or R-LGP solution; One-way has no incumbent to
        # improve (SolveOptions.validated refuses it per run: here before any run)
        other = [s.label for s in specs if s.algorithm not in ("gnpp", "rlgp")]
        if other:
            raise UserError(f"--anytime serves the gnpp and rlgp algorithms, not {', '.join(other)} "
                            f"(choose --algorithms without them)")


def _write_text(path: str, text: str, option: str) -> None:
    from gnppdsl.errors import UserError
    from gnppdsl.outputs import write_atomic

    try:
        Path(path).parent.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise UserError(f"{option} {path}: {exc.strerror or exc}") from None
    write_atomic(path, text, option)


def run(args: argparse.Namespace) -> int:
    import contextlib

    from gnppdsl.cli.status import BenchStatus
    from gnppdsl.cli.sweep import CsvJournal, RunSettings, grid, row_key, run_on_ray, run_serial

    specs = parse_algorithms(args.algorithms)
    _check_numbers(args)
    _check_planner(args, specs)
    check_ranges(args)
    check_outputs(args, ("markdown", "plot"), parents_created=True)   # before minutes of benchmarking
    journal = CsvJournal(args.csv) if args.csv else None
    files = find_problems(args.paths)
    settings = RunSettings(time_limit=args.time_limit, max_horizon=args.max_horizon, order=args.order,
                           jit=bool(args.jit) if args.jit is not None else False,
                           distance_curvature=args.distance_curvature,
                           kinematic_curvature=args.kinematic_curvature, planner=args.planner,
                           anytime=args.anytime, run_timeout=args.run_timeout, memory_mb=args.memory_limit)
    instances = range(args.seed, args.seed + args.instances) if args.instances else (None,)
    cells = list(grid(files, [s.label for s in specs], args.seeds, instances))
    done = journal.done() if journal else set()
    todo = [c for c in cells if c.key not in done]
    wanted = {c.key for c in cells}
    rows = [typed(r) for r in (journal.rows if journal else []) if row_key(r) in wanted]
    if journal and rows:
        print(f"gnpp bench: resuming {args.csv}: {len(rows)} of {len(cells)} runs already there",
              file=sys.stderr)
    skipped: list[str] = []

    status = BenchStatus(len(todo)) if not args.quiet else None    # gnppdsl.cli.status

    def on_row(row: dict) -> None:
        if journal:
            journal.append(row)
        rows.append(typed({k: row.get(k) for k in row}))
        if status is not None:
            inst = "" if row.get("instance") in (None, "") else f" instance {row['instance']}"
            status.print_row(f"{row['problem']:16s} {row['algorithm']:10s}{inst} seed {row['seed']}: {row['status']:14s} "
                             f"NLP {row.get('nlp_solves') or 0:4} cpu {float(row.get('cpu_time') or 0):6.2f} s "
                             f"wall {float(row.get('total_time') or 0):6.2f} s  N0 {row.get('N0')} N {row.get('N')}",
                             row)

    def on_error(file: str, err: Exception) -> None:
        print(f"gnpp bench: skipping {file}:\n{err}", file=sys.stderr)
        skipped.append(file)

    warm = None
    if todo and settings.jit:
        from gnppdsl.cli.kernel_warmup import warm_up    # compiled kernels ready before any timed run
        warm = warm_up(todo, settings, **({"say": lambda line: None} if args.quiet else {}))
    if journal:
        journal.open()
    try:
        with status or contextlib.nullcontext():
            if todo and (args.workers > 1 or args.address):
                run_on_ray(todo, settings, on_row, workers=args.workers if not args.address else None,
                           address=args.address)
            elif todo:
                run_serial(todo, settings, on_row, on_error, progress_for=(
                    (lambda c: status.run_progress(f"{Path(c.file).stem} {c.algorithm} seed {c.seed}"
                                                   + ("" if c.instance is None else f" instance {c.instance}")))
                    if status is not None else None))
    finally:
        if journal:
            journal.close()
    order = {c.key: i for i, c in enumerate(cells)}
    rows.sort(key=lambda r: order.get(row_key(r), len(order)))
    names: list[str] = []
    for r in rows:
        if r["status"] != "error" and r["problem"] not in names:
            names.append(r["problem"])
    if not names:
        from gnppdsl.errors import UserError
        raise UserError("gnpp bench: no problem could be loaded")
    print(format_table(names, specs, rows))
    if args.instances:
        print(format_family_table(names, specs, rows))
    if args.planner:
        print(f"logic mode: planner {args.planner} (--planner)")
    from gnppdsl.geometry import native
    print(f"distance queries: {native.describe()}")
    if warm is not None and warm.note():
        print(warm.note())
    if skipped:
        print(f"skipped (load errors): {', '.join(skipped)}")
    if args.markdown:
        from gnppdsl.cli.table1 import markdown
        text = markdown(names, specs, rows)
        _write_text(args.markdown, text + (f"\n{warm.note()}.\n" if warm is not None and warm.note() else ""),
                    "--markdown")
        print(f"wrote {args.markdown}")
    if args.plot:
        from gnppdsl.cli.table1 import plot
        Path(args.plot).parent.mkdir(parents=True, exist_ok=True)
        plot(names, specs, rows, args.plot)
        print(f"wrote {args.plot}")
    if journal:
        print(f"{len(todo)} runs added to {args.csv} ({len(journal.rows)} in all)")
    return 2 if skipped else 0
