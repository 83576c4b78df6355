"""R-LGP in the solve loop (paper 002, Alg. 1): travel costs choose the plan, graph paths warm-start
trajectories. Checked on the mobile sorting domain without running the (slow) NLPs."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gnppdsl.compile.factors import VarInstance
from gnppdsl.logic.planner import IncrementalPlanner
from gnppdsl.logic.validate import plan_cost
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import Loop
from gnppdsl.solve.options import SolveOptions

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"


@pytest.fixture(scope="module")
def run():
    compiled = load_and_compile([str(MOBILE / "sort2.pntc")])
    return Loop(compiled, SolveOptions(algorithm="rlgp", time_limit=120).validated(), None)


def test_travel_costs_choose_the_cheapest_shortest_plan(run):
    task = run.task
    assert task.pair_costs and run.stats.reach_time > 0
    first = run.next_plan(enumerate_=False)
    assert first.found
    chosen = plan_cost(task, first.plan.operators)
    # every shortest plan, enumerated independently, costs at least as much under the travel costs
    other = IncrementalPlanner(task, max_horizon=len(first.plan))
    n = 0
    while True:
        res = other.next_plan(max_horizon=len(first.plan), time_limit=60)
        if not res.found or len(res.plan) > len(first.plan):
            break
        n += 1
        assert plan_cost(task, res.plan.operators) >= chosen
    assert n > 1          # a real choice was made
    # the costs are travel: a plan without them would not prefer this one necessarily
    assert chosen > sum(task.operators[o].cost for o in first.plan.operators)


def test_graph_waypoints_warm_start_trajectories(run):
    import networkx as nx

    robot = "mm"
    graph, block = run.reach[robot]
    nq = graph.robot.nc
    # two configurations the graph already holds, a few edges apart (no new IK, no enhancement)
    nodes = graph.nodes()
    a = nodes[0]
    dist = nx.single_source_shortest_path_length(graph.G.to_networkx(), a, cutoff=3)
    b = max(dist, key=lambda n: (dist[n], -n))
    assert dist[b] >= 1
    qa, qb = np.asarray(graph.G.nodes[a]["q"], float), np.asarray(graph.G.nodes[b]["q"], float)
    q = lambda i: VarInstance("q", (robot,), i, "joints", nq)
    path = VarInstance("path", (robot,), 0, "joints", 20 * nq, frozenset({"traj"}), waypoints=20)
    before = (run.stats.reach_warmstarts, run.stats.reach_waypoints)
    pts = run.reach_warmstart(path, {q(0): qa, q(1): qb})
    assert pts is not None
    # the statistics count it: one trajectory, its 20 waypoints from the graph; asked again,
    # the solution library answers (one more query, one more hit)
    assert (run.stats.reach_warmstarts, run.stats.reach_waypoints) == (before[0] + 1, before[1] + 20)
    run.reach_statistics()
    queries, hits = run.stats.reach_queries, run.stats.reach_library_hits
    assert run.stats.reach_samples == graph.num_samples and queries >= 1
    assert np.array_equal(run.reach_warmstart(path, {q(0): qa, q(1): qb}), pts)
    run.reach_statistics()
    assert (run.stats.reach_queries, run.stats.reach_library_hits) == (queries + 1, hits + 1)
    pts = pts.reshape(20, nq)
    assert np.allclose(pts[0], qa) and np.allclose(pts[-1], qb)
    # the waypoints follow the graph's path (it passes through its intermediate nodes), which
    # is not the straight line when the path has corners
    ref = graph.query_configs(qa, qb).path
    assert len(ref) >= 2
    for node_q in ref[1:-1]:
        assert np.min(np.linalg.norm(pts - node_q, axis=1)) < np.linalg.norm(qb - qa) / 2
    # not a trajectory the block does not name
    other = VarInstance("other", (robot,), 0, "joints", 20 * nq, frozenset({"traj"}), waypoints=20)
    assert run.reach_warmstart(other, {q(0): qa, q(1): qb}) is None


def test_rlgp_keyframes_start_next_to_what_they_act_on():
    """R-LGP starts a keyframe with the robot's base next to the object it picks or the tray it
    drops into, on the side nearest where the base stood before (`rlgp.reach_keyframe_starts`);
    GNPP keeps the home start. pick_place3 instance 9 (red1 0.95 m from the start, south of the
    table's centre line): from home, the first pick was made from the far side (base 10.05 m)."""
    from gnppdsl.compile.semantics import parse_plan, plan_states

    c = load_and_compile([str(MOBILE / "pick_place3.pntc")], instance=9)
    plan = ("pick(red1, mm, center); drop(red1, mm, red_tray); pick(blue1, mm, center); "
            "drop(blue1, mm, red_tray); pick(red2, mm, center); drop(red2, mm, red_tray)")
    states = plan_states(c.task, parse_plan(c.task, plan))
    targets = {1: "red1", 2: "red_tray", 3: "blue1", 4: "red_tray", 5: "red2", 6: "red_tray"}
    home = np.asarray(c.problem.scene.robots["mm"].home, float)
    table = c.problem.scene.objects["center"]
    starts = {}
    for algorithm in ("rlgp", "gnpp"):
        loop = Loop(c, SolveOptions(algorithm=algorithm, time_limit=120).validated(), None)
        g = loop.build_graph(states)
        starts[algorithm] = {v.step: np.asarray(g.initial_guess[v], float) for v in g.variables
                             if v.kind == "q" and not v.waypoints and v.step >= 1}
    assert set(starts["rlgp"]) == set(targets)
    from gnppdsl.compile.placement import RADII, base_radius
    outer = base_radius(c.problem.scene.robots["mm"]) + max(RADII)     # 0.955 m: the Panda's reach
    for step, name in targets.items():
        q = starts["rlgp"][step]
        target = np.asarray(c.problem.scene.objects[name].pose[:2], float)
        assert np.linalg.norm(q[:2] - target) <= outer + 1e-9, (step, q[:3])   # within arm's reach
        assert np.allclose(q[3:], home[3:])                                   # the arm at home
        assert np.allclose(starts["gnpp"][step], home)
    # the first pick not from the far (north) half of the room: the robot starts south of the table
    assert starts["rlgp"][1][1] <= table.pose[1]


def test_placement_across_rings_is_the_least_travel():
    """`base_next_to(..., across_rings=True)` (R-LGP's keyframe starts): the free ring point
    nearest the previous base over every ring; without it (the restarts), the innermost ring's."""
    from gnppdsl.compile.placement import BASE_RADIUS, RADII, base_next_to

    home = [0.0, -2.0, 0.0, 0.1]
    inner = base_next_to([0.0, 0.0], home, [])
    least = base_next_to([0.0, 0.0], home, [], across_rings=True)
    assert np.allclose(inner[:2], [0.0, -(BASE_RADIUS + min(RADII))])
    assert np.allclose(least[:2], [0.0, -(BASE_RADIUS + max(RADII))])
    assert np.isclose(least[2], np.pi / 2) and least[3:] == home[3:]      # facing the target, arm at home


def test_placement_uses_the_robots_own_footprint():
    """`base_radius`: the footprint of the placement's free check and rings is the robot's base
    link (its collision hull's x-y extent) plus `base_clearance`: the Panda's 0.3 m as before,
    the PR2's 0.67 m square platform 0.45 m; a PR2 base placed next to an object near the edge
    of the central table clears the table by that footprint, not the Panda's."""
    import math
    from pathlib import Path

    from gnppdsl.compile.placement import _yaw, base_next_to, base_radius
    from gnppdsl.ir.scene import load_scene_file

    root = Path(__file__).resolve().parents[2] / "examples" / "mobile"
    panda = load_scene_file(root / "sorting_setting.yaml")
    pr2 = load_scene_file(root / "sorting_pr2_setting.yaml")
    assert base_radius(panda.robots["mm"]) == pytest.approx(0.305, abs=0.01)
    r = base_radius(pr2.robots["mm"])
    assert r == pytest.approx(0.45, abs=0.01)
    obstacles = [o for o in pr2.objects.values() if o.static and len(o.pose) >= 7]
    spec = pr2.robots["mm"]
    for target in ([0.0, -0.35, 0.55], [0.5, 0.0, 0.55], [-1.8, 0.1, 0.55]):
        q = base_next_to(target, spec.home, obstacles, spec.attributes["base_min"],
                         spec.attributes["base_max"], near=spec.home, across_rings=True, radius=r)
        assert q is not None
        for o in obstacles:                       # the disc of r clears every table's rectangle
            t = _yaw(o.pose[3:7])
            dx, dy = q[0] - o.pose[0], q[1] - o.pose[1]
            lx, ly = math.cos(t) * dx + math.sin(t) * dy, -math.sin(t) * dx + math.cos(t) * dy
            gap = math.hypot(max(abs(lx) - o.shape.size[0] / 2, 0), max(abs(ly) - o.shape.size[1] / 2, 0))
            assert gap >= r - 1e-9, (target, o.name, q[:2], gap)


def _table():
    from types import SimpleNamespace as NS

    return NS(pose=[0.0, 0.0, 0.25, 0.0, 0.0, 0.0, 1.0], shape=NS(kind="box", size=(1.2, 0.9, 0.5)))


def test_travel_map_drives_around_the_table():
    """`TravelMap`: the straight line where it clears the table's footprint grown by the base's
    radius, else around its (cut) corners; never shorter than the straight line."""
    from gnppdsl.reach.drives import TravelMap

    r = 0.45
    m = TravelMap([_table()], r, (-2.2, -1.6), (2.2, 1.6))
    south, north = np.array([[0.0, -1.2]]), np.array([[0.0, 1.2]])
    d = m.distances(south, north)[0, 0]
    # at least the detour past x = 0.6 + r at y = 0, at most the one by the grown rectangle's corners
    assert 2 * np.hypot(0.6 + r, 1.2 - 0.45 - r) + 2 * (0.45 + r) >= d > 2 * np.hypot(0.6 + r, 1.2)
    assert m.distances(south, np.array([[1.5, -1.2]]))[0, 0] == pytest.approx(1.5)   # clear line
    assert m.distances(south, north)[0, 0] == pytest.approx(m.distances(north, south)[0, 0])


def test_plan_bases_take_the_side_the_whole_plan_favours():
    """R-LGP's keyframe bases (`plan_bases`, `restart_guesses(plan=plan_bases)`): a pick at the
    west end of the table followed by a put north of it is made from the west side, on the way
    north, not from the south (the ring point nearest the home base, which the greedy choice
    took: sort_random_pr2 instance 4's second pick from the west, then the NLP slid north); the
    plan's drive is the shortest of the choices."""
    from gnppdsl.compile.placement import base_next_to
    from gnppdsl.reach.drives import TravelMap, plan_bases

    r, lo, hi = 0.45, (-2.2, -1.6), (2.2, 1.9)
    home = [0.0, -1.15, 1.5708, 0.1]
    targets = [(-0.5, 0.0), (0.0, 1.5)]
    dp = plan_bases(targets, home, [_table()], lo, hi, radius=r)
    greedy, near = [], home
    for t in targets:
        near = base_next_to(t, home, [_table()], lo, hi, near=near, across_rings=True, radius=r)
        greedy.append(near)
    assert greedy[0][1] < -0.45 - r + 1e-9              # the greedy pick: south of the table
    assert dp[0][0] < -0.6 - r + 1e-9                   # the plan's: west of it
    m = TravelMap([_table()], r, lo, hi)

    def drive(qs):
        pts = [home[:2]] + [q[:2] for q in qs]
        return sum(m.distances(np.array([a]), np.array([b]))[0, 0] for a, b in zip(pts, pts[1:]))

    assert drive(dp) < drive(greedy) - 0.1
    for q, t in zip(dp, targets):                       # facing the target, the arm at home
        assert np.isclose(q[2], np.arctan2(t[1] - q[1], t[0] - q[0])) and q[3:] == home[3:]


def _pr2_plan_starts(instance: int):
    """(compiled, R-LGP's keyframe bases by step) of sort_random_pr2 `instance` for the plan
    red1 to its tray, then blue1 to its tray."""
    from gnppdsl.compile.placement import restart_guesses
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.reach.drives import plan_bases

    c = load_and_compile([str(MOBILE / "sort_random_pr2.pntc")], instance=instance)
    plan = ("pick(red1, mm, center); drop(red1, mm, red_tray); pick(blue1, mm, center); "
            "drop(blue1, mm, blue_tray)")
    states = plan_states(c.task, parse_plan(c.task, plan))
    return c, {v.step: q for v, q in restart_guesses(c.factory, c.factory.variables(states), states,
                                                     plan=plan_bases).items() if v.kind == "q"}


def test_rlgp_second_pick_of_sort_random_pr2_4_from_the_south():
    """sort_random_pr2 instance 4 (red1 at (0.44, 0.01), blue1 at (-0.42, 0.08), home south of
    the table): R-LGP's start for the second pick, blue1, is south of the table, where the whole
    plan drives (the greedy choice put it west of blue1, nearest the red tray's base, and the
    solve's base drove 4.28 m against plain GNPP's 2.20 m)."""
    _, by_step = _pr2_plan_starts(4)
    assert set(by_step) == {1, 2, 3, 4}
    assert by_step[3][1] < -0.45 - 0.45 + 1e-6          # south of the central table's footprint
    assert by_step[1][1] < -0.45 - 0.45 + 1e-6


def test_plan_bases_prefer_points_within_reach():
    """`RING_WEIGHT`: a ring point beyond the innermost ring costs drive, so the plan's bases do
    not sit on the outer ring (1.10 m from the target for the PR2, beyond its reach) to save a
    few centimetres of travel: sort_random_pr2 instance 0's first pick (red1) from 0.89 m, not
    from the 1.1 m ring diagonal to it (that run drove 4.07 m, 2.31 m before the plan choice)."""
    from gnppdsl.compile.placement import RADII, base_radius

    c, by_step = _pr2_plan_starts(0)
    r = base_radius(c.problem.scene.robots["mm"])
    red1 = np.asarray(c.problem.scene.objects["red1"].pose[:2], float)
    assert np.linalg.norm(np.asarray(by_step[1][:2]) - red1) <= r + RADII[1] + 1e-6
