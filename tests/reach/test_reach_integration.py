"""R-LGP integration: graphs from `reachability` blocks, operator targets, pair costs that change
the clingo planner's optimal plan (checked by brute-force enumeration), trajectory warm starts."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_checks import LAB, LEFT_BOX, IndependentChecker, fk_position  # noqa: E402

from gnppdsl.compile.sas import Effect, Operator, PartialState, SASTask, SASVariable  # noqa: E402
from gnppdsl.compile.semantics import applicable, initial_state, successor  # noqa: E402
from gnppdsl.errors import UserError  # noqa: E402
from gnppdsl.ir.scene import load_scene_file  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner  # noqa: E402
from gnppdsl.reach.graph import ReachabilityGraph  # noqa: E402
from gnppdsl.reach.integration import (build_from_problem, heuristic_pair_costs, operator_arguments,  # noqa: E402
                                       operator_targets, resample_polyline, select_block, settings_from_problem,
                                       warmstart_waypoints)
from gnppdsl.reach.settings import ReachSettings  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


def _cost(task, ops):
    """Plan cost by the SASTask contract: operator costs + pair costs (None before the first)."""
    total, prev = 0, None
    for o in ops:
        total += task.operators[o].cost + task.pair_costs.get((prev, o), 0)
        prev = o
    return total


def _brute_force_cheapest(task, horizon):
    """Cheapest goal-reaching plan of length <= horizon by exhaustive search."""
    best = (math.inf, None)

    def dfs(state, ops):
        nonlocal best
        if task.goal.holds_in(state):
            c = _cost(task, ops)
            if c < best[0]:
                best = (c, tuple(ops))
        if len(ops) == horizon:
            return
        for i, op in enumerate(task.operators):
            if applicable(op, state):
                dfs(successor(task, state, op), ops + [i])

    dfs(initial_state(task), [])
    return best


@pytest.fixture(scope="module")
def lab_graph():
    sc = load_scene_file(ROOT / LAB)
    return ReachabilityGraph.from_scene(sc, ReachSettings("left_arm", workspace=LEFT_BOX, samples=30, neighbours=6))


def test_pair_costs_make_the_cheapest_plan_differ_from_the_shortest(lab_graph):
    """One action reaches the goal at a far target; two actions reach it at targets near the
    start. By length the far one wins; with R-LGP travel costs the two near ones do."""
    g = lab_graph
    s0 = g.start_position
    near1, near2 = s0 + np.array([0.05, 0.08, 0.0]), s0 + np.array([0.1, 0.12, 0.0])
    far = np.array([-0.82, 0.45, 0.7])
    task = SASTask(
        variables=[SASVariable("progress", ("start", "half", "done"))], initial=(0,),
        goal=PartialState.of({0: 2}),
        operators=[Operator("reach_far()", ((0, 0),), (Effect(0, 2),)),
                   Operator("reach_near1()", ((0, 0),), (Effect(0, 1),)),
                   Operator("reach_near2()", ((0, 1),), (Effect(0, 2),))], name="travel")
    targets = {0: far, 1: near1, 2: near2}
    task.pair_costs = heuristic_pair_costs(task, targets, g, scale=100)
    # the costs are the graph's travel costs, integer-scaled, from the home position at the start
    assert task.pair_costs[(None, 0)] == round(100 * g.query_from_config(g.home, far).cost)
    assert g.query_from_config(g.home, far).path[0].tolist() == g.home.tolist()
    assert task.pair_costs[(1, 2)] == round(100 * g.travel_cost(near1, near2))
    assert task.pair_costs[(2, 1)] == task.pair_costs[(1, 2)]          # travel is symmetric
    assert 1 + task.pair_costs[(None, 0)] > 2 + task.pair_costs[(None, 1)] + task.pair_costs[(1, 2)]
    shortest = IncrementalPlanner(task).shortest_plan(max_horizon=3).unwrap()
    assert shortest.operators == (0,)
    optimal = IncrementalPlanner(task).optimal_plan(horizon=3).unwrap()
    assert optimal.operators == (1, 2) and optimal.optimal
    assert optimal.cost == _cost(task, optimal.operators) == _brute_force_cheapest(task, 3)[0]


@pytest.fixture(scope="module")
def sorting():
    from gnppdsl.compile.task import build_task
    from gnppdsl.ir import load_problem
    problem = load_problem(ROOT / "examples/mobile/sort2.pntc")
    return problem, build_task(problem)


@pytest.fixture(scope="module")
def sorting_graph(sorting):
    return build_from_problem(sorting[0], samples=30)


def test_block_settings_reach_the_graph(sorting, sorting_graph):
    problem, _ = sorting
    block = select_block(problem)
    s = sorting_graph.settings
    # the mobile domain's block names no frame: the scene robot's `ee` (the Panda's tcp)
    assert block.frame is None and s.frame == problem.scene.robots[block.robot].ee == "panda_hand_tcp"
    assert (s.robot, s.neighbours, s.weights, s.interpolation, s.ik_restarts, s.ik_tolerance, s.seed) == \
        (block.robot, block.neighbours, block.weights, block.interpolation, block.ik_restarts,
         block.ik_tolerance, block.seed)
    assert s.workspace == block.workspace and s.samples == 30 and sorting_graph.num_samples == 30
    assert settings_from_problem(problem).samples == block.samples
    with pytest.raises(UserError, match="no reachability block 'nope'"):
        select_block(problem, "nope")


def test_operator_targets_follow_the_heuristic_lines(sorting):
    problem, task = sorting
    targets = operator_targets(problem, task)
    scene = problem.scene
    for i, op in enumerate(task.operators):
        action, args = operator_arguments(op.name)
        if action == "pick":           # heuristic pick(o, r, from) : travel(r, o)
            assert np.allclose(targets[i], scene.objects[args[0]].pose[:3])
        elif action == "drop":         # heuristic drop(o, r, to) : travel(r, to): above the tray
            tray = scene.objects[args[2]]
            top = tray.pose[2] + tray.shape.size[2] / 2
            assert np.allclose(targets[i], (tray.pose[0], tray.pose[1], top + 0.05))
        else:
            assert i not in targets
    assert len(targets) == len(task.operators)


def test_sorting_optimal_plan_with_travel_costs(sorting, sorting_graph):
    problem, task = sorting
    task = SASTask(task.variables, task.initial, task.goal, task.operators, task.axioms, name=task.name)
    targets = operator_targets(problem, task)
    task.pair_costs = heuristic_pair_costs(task, targets, sorting_graph)
    assert all(isinstance(c, int) and c >= 0 for c in task.pair_costs.values())
    for (prev, op), c in list(task.pair_costs.items())[:20]:
        if prev is None:
            assert c == round(100 * sorting_graph.query_from_config(sorting_graph.home, targets[op]).cost)
        else:
            assert c == round(100 * sorting_graph.travel_cost(targets[prev], targets[op]))
    plan = IncrementalPlanner(task).optimal_plan(horizon=4).unwrap()
    best_cost, _ = _brute_force_cheapest(task, 4)
    assert plan.cost == _cost(task, plan.operators) == best_cost


def test_warmstart_waypoints_follow_a_checked_path(lab_graph):
    g = lab_graph
    checker = IndependentChecker(g.robot, load_scene_file(ROOT / LAB))
    goal = g.G.nodes[max(g.nodes("sample"), key=lambda n: np.linalg.norm(g.G.nodes[n]["x"] - g.start_position))]["q"]
    W = warmstart_waypoints(g, g.home, goal, 12)
    assert W.shape == (12, g.robot.nc)
    assert np.array_equal(W[0], g.home) and np.array_equal(W[-1], goal)
    # every waypoint lies on the graph path, spaced by at most 1/(n-1) of its joint-space length
    P = g.query_configs(g.home, goal).path
    assert len(P) >= 2
    length = np.linalg.norm(np.diff(P, axis=0), axis=1).sum()
    assert np.linalg.norm(np.diff(W, axis=0), axis=1).max() <= length / 11 + 1e-9
    for w in W:
        on = [np.linalg.norm(w - a) + np.linalg.norm(b - w) - np.linalg.norm(b - a) for a, b in zip(P, P[1:])]
        assert min(on) < 1e-9
    for q in W:
        assert checker.min_distance(q) > 0.0
        assert np.all(q >= g.robot.lower - 1e-9) and np.all(q <= g.robot.upper + 1e-9)
    # the same trajectory is answered from the library the second time
    hits, runs = g.library.hits, g.stats.dijkstra_runs
    assert np.array_equal(warmstart_waypoints(g, g.home, goal, 12), W)
    assert g.library.hits == hits + 1 and g.stats.dijkstra_runs == runs
    assert np.linalg.norm(fk_position(g.robot, W[-1], g.frame) - fk_position(g.robot, goal, g.frame)) < 1e-12


def test_resample_polyline_is_even_by_arc_length():
    pts = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 3.0]])
    out = resample_polyline(pts, 5)
    assert np.allclose(out, [[0, 0], [1, 0], [1, 1], [1, 2], [1, 3]])
    assert np.allclose(resample_polyline(pts[:1], 3), [[0, 0]] * 3)


def test_planar_problems_have_no_graph():
    from gnppdsl.ir import load_problem
    problem = load_problem(ROOT / "examples/planar/p1_one_block.pntc")
    with pytest.raises(UserError):
        build_from_problem(problem)
