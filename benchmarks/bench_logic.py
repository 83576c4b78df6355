"""Benchmark of the logic layer (not a test: prints tables, asserts nothing about time).

    /work/venv/bin/python benchmarks/bench_logic.py [--repeat 3]

1. Time to the first plan: example problems (examples/*/*.pntc) and generated blocks towers
   (10 blocks: build a tower from the table, and reverse a tower). Columns: wall time of
   `IncrementalPlanner(...)` + `shortest_plan()`, clingo's own solve and ground time.
   Target: under 0.1 s of solver time for the 10-block tower.
2. Replanning after adding 1, 10 and 100 conflicts to the Lab example: wall time of the
   `add_conflict` calls and of the next `shortest_plan()`. Target: under 0.5 s after 100.
   Two kinds of conflicts: random ones read off random walks, and GNPP-style ones learned
   from the current plan (the facts one step of the plan changes), one per replan.
"""
from __future__ import annotations

import argparse
import random
import statistics
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.logic.generators import random_conflicts, reverse_tower_task, tower_task  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner  # noqa: E402
from gnppdsl.logic.validate import validate_plan  # noqa: E402


def load_examples():
    try:
        from gnppdsl.compile.task import build_task
        from gnppdsl.ir import load_problem
    except ImportError:
        return []
    out = []
    for path in sorted(ROOT.glob("examples/*/*.pntc")):
        if path.name == "domain.pntc":
            continue
        try:
            out.append((f"{path.parent.name}/{path.stem}", build_task(load_problem(path))))
        except Exception as exc:  # report, keep benchmarking the rest
            print(f"  (skipped {path}: {type(exc).__name__}: {exc})")
    return out


def first_plan(task, repeat):
    walls, solves, searches, grounds = [], [], [], []
    for _ in range(repeat):
        t0 = time.perf_counter()
        planner = IncrementalPlanner(task, statistics=True)
        res = planner.shortest_plan()
        walls.append(time.perf_counter() - t0)
        solves.append(planner.stats.solve_time)
        searches.append(planner.stats.clingo_solve_time)
        grounds.append(planner.stats.ground_time)
        assert res.found and validate_plan(task, res.plan).valid, res.message
    return len(res.plan), min(walls), min(solves), min(searches), min(grounds)


def transition_conflict(task, plan, rng, context=2):
    """The facts one step of the plan changes, plus `context` unchanged facts of the state
    before (like a graph-NLP conflict: the moved object and what it interacts with)."""
    i = rng.randrange(len(plan.states) - 1)
    a, b = plan.states[i], plan.states[i + 1]
    state_vars = [v for v in range(len(a)) if not task.variables[v].is_derived]
    changed = [v for v in state_vars if a[v] != b[v]]
    others = [v for v in state_vars if a[v] == b[v]]
    ctx = rng.sample(others, min(context, len(others)))
    return (PartialState(tuple((v, a[v]) for v in changed + ctx)),
            PartialState(tuple((v, b[v]) for v in changed)))


def replan_random(task, counts, seed, horizon):
    rng = random.Random(seed)
    rows = []
    for k in counts:
        planner = IncrementalPlanner(task)
        planner.shortest_plan(max_horizon=horizon)
        conflicts = random_conflicts(task, rng, k, max_len=3, max_facts=3, walk_length=10)
        t0 = time.perf_counter()
        planner.add_conflicts(conflicts)
        t_add = time.perf_counter() - t0
        res = planner.shortest_plan(max_horizon=horizon)
        t_plan = time.perf_counter() - t0 - t_add
        if res.found:
            assert validate_plan(task, res.plan, planner.conflicts).valid
        rows.append((k, len(planner.conflicts), t_add, t_plan, planner.stats.solve_time,
                     len(res.plan) if res.found else res.status.value))
    return rows


def replan_learned(task, rounds, seed, horizon):
    """GNPP-style: plan, learn a conflict from it, replan; times of the replans."""
    rng = random.Random(seed)
    planner = IncrementalPlanner(task)
    res = planner.shortest_plan(max_horizon=horizon)
    times, marks = [], {}
    for r in range(1, rounds + 1):
        if not res.found or len(res.plan) == 0:
            break
        t0 = time.perf_counter()
        planner.add_conflict(transition_conflict(task, res.plan, rng))
        res = planner.shortest_plan(max_horizon=horizon)
        times.append(time.perf_counter() - t0)
        if res.found:
            assert validate_plan(task, res.plan, planner.conflicts).valid
        if r in (1, 10, 50, 100):
            marks[r] = (times[-1], len(res.plan) if res.found else res.status.value)
    return times, marks, planner


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--repeat", type=int, default=3, help="repetitions (minimum reported)")
    ap.add_argument("--horizon", type=int, default=24, help="max horizon when replanning")
    args = ap.parse_args(argv)

    print("== time to the first plan (min of %d runs) ==" % args.repeat)
    print("wall: planner construction + shortest_plan(); solve: wall inside clingo's solve calls;")
    print("search: clingo's own solve time (statistics); ground: wall inside ground calls")
    print(f"{'task':<26}{'vars':>5}{'ops':>6}{'len':>5}{'wall s':>9}{'solve s':>9}{'search s':>10}{'ground s':>10}")
    tasks = load_examples() + [("tower10 (build)", tower_task(10)),
                               ("tower10 (reverse)", reverse_tower_task(10))]
    for name, task in tasks:
        n, wall, solve, search, ground = first_plan(task, args.repeat)
        print(f"{name:<26}{len(task.variables):>5}{len(task.operators):>6}{n:>5}"
              f"{wall:>9.4f}{solve:>9.4f}{search:>10.4f}{ground:>10.4f}")

    labs = [(n, t) for n, t in tasks if n.startswith("lab/")]
    lab = max(labs, key=lambda nt: len(nt[1].operators)) if labs else ("tower10 (build)", tower_task(10))
    name, task = lab
    print(f"\n== replanning on {name} after adding random conflicts (one planner per row) ==")
    print(f"{'added':>6}{'distinct':>9}{'add s':>9}{'replan s':>10}  result (plan length)")
    for k, distinct, t_add, t_plan, solve, result in replan_random(task, (1, 10, 100), 0, args.horizon):
        print(f"{k:>6}{distinct:>9}{t_add:>9.4f}{t_plan:>10.4f}  {result}")

    print(f"\n== GNPP-style: plan, learn a conflict from the plan, replan (on {name}) ==")
    times, marks, planner = replan_learned(task, 100, 0, args.horizon)
    for r, (t, result) in marks.items():
        print(f"  replan after conflict {r:>3}: {t:.4f} s  -> {result}")
    if times:
        print(f"  {len(times)} replans: mean {statistics.mean(times):.4f} s, max {max(times):.4f} s, "
              f"total {sum(times):.3f} s; ground calls {planner.stats.ground_calls}, "
              f"base grounded {planner.stats.count('base')}x, horizon {planner.horizon}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
