"""Reachability graph (R-LGP, paper 002) timings: build time for 100 / 300 / 1000 samples of a
Panda on the Lab scene, query time (lazy Dijkstra with edge checks, then from the solution
library), IK success rate of the node validation (Eq. 2).

    /work/venv/bin/python benchmarks/bench_reach.py [--samples 100 300 1000] [--queries 20]
                                                    [--scene lab|mobile] [--seed 0]

Paper 002 reports 14.2 s for 200 samples (HSR/PR2, their IK). Prints a table; timings are
never asserted anywhere (the machine is shared).
"""
from __future__ import annotations

import argparse
import math
import statistics
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
SCENES = {
    # (scene file, robot, workspace box): the left arm's half of the Lab table
    "lab": ("examples/lab/lab.yaml", "left_arm", ((-1.0, -0.1, 0.62), (0.1, 0.6, 1.2))),
    # the mobile manipulator of the sorting scene (planar base + Panda), the domain's block box
    "mobile": ("examples/mobile/sorting.yaml", "mm", ((-1.8, -1.2, 0.5), (1.8, 1.2, 0.9))),
}


def run(scene_key: str, samples: int, queries: int, seed: int) -> dict:
    from gnppdsl.ir.scene import load_scene_file
    from gnppdsl.reach.graph import ReachabilityGraph
    from gnppdsl.reach.settings import ReachSettings

    path, robot, box = SCENES[scene_key]
    scene = load_scene_file(ROOT / path)
    settings = ReachSettings(robot, workspace=box, samples=samples, neighbours=8, seed=seed)
    t0 = time.perf_counter()
    g = ReachabilityGraph.from_scene(scene, settings)
    build = time.perf_counter() - t0
    v = g.stats.validation
    row = dict(samples=samples, draws=g.stats.draws, ik_rate=v.success_rate, solves=v.ik_solves / max(v.targets, 1),
               build=build, edges=g.G.number_of_edges())
    rng = np.random.default_rng(seed + 1)
    lo, hi = np.array(box[0]), np.array(box[1])
    pairs = [(rng.uniform(lo, hi), rng.uniform(lo, hi)) for _ in range(queries)]
    times, ok = [], 0
    for a, b in pairs:
        t = time.perf_counter()
        c = g.travel_cost(a, b)
        times.append(time.perf_counter() - t)
        ok += math.isfinite(c)
    cached = []
    for a, b in pairs:
        t = time.perf_counter()
        g.travel_cost(b, a)
        cached.append(time.perf_counter() - t)
    row.update(ok=ok, q_med=statistics.median(times), q_max=max(times), cached=statistics.median(cached),
               checks=g.stats.edge_checks, removed=g.stats.edges_removed, enhanced=g.stats.enhanced_nodes)
    return row


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--samples", type=int, nargs="+", default=[100, 300, 1000])
    ap.add_argument("--queries", type=int, default=20)
    ap.add_argument("--scene", choices=sorted(SCENES), default="lab")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    print(f"scene {args.scene}: robot {SCENES[args.scene][1]}, workspace {SCENES[args.scene][2]}, k = 8, "
          f"{args.queries} random position queries (some ends unreachable)")
    head = (f"{'samples':>7} {'draws':>6} {'IK ok':>6} {'IK/draw':>7} {'build s':>8} {'ms/node':>8} {'edges':>6} "
            f"{'q ok':>5} {'q med ms':>9} {'q max ms':>9} {'lib us':>7} {'checks':>6} {'removed':>7} {'enh':>4}")
    print(head)
    print("-" * len(head))
    for n in args.samples:
        r = run(args.scene, n, args.queries, args.seed)
        print(f"{r['samples']:>7} {r['draws']:>6} {r['ik_rate']:>6.0%} {r['solves']:>7.2f} {r['build']:>8.2f} "
              f"{1e3 * r['build'] / r['samples']:>8.1f} {r['edges']:>6} {r['ok']:>2}/{args.queries:<2} "
              f"{1e3 * r['q_med']:>9.1f} {1e3 * r['q_max']:>9.1f} {1e6 * r['cached']:>7.1f} {r['checks']:>6} "
              f"{r['removed']:>7} {r['enhanced']:>4}", flush=True)


if __name__ == "__main__":
    main()
