"""End-to-end on the planar examples: .pntc -> plan + continuous values, checked independently.

- soundness: every factor of the full graph-NLP, rebuilt by the factory from the returned plan,
  holds at the returned values under the numpy evaluator (and the plan is valid);
- conflicts are real: each extracted conflict's subgraph stays infeasible from many starts;
- completeness: where brute force can enumerate every plan up to N, GNPP finds the same N;
- N0 / N as recorded in examples/planar/expected.yaml (N > N0 problems included).
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from solve_checks import check_conflict_infeasible, check_solution

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
EXPECTED = yaml.safe_load((PLANAR / "expected.yaml").read_text())["problems"]

from gnppdsl.solve.brute import brute_force  # noqa: E402
from gnppdsl.solve.compiled import load_and_compile  # noqa: E402
from gnppdsl.solve.loop import solve_compiled  # noqa: E402
from gnppdsl.solve.options import SolveOptions  # noqa: E402

_COMPILED: dict[str, object] = {}


def compiled(name: str):
    if name not in _COMPILED:
        _COMPILED[name] = load_and_compile([str(PLANAR / EXPECTED[name]["file"])])
    return _COMPILED[name]


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_gnpp_trn_on_planar(name):
    exp = EXPECTED[name]
    c = compiled(name)
    horizon = (exp["n"] or exp["n0"] + 2)
    res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, switches="trn", time_limit=60,
                                                       max_horizon=horizon))
    assert res.stats.N0 == exp["n0"]
    if exp["n"] is None:
        assert res.status == "no_plan", res.message
    else:
        assert res.solved, res.message
        assert res.stats.N == exp["n"]
        check_solution(c, res)
    if exp["n"] is not None and exp["n"] > exp["n0"]:
        assert res.conflicts, "N > N0 needs at least one conflict"
    for conflict in res.conflicts:
        check_conflict_infeasible(c, conflict)


@pytest.mark.parametrize("name", sorted(n for n, e in EXPECTED.items() if e.get("brute_force")))
def test_completeness_against_brute_force(name):
    exp = EXPECTED[name]
    c = compiled(name)
    L = exp["n"] if exp["n"] is not None else exp["n0"] + 1
    bf = brute_force(c, L, time_limit=60)
    assert bf.exhausted, "brute force did not finish"
    res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, switches="trn", time_limit=60,
                                                       max_horizon=L))
    assert res.stats.N == bf.shortest
    assert res.solved == (bf.shortest is not None)


@pytest.mark.parametrize("algorithm,switches", [("oneway", ""), ("gnpp", "t"), ("gnpp", "trng")])
def test_other_algorithms_on_the_occupied_target(algorithm, switches):
    c = compiled("p3_occupied")
    res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, algorithm=algorithm, switches=switches,
                                                       time_limit=60, max_horizon=4))
    assert res.solved and res.stats.N0 == 2 and res.stats.N == 4
    check_solution(c, res)
    for conflict in res.conflicts:
        if conflict.source != "plan":
            check_conflict_infeasible(c, conflict)


def test_gnpp_needs_fewer_nlps_than_oneway_when_branching_grows():
    """Counts (deterministic for a seed), not timings: on p6_clutter (p3 with distractor blocks
    and too-small regions) the conflicts prune what One-way has to enumerate plan by plan, so
    GNPP_trn needs fewer plans, fewer NLPs and fewer solver runs (measured: 4 plans / 12 NLPs
    vs 30 / 30)."""
    c = compiled("p6_clutter")
    runs = {}
    for algorithm, switches in (("oneway", ""), ("gnpp", "trn")):
        res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, algorithm=algorithm,
                                                           switches=switches, time_limit=120, max_horizon=4))
        assert res.solved and res.stats.N0 == 2 and res.stats.N == 4
        check_solution(c, res)
        runs[algorithm] = res.stats
    assert 2 * runs["gnpp"].plans < runs["oneway"].plans
    assert runs["gnpp"].nlp_solves < runs["oneway"].nlp_solves
    assert runs["gnpp"].ipopt_runs < runs["oneway"].ipopt_runs


def test_screened_relaxation_levels_keep_conflicts_real():
    """t1_swap, seed 1, full_first: the full graph's convergence point leaves residuals of ~1e-5
    on grasp factors, so without screening the relaxations without collisions are checked only
    to be found feasible. With screening (default) they are skipped: no more NLPs (since start
    certificates, those levels cost no NLP either: the initial guess satisfies them), the same
    N, and every conflict is still confirmed infeasible from many starts."""
    c = compiled("t1_swap")
    runs = {}
    for screen in (0.0, 1e-4):
        res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, switches="trn", seed=1,
                                                           order="full_first", time_limit=60,
                                                           screen_tolerance=screen))
        assert res.solved and res.stats.N == 6
        check_solution(c, res)
        for conflict in res.conflicts:
            check_conflict_infeasible(c, conflict)
        runs[screen] = res.stats
    assert runs[0.0].screened_levels == 0 < runs[1e-4].screened_levels
    assert runs[1e-4].nlp_solves <= runs[0.0].nlp_solves
