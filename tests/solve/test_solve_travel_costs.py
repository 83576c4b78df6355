"""Action costs with the reachability graph's travel in the solve layer (issue 22): a solve builds
the graph of the robot a `travel(r, a, b)` cost names, for any algorithm, and its task carries the
graph's travel where the compiled task had the lower bound `travel_lb`.

Oracles: each travel cost recomputed by hand from the graph's own nodes along the returned path
(Eq. 3 of paper 002 with the weights written in the domain, not read from the settings), the
path's ends checked against the scene YAML's coordinates; the bound w_x * distance (by hand) below
it; the cheapest assignment of items to trays by enumerating the four assignments with those
hand-computed costs; a uniform-cost search over the task (tests/compile/sas_semantics.py); the
solved plan's `plan_cost` against the hand-computed costs (slow: runs the NLPs).
"""
from __future__ import annotations

import math
import sys
from itertools import product
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "compile"))
from mobile_travel import W_X, arguments, lower_bound, scene_xy, write  # noqa: E402
from sas_semantics import optimal_cost  # noqa: E402

from gnppdsl.compile.sas import COST_RESOLUTION  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner  # noqa: E402
from gnppdsl.logic.validate import validate_plan  # noqa: E402
from gnppdsl.reach.integration import target_position  # noqa: E402
from gnppdsl.solve.compiled import load_and_compile  # noqa: E402
from gnppdsl.solve.loop import Loop  # noqa: E402
from gnppdsl.solve.options import SolveOptions  # noqa: E402

WEIGHTS = (W_X, 0.5, 0.1)      # the block's Eq. 3 weights as mobile_travel writes them
TRAYS = ("red_tray", "blue_tray")


@pytest.fixture(scope="module")
def mobile(tmp_path_factory):
    return write(tmp_path_factory.mktemp("travel"))


@pytest.fixture(scope="module")
def run(mobile):
    compiled = load_and_compile([str(mobile / "either.pntc")])
    return Loop(compiled, SolveOptions(algorithm="gnpp", time_limit=120).validated(), None)


def _by_hand(run, a: str, b: str) -> float:
    """The graph's travel from a's target to b's, summed edge by edge from the nodes' data."""
    graph, _ = run.reach["mm"]
    scene = run.compiled.problem.scene
    sol = graph.query(target_position(scene, a), target_position(scene, b))
    assert math.isfinite(sol.cost) and len(sol.nodes) >= 2
    xy = scene_xy(Path(run.compiled.problem.path).parent)
    nodes = [graph.G.nodes[n] for n in sol.nodes]
    ends = {tuple(np.round(nodes[0]["x"][:2], 9)), tuple(np.round(nodes[-1]["x"][:2], 9))}
    assert ends == {tuple(np.round(xy[a], 9)), tuple(np.round(xy[b], 9))}     # the path joins the targets
    wx, wq, wc = WEIGHTS
    total = 0.0
    for u, v, nu, nv in zip(sol.nodes, sol.nodes[1:], nodes, nodes[1:]):
        assert graph.G.has_edge(u, v) and graph.G[u][v]["checked"]          # collision-checked edges
        total += (wx * np.linalg.norm(nu["x"] - nv["x"]) + wq * np.linalg.norm(nu["q"] - nv["q"])
                  + wc * (nu["c"] + nv["c"]))
    return float(total)


def test_drops_cost_the_graph_travel_and_the_bound_is_below_it(run):
    compiled = run.compiled.task
    xy = scene_xy(Path(run.compiled.problem.path).parent)
    assert set(run.reach) == {"mm"} and run.stats.reach_time > 0
    assert not run.task.pair_costs                    # gnpp: travel costs only, no R-LGP pair costs
    strict = 0
    for op, before in zip(run.task.operators, compiled.operators):
        assert op.name == before.name
        o, _, where = arguments(op.name)
        if op.action == "pick":                        # travel_lb needs no graph: unchanged
            assert op.cost == before.cost == pytest.approx(0.5 + lower_bound(xy, where, o), abs=1e-12)
            continue
        travel = _by_hand(run, o, where)
        assert op.cost == pytest.approx(1 + travel, rel=1e-9)
        assert before.cost == pytest.approx(1 + lower_bound(xy, o, where), abs=1e-12)
        assert lower_bound(xy, o, where) <= travel + 1e-6              # admissible
        strict += travel > lower_bound(xy, o, where) + 0.1
    assert strict >= 1                                 # the graph is not the straight line


def test_clingo_optimum_under_graph_costs_is_the_cheapest_assignment(run):
    xy = scene_xy(Path(run.compiled.problem.path).parent)
    travel = {(o, t): _by_hand(run, o, t) for o in ("red1", "blue1") for t in TRAYS}

    def total(red_to: str, blue_to: str) -> float:
        return sum(0.5 + lower_bound(xy, "center", o) + 1 + travel[(o, to)]
                   for o, to in (("red1", red_to), ("blue1", blue_to)))

    costs = {(a, b): total(a, b) for a, b in product(TRAYS, TRAYS)}
    expected = min(costs.values())
    res = IncrementalPlanner(run.task).optimal_plan(4)
    assert res.plan.optimal and validate_plan(run.task, res.plan.operators).valid
    assert res.plan.cost == pytest.approx(expected, abs=4 * 0.5 / COST_RESOLUTION)
    assert optimal_cost(run.task) == pytest.approx(expected, abs=1e-9)
    best = min(costs, key=costs.get)
    names = {run.task.operators[o].name for o in res.plan.operators}
    assert {f"drop(red1, mm, {best[0]})", f"drop(blue1, mm, {best[1]})"} <= names


def test_rlgp_reuses_the_graph_for_its_pair_costs(run, monkeypatch):
    """With R-LGP the same graph serves the travel costs and the pair costs (built once), and
    the travel costs are those of the gnpp solve (same seed)."""
    from gnppdsl.reach import integration

    built = []
    real = integration.build_from_problem
    monkeypatch.setattr(integration, "build_from_problem",
                        lambda *a, **k: built.append(a[1:]) or real(*a, **k))
    other = Loop(run.compiled, SolveOptions(algorithm="rlgp", time_limit=120).validated(), None)
    assert built == [("reach",)]
    assert set(other.reach) == {"mm"} and other.task.pair_costs
    assert [op.cost for op in other.task.operators] == pytest.approx([op.cost for op in run.task.operators])


@pytest.mark.slow
@pytest.mark.mobile        # `.ci/run`: with the mobile problems
def test_solved_plan_cost_is_the_graph_travel(mobile, run):
    """The solution's plan_cost is the sum of the graph costs of its actions (it was the compiled
    task's, i.e. the lower bound's)."""
    from gnppdsl.solve.loop import solve_compiled

    compiled = load_and_compile([str(mobile / "sort2.pntc")])
    result = solve_compiled(compiled, SolveOptions(algorithm="gnpp", time_limit=300, jit=False).validated())
    assert result.solved, result.message
    xy = scene_xy(mobile)
    expected = 0.0
    for name in result.plan:
        o, _, where = arguments(name)
        expected += (0.5 + lower_bound(xy, where, o)) if name.startswith("pick") else 1 + _by_hand(run, o, where)
    assert result.stats.plan_cost == pytest.approx(expected, rel=1e-9)
    lb = sum(op.cost for op in compiled.task.operators if op.name in result.plan)
    assert result.stats.plan_cost > lb + 0.1
