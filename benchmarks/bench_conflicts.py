"""Conflicts per problem before and after issue 19's generalisation (a benchmark, not a test: it
prints, it asserts nothing).

Variants, run side by side per problem and seed, alternating (one process, CPU time):
- `plain`: the conflict Alg. 1 found, one instance (before issue 19: `lift_conflicts=False`);
- `lifted`: every symmetric instance the factory confirms, learned as one conflict
  (`gnppdsl.conflicts.lifting`, the default);
- `minimal`: lifted, and each conflict's facts minimised by the deletion filter first
  (`gnppdsl.conflicts.minimise`, `minimise_conflicts=True`).
Per run: status, N, plans, conflicts learned, ground instances they forbid, NLPs, CPU seconds
(this process + children: Fast Downward), and the independent verification of the solution
(pinocchio + coal over the domain's `avoid` pairs, `gnppdsl.solve.active_set.verify`; a failed check is a failure).
What the conflicts are (issue 19 item 4: they should grow with the kinds of geometric failure,
not with the objects): `kinds` = distinct sets of factor templates of the learned conflicts'
subgraphs (`fixed_world+grasp+kin_switch_rel`: an object out of an arm's reach where it
starts; `fixed_world+no_collision+on+on`: a pad covered by an unmoved obstacle), `found` = how
the conflicts were found (`n` the loop's NLP search on a plan, `b` a batch renaming hit by a
plan), `batch` = NLPs spent deciding renamed candidates / instances learned from them
(`gnppdsl.conflicts.batch`), `held` = ground conflict instances (originals, symmetric, batched,
interleaved) that the verified solution's states contain, read from the result's DSL text alone
(must be 0: a verified plan holding a conflict would make it a false conflict, Prop. 7.1).

    python benchmarks/bench_conflicts.py [--problems planar/p6_clutter scalability/clutter_3 ...]
        [--variants plain lifted minimal] [--seeds 1] [--time-limit 300] [--planner auto]
"""
from __future__ import annotations

import argparse
from collections import Counter
from dataclasses import replace
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ["planar/p3_occupied", "planar/p6_clutter", "planar/p7_relay", "scalability/clutter_3",
           "scalability/clutter_4", "scalability/clutter_5", "scalability/clutter_6", "scalability/stack_8",
           "scalability/stack_16", "scalability/lab4_paper", "scalability/lab5_paper"]
VARIANTS = {"plain": dict(lift_conflicts=False), "lifted": dict(lift_conflicts=True),
            "minimal": dict(lift_conflicts=True, minimise_conflicts=True)}


def run(compiled, variant: str, seed: int, time_limit: float, planner: str | None) -> dict:
    from gnppdsl.solve.loop import solve_compiled
    from gnppdsl.solve.options import SolveOptions

    opts = SolveOptions.from_settings(compiled.problem.settings, seed=seed, time_limit=time_limit, jit=False)
    opts = replace(opts, **VARIANTS[variant], **({"planner": planner} if planner else {}))
    r = solve_compiled(compiled, opts)
    # "solved" is verified (every solved result passes `active_set.verify`, else its status is
    # "verification_failed"); CPU of the solve and its child processes: Stats.cpu_time
    ok = r.status == "solved"
    s = r.stats
    return dict(status=r.status, N=s.N if ok else None, plans=s.plans, conflicts=s.conflicts,
                instances=s.conflict_instances, nlps=s.nlp_solves, min_nlps=s.minimise_checks,
                cpu=s.cpu_time, lift=s.lift_time, kinds=len(kinds(r.conflicts)),
                found=found(r.conflicts), batch=f"{s.batch_candidates}/{s.batch_learned}",
                held=len(held_by_solution(r)) if ok else "-")


def kind(conflict) -> str:
    """A conflict's kind: the sorted templates of its subgraph's factors (labels
    `name(args) -> template @step`), objects and steps left out."""
    return "+".join(sorted(label.split("->")[-1].split("@")[0].strip().split(".")[-1]
                           for label in conflict.factors))


def kinds(conflicts) -> dict[str, int]:
    """Learned conflicts per kind (`kind`)."""
    return dict(Counter(kind(c) for c in conflicts))


def found(conflicts) -> str:
    """How the conflicts were found: `n3 b1` = three by the loop's NLP search, one by a batch hit."""
    return " ".join(f"{k}{v}" for k, v in sorted(Counter(c.source[:1] for c in conflicts).items()))


def _facts(text: str) -> frozenset[str]:
    """`{parent(b1) = table, not moved(b1)}` -> its facts as text (commas inside parentheses kept)."""
    body, depth, cur, out = text.strip()[1:-1], 0, "", set()
    for ch in body:
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            out.add(cur.strip())
            cur = ""
        else:
            cur += ch
    if cur.strip():
        out.add(cur.strip())
    return frozenset(out)


def held_by_solution(result) -> list[str]:
    """The ground conflict instances (DSL text: originals, symmetric, batched, interleaved) that
    the solution's states contain at some offset, checked on the result's text alone (not the
    solver's own matching): a verified plan that holds one shows a false conflict."""
    states = [_facts(step.state) for step in result.steps]
    out = []
    for c in result.conflicts:
        for text in (c.text, *c.instances, *c.batched, *c.interleaved):
            seq = [_facts(p) for p in text.split(" -> ")]
            if any(all(p <= states[i + j] for j, p in enumerate(seq))
                   for i in range(len(states) - len(seq) + 1)):
                out.append(text)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--problems", nargs="*", default=DEFAULT, help="examples/<dir>/<name> without .pntc")
    ap.add_argument("--variants", nargs="*", default=["plain", "lifted"], choices=list(VARIANTS))
    ap.add_argument("--seeds", type=int, default=1)
    ap.add_argument("--time-limit", type=float, default=300.0)
    ap.add_argument("--planner", default=None, help="logic mode (default: the problem's setting)")
    args = ap.parse_args(argv)

    from gnppdsl.solve.compiled import load_and_compile

    print("| problem | variant | seed | status | N | plans | conflicts | kinds | found | instances | batch NLPs/learned "
          "| held | NLPs (minimise) | CPU s | lift s |")
    print("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|")
    totals: dict[tuple[str, str], list[dict]] = {}
    for name in args.problems:
        compiled = load_and_compile(str(ROOT / "examples" / f"{name}.pntc"))
        for seed in range(args.seeds):
            order = args.variants if seed % 2 == 0 else args.variants[::-1]    # alternate
            for variant in order:
                row = run(compiled, variant, seed, args.time_limit, args.planner)
                totals.setdefault((name, variant), []).append(row)
                print(f"| {name} | {variant} | {seed} | {row['status']} | {row['N']} | {row['plans']} | "
                      f"{row['conflicts']} | {row['kinds']} | {row['found']} | {row['instances']} | {row['batch']} | "
                      f"{row['held']} | {row['nlps']} ({row['min_nlps']}) | "
                      f"{row['cpu']:.1f} | {row['lift']:.2f} |", flush=True)
    base = args.variants[0]
    print(f"\nCPU ratio against {base} (mean over seeds):")
    for name in args.problems:
        ref = totals[(name, base)]
        for variant in args.variants[1:]:
            rows = totals[(name, variant)]
            ratio = sum(r["cpu"] for r in rows) / max(1e-9, sum(r["cpu"] for r in ref))
            print(f"  {name}: {variant} {ratio:.2f}x CPU, conflicts "
                  f"{sum(r['conflicts'] for r in ref) / len(ref):.1f} -> {sum(r['conflicts'] for r in rows) / len(rows):.1f}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
