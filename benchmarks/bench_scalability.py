"""Scalability benchmark (paper 000, Appendix D, Figs. 8-9) on examples/scalability: a benchmark,
not a test (it prints, it asserts nothing).

Per problem:
- logic alone: CPU seconds to the first logical plan with the sequential clingo planner (before
  issue 19: the only mode) and with each mode asked for (default: auto and fd), FD's child CPU
  included; `>T` = no plan within the logic limit;
- N0 proven: the exact (sequential) planner's first plan length, or `>=h` when its proof of the
  horizons below h ran out of time; expected.yaml gives N0 by construction;
- end to end (`--solve`): `gnpp solve` with the chosen planner (default auto): status, N, NLPs,
  total CPU (this process + children: FD and the C compiler), logic CPU seconds (FD included)
  and their share of the total CPU, each solution checked by the independent pinocchio + coal verification
  (`gnppdsl.solve.verify_solution`, as benchmarks/bench_lab.py); a failed check is a failure;
- the paper's CPU seconds beside it. Figs. 8-9 of paper 000 are images; the text gives no
  numbers. Read off the figures (approximate, `~`): stacking 32 blocks about 500 s; the
  cluttered table about 10 s with 1 obstacle and 60 s with 6, linear in between as the paper
  says ("scales linearly to the number of obstacles"; the in-between values are that line,
  marked `~lin`). Lab_4 / Lab_5 are Table I's GNPP_trng means (6.3 s, 19.0 s; exact).

    python benchmarks/bench_scalability.py [--problems stack_4 clutter_1] [--modes auto fd]
        [--logic-limit 60] [--solve] [--time-limit 300] [--seeds 1] [--plot scalability.png]

`--plot` (matplotlib, the optional `bench` extra) draws CPU seconds against the family's parameter
(blocks; obstacles), as the paper's figures: this project's end-to-end CPU (with --solve) and first-plan times,
and the paper's points.
"""
from __future__ import annotations

import argparse
import resource
import sys
import time
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
FAMILY = ROOT / "examples" / "scalability"

# paper 000: (CPU seconds, how it was read). Appendix D figures are approximate readings.
PAPER = {"stack_32": (500.0, "~"), "clutter_1": (10.0, "~"), "clutter_6": (60.0, "~"),
         "lab4_paper": (6.3, "Table I"), "lab5_paper": (19.0, "Table I")}
for _k in range(2, 6):
    PAPER[f"clutter_{_k}"] = (10.0 + (60.0 - 10.0) * (_k - 1) / 5, "~lin")


def cpu_now() -> float:
    """CPU seconds of this process and of the children it waited for (Fast Downward, cc)."""
    ch = resource.getrusage(resource.RUSAGE_CHILDREN)
    return time.process_time() + ch.ru_utime + ch.ru_stime


def first_plan(task, mode: str, limit: float) -> tuple[float, int | None, bool, int]:
    """(CPU s, plan length or None, proven shortest, horizon reached) of a fresh planner's first plan."""
    from gnppdsl.logic.modes import make_planner

    c0 = cpu_now()
    planner = make_planner(task, mode, max_horizon=64)
    res = planner.shortest_plan(time_limit=limit)
    cpu = cpu_now() - c0
    if res.plan is None:
        return cpu, None, False, res.horizon
    return cpu, len(res.plan), res.plan.shortest, res.horizon


def solve_one(path: Path, mode: str, seed: int, time_limit: float) -> dict:
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions
    from gnppdsl.solve.verify_solution import verify_solution

    comp = load_and_compile(str(path))
    opts = SolveOptions.from_settings(comp.problem.settings, seed=seed, time_limit=time_limit, planner=mode,
                                      jit=False)
    w0 = time.perf_counter()
    r = solve_compiled(comp, opts)
    wall = time.perf_counter() - w0
    ok, why = r.status == "solved", r.message
    if ok:
        rep = verify_solution(comp.geometry, r)
        ok, why = rep.ok, "" if rep.ok else "verification: " + "; ".join(rep.failures[:2])
    s = r.stats
    return dict(ok=ok, status=r.status, why=why if not ok else "", cpu=s.cpu_time, wall=wall,
                logic=s.logic_cpu, share=s.logic_cpu / max(s.cpu_time, 1e-9), nlp=s.nlp_solves,
                n0=s.N0, n=s.N if r.status == "solved" else None, first=s.first_plan_time,
                conflicts=s.conflicts)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="*", default=None, help="names from examples/scalability/expected.yaml")
    ap.add_argument("--modes", nargs="*", default=["auto", "fd"], help="logic modes timed beside sequential")
    ap.add_argument("--logic-limit", type=float, default=60.0, help="seconds per first-plan search")
    ap.add_argument("--solve", action="store_true", help="also solve end to end (slow) and verify")
    ap.add_argument("--solve-mode", default="auto", help="logic mode of the end-to-end solves")
    ap.add_argument("--time-limit", type=float, default=300.0)
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--plot", default=None, metavar="PNG")
    ap.add_argument("--dir", type=Path, default=FAMILY,
                    help="problem directory with an expected.yaml (default examples/scalability; "
                         "examples/lab gives the logic share on the Lab problems)")
    args = ap.parse_args(argv)

    from gnppdsl.compile.task import build_task
    from gnppdsl.ir import load_problem

    expected = yaml.safe_load((args.dir / "expected.yaml").read_text())["problems"]
    names = args.problems or list(expected)
    unknown = [n for n in names if n not in expected]
    if unknown:
        print(f"bench_scalability: unknown problems {unknown} (see {args.dir / 'expected.yaml'})", file=sys.stderr)
        return 2
    rows = []
    for name in names:
        spec = expected[name]
        task = build_task(load_problem(args.dir / spec["file"]))
        logic = {"sequential": first_plan(task, "sequential", args.logic_limit)}
        for mode in args.modes:
            logic[mode] = first_plan(task, mode, args.logic_limit)
        runs = [solve_one(args.dir / spec["file"], args.solve_mode, seed, args.time_limit)
                for seed in range(args.seeds)] if args.solve else []
        rows.append((name, spec, logic, runs))
        print(f"  {name}: first plan " + ", ".join(
            f"{m} {c:.2f} s" + (f" (length {n})" if n is not None else f" (none, horizon {h})")
            for m, (c, n, _, h) in logic.items())
            + "".join(f"; seed {i}: {r['status']}{' verified' if r['ok'] else ' FAIL ' + r['why'][:120]} "
                      f"cpu {r['cpu']:.1f} s N {r['n']} NLP {r['nlp']} logic {r['logic']:.2f} s"
                      for i, r in enumerate(runs)), file=sys.stderr, flush=True)
    _table(rows, args)
    if args.plot:
        _plot(rows, args.plot)
    return 0


def _fmt_first(entry, limit: float) -> str:
    """CPU s to the first plan; `>c` = none within the (wall) limit after c CPU s."""
    cpu, n, _, _ = entry
    return f">{cpu:.1f}" if n is None else f"{cpu:.2f}"


def _table(rows, args) -> None:
    modes = ["sequential", *args.modes]
    print(f"Scalability (paper 000, Appendix D) on {args.dir.name}; CPU seconds (this process + "
          f"Fast Downward / cc children); logic limit {args.logic_limit:g} s"
          + (f"; end to end with planner {args.solve_mode}, {args.seeds} seed(s), time limit "
             f"{args.time_limit:g} s, solutions verified with pinocchio + coal" if args.solve else ""))
    hdr = (f"{'problem':11} {'obj':>3} {'N0 exp':>6} {'N0 proven':>9} "
           + " ".join(f"{'1st ' + m[:5]:>10}" for m in modes)
           + (f" | {'solved':>6} {'N':>3} {'NLP':>4} {'CPU s':>7} {'logic s':>7} {'share':>5} {'1st s':>5}" if args.solve else "")
           + f" | {'paper s':>9}")
    print(hdr)
    print("-" * len(hdr))
    for name, spec, logic, runs in rows:
        cpu, n, shortest, h = logic["sequential"]
        proven = str(n) if n is not None and shortest else f">={h}"
        line = (f"{name:11} {spec.get('objects', '-'):>3} {spec['n0']:>6} {proven:>9} "
                + " ".join(f"{_fmt_first(logic[m], args.logic_limit):>10}" for m in modes))
        if args.solve:
            good = [r for r in runs if r["ok"]]
            mean = (lambda k: sum(r[k] for r in good) / len(good)) if good else (lambda k: float("nan"))
            ns = "/".join(sorted({str(r["n"]) for r in good})) or "-"
            line += (f" | {len(good):>2}/{len(runs):<3} {ns:>3} {mean('nlp'):>4.0f} {mean('cpu'):>7.1f} "
                     f"{mean('logic'):>7.2f} {100 * mean('share'):>4.0f}% {mean('first'):>5.2f}")
        paper = PAPER.get(name)
        line += f" | {(f'{paper[0]:.0f} {paper[1]}' if paper else '-'):>9}"
        print(line)


def _plot(rows, path: str) -> None:
    try:
        import matplotlib
        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        print("bench_scalability: --plot needs matplotlib (pip install 'gnppdsl[bench]')", file=sys.stderr)
        return
    fig, axes = plt.subplots(1, 2, figsize=(10, 4))
    for ax, prefix, title in ((axes[0], "stack_", "Stacking boxes (Fig. 8)"),
                              (axes[1], "clutter_", "Cluttered table (Fig. 9)")):
        # x: the family's parameter (blocks; obstacles), as the paper's figures
        mine = [(int(name.split("_")[1]), logic, runs) for name, spec, logic, runs in rows if name.startswith(prefix)]
        if not mine:
            continue
        xs = [m[0] for m in mine]
        for mode, style, colour in (("sequential", "x:", "C0"), ("auto", "o-", "C1"), ("fd", "s--", "C2")):
            pts = [(x, lg[mode][0]) for x, lg, _ in mine if mode in lg and lg[mode][1] is not None]
            if pts:
                ax.plot(*zip(*pts), style, color=colour, label=f"first logical plan, {mode}")
        ends = [(x, sum(r["cpu"] for r in runs if r["ok"]) / max(1, sum(r["ok"] for r in runs)))
                for x, _, runs in mine if any(r["ok"] for r in runs)]
        if ends:
            ax.plot(*zip(*ends), "D-", color="black", label="end to end (verified), this project")
        paper = [(int(name.split("_")[1]), PAPER[name][0]) for name, spec, _, _ in rows
                 if name.startswith(prefix) and name in PAPER]
        if paper:
            ax.plot(*zip(*sorted(paper)), "^--", color="grey", label="paper 000 (read off the figure, ~)")
        ax.set_yscale("log")
        ax.set_xlabel("movable obstacles" if prefix == "clutter_" else "blocks")
        ax.set_ylabel("CPU seconds")
        ax.set_title(title)
        ax.set_xticks(xs)
        ax.legend(fontsize=7)
    fig.tight_layout()
    fig.savefig(path, dpi=120)
    print(f"plot written to {path}")


if __name__ == "__main__":
    sys.exit(main())
