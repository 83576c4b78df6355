"""Timing table of the nlp layer on the toy graphs (prints only; not a test).

Run: python benchmarks/bench_nlp.py   (the toy graphs are the tests' own, tests/nlp/nlp_toys.py)
"""
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path[:0] = [str(ROOT), str(ROOT / "tests" / "nlp")]
from nlp_toys import *  # noqa: E402,F403
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.feasibility import FeasibilitySolver
from gnppdsl.nlp.subgraph import find_infeasible_subgraph
print("%-12s %5s %5s %9s %9s %6s %6s" % ("graph", "|H|", "|X|", "asm ms", "solve ms", "iters", "feas"))
for name, (vs, fs) in [("discs2", discs(2)), ("discs3", discs(3)), ("discs6/c2", discs(6, c=3.0)),
                       ("chain10", chain(10, None)), ("chain40", chain(40, None)), ("chain100", chain(100, None)),
                       ("chain40-3", chain(40, 3))]:
    g = GraphNLP(fs); S = FeasibilitySolver()
    t = time.perf_counter(); S.assemble(g); ta = time.perf_counter() - t
    ts = []
    for seed in range(3):
        r = S.solve(g, seed=seed); ts.append(r.solve_time)
    print("%-12s %5d %5d %9.1f %9.1f %6d %6s" % (name, g.n_factors, len(g.variables), 1e3 * ta, 1e3 * sorted(ts)[1], r.iterations, r.feasible))
print()
print("Alg. 1 (trn) on chain(n) with the conflict at steps 3..4")
for n in (8, 16, 32, 64, 128):
    vs, fs = chain(n, 3)
    g = GraphNLP(fs); S = FeasibilitySolver()
    t = time.perf_counter(); res = find_infeasible_subgraph(g, [], "trn", solver=S); dt = time.perf_counter() - t
    print(f"n={n:4d}: {res.stats.checks} checks, {S.solves} ipopt runs, {1e3*dt:.0f} ms, conflict {res.time_range}")
