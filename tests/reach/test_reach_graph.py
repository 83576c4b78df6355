"""The R-LGP reachability graph on the Lab scene (left Panda) with an extra wall.

Every claim is re-checked independently of gnppdsl.reach: positions with pinocchio's
framesForwardKinematics, collisions with pinocchio geometry placements + direct coal calls on
the individual link shapes, shortest paths with networkx's Bellman-Ford, edge costs from Eq. 3.
"""
from __future__ import annotations

import math
import sys
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_checks import LEFT_BOX, IndependentChecker, fk_position, lab_scene_with_wall  # noqa: E402

from gnppdsl.errors import UserError  # noqa: E402
from gnppdsl.reach.graph import ENHANCE, QUERY, SAMPLE, ReachabilityGraph  # noqa: E402
from gnppdsl.reach.settings import ReachSettings  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
A, B, C = (-0.75, 0.25, 0.7), (-0.15, 0.25, 0.7), (-0.45, 0.1, 0.98)   # A, B on both sides of the wall
SETTINGS = ReachSettings("left_arm", workspace=LEFT_BOX, samples=36, neighbours=6, seed=1)


@pytest.fixture(scope="module")
def scene():
    return lab_scene_with_wall(ROOT)


@pytest.fixture(scope="module")
def graph(scene):
    return ReachabilityGraph.from_scene(scene, SETTINGS)


@pytest.fixture(scope="module")
def checker(graph, scene):
    return IndependentChecker(graph.robot, scene)


def _assert_node_valid(g, n, checker):
    d = g.G.nodes[n]
    tol = g.settings.ik_tolerance
    assert np.linalg.norm(fk_position(g.robot, d["q"], g.frame) - d["x"]) <= tol + 1e-9
    assert np.all(d["q"] >= g.robot.lower - 1e-9) and np.all(d["q"] <= g.robot.upper + 1e-9)
    assert checker.min_distance(d["q"]) > 0.0
    if d["kind"] != QUERY:     # sampled nodes lie in the workspace box
        assert np.all(d["x"] >= np.array(LEFT_BOX[0]) - 1e-12) and np.all(d["x"] <= np.array(LEFT_BOX[1]) + 1e-12)


def test_prebuilt_graph_nodes_edges_and_costs(graph, checker):
    g = graph
    assert g.num_samples == SETTINGS.samples
    for n in g.G:
        _assert_node_valid(g, n, checker)
    # k-nearest-neighbour edges (by position), all unchecked before any query (lazy)
    X = {n: g.G.nodes[n]["x"] for n in g.G}
    for n in g.G:
        dist = sorted((float(np.linalg.norm(X[m] - X[n])), m) for m in g.G if m != n)
        for _, m in dist[:SETTINGS.neighbours]:
            assert g.G.has_edge(n, m)
    for u, v, d in g.G.edges(data=True):
        assert d["checked"] is False
        wx, wq, wc = SETTINGS.weights
        a, b = g.G.nodes[u], g.G.nodes[v]
        expected = (wx * math.dist(a["x"], b["x"]) + wq * math.dist(a["q"], b["q"]) + wc * (a["c"] + b["c"]))
        assert d["cost"] == pytest.approx(expected, rel=1e-12)
    # the IK cost of Eq. 2 is the squared position error of the node
    for n in g.G:
        err = np.linalg.norm(fk_position(g.robot, g.G.nodes[n]["q"], g.frame) - g.G.nodes[n]["x"])
        assert g.G.nodes[n]["c"] == pytest.approx(err ** 2, abs=1e-12)


def test_lazy_queries_are_shortest_and_collision_free(graph, checker):
    g = graph
    for a, b in [(A, B), (B, C), (A, C)]:
        sol = g.query(a, b)
        assert math.isfinite(sol.cost)
        s, t = sol.nodes[0], sol.nodes[-1]
        assert np.allclose(g.G.nodes[s]["x"], a) and np.allclose(g.G.nodes[t]["x"], b)
        # the path's configurations reach its ends (pinocchio)
        assert np.linalg.norm(fk_position(g.robot, sol.path[0], g.frame) - a) <= 1e-3
        assert np.linalg.norm(fk_position(g.robot, sol.path[-1], g.frame) - b) <= 1e-3
        # Dijkstra's answer is the shortest path of the current graph (Bellman-Ford agrees) and
        # every edge on it has been checked
        assert sol.cost == pytest.approx(nx.bellman_ford_path_length(g.G.to_networkx(), s, t, weight="cost"), rel=1e-12)
        assert sol.cost == pytest.approx(sum(g.G[u][v]["cost"] for u, v in zip(sol.nodes, sol.nodes[1:])), rel=1e-12)
        assert all(g.G[u][v]["checked"] for u, v in zip(sol.nodes, sol.nodes[1:]))
        # dense independent check: 4x finer than the graph's own, no margin
        for q1, q2 in zip(sol.path, sol.path[1:]):
            n = 4 * len(g.checker.segment_configs(q1, q2, g.settings.interpolation, g.settings.max_joint_step)) + 2
            assert checker.segment_min_distance(q1, q2, n) > 0.0
    # the wall makes some lazily assumed edges collide: they were found and removed
    assert g.stats.edges_removed > 0
    for n in g.G:
        _assert_node_valid(g, n, checker)


def test_removed_edges_really_collide(scene, checker):
    """On a fresh graph: the lazy answer equals the shortest path of the fully validated graph,
    and every edge the check removed fails a dense independent check (no false removals)."""
    g = ReachabilityGraph.from_scene(scene, SETTINGS.merged(margin=0.0))
    coords = {n: g.G.nodes[n]["q"] for n in g.G}
    sol = g.query(A, B)
    s, t = sol.nodes[0], sol.nodes[-1]
    unchecked = [(u, v) for u, v, c in g.G.edges(data="checked") if not c]
    removed = [(u, v) for u, v in unchecked if not g.check_edge(u, v)]
    assert removed, "the wall should block some k-NN edges"
    assert sol.cost == pytest.approx(nx.bellman_ford_path_length(g.G.to_networkx(), s, t, weight="cost"), rel=1e-12)
    for u, v in removed[:5]:
        qs = g.checker.segment_configs(coords[u], coords[v], g.settings.interpolation, g.settings.max_joint_step)
        assert min(checker.min_distance(q) for q in qs) <= 1e-6


def test_library_answers_both_directions(graph):
    g = graph
    sol = g.query(A, B)
    runs, hits = g.stats.dijkstra_runs, g.library.hits
    back = g.query(B, A)
    assert g.stats.dijkstra_runs == runs and g.library.hits == hits + 1
    assert back.cost == sol.cost
    assert np.array_equal(back.path, sol.path[::-1])
    cost, path = g.path(B, A)
    assert cost == sol.cost and path.shape == sol.path.shape


def test_travel_costs_obey_the_triangle_inequality(graph):
    g = graph
    pts = [A, B, C, (-0.3, 0.35, 0.85)]
    for a in pts:
        for b in pts:
            for c in pts:
                assert g.travel_cost(a, c) <= g.travel_cost(a, b) + g.travel_cost(b, c) + 1e-9
    assert g.travel_cost(A, A) == 0.0


def test_unreachable_ends(graph):
    g = graph
    cost, path = g.path(A, (3.0, 0.0, 0.8))              # far out of reach
    assert cost == math.inf and path.shape == (0, g.robot.nc)
    cost, _ = g.path(A, (-0.3, 0.2, 0.58))                # inside the table (g_prec of Eq. 2)
    assert cost == math.inf
    assert g.stats.validation.in_obstacle >= 1


def test_enhancement_reconnects_an_isolated_end(scene, checker):
    g = ReachabilityGraph.from_scene(scene, SETTINGS.merged(samples=20, seed=3))
    u = g.attach_position(B)
    for v in list(g.G.neighbors(u)):         # pretend all its edges failed their checks
        g.G.remove_edge(u, v)
        g._invalid.add(frozenset((u, v)))
    s = g.attach_position(A)
    r = g.shortest_path(s, u)
    assert r is not None and g.stats.enhanced_nodes > 0
    new = g.nodes(ENHANCE)
    assert new and any(g.G.has_edge(u, n) for n in new)
    for n in new:
        _assert_node_valid(g, n, checker)
        assert all(g.G[n][m]["checked"] for m in g.G.neighbors(n))   # enhancement checks its edges
    for q1, q2 in zip(r.waypoints, r.waypoints[1:]):
        assert checker.segment_min_distance(q1, q2, 40) > 0.0


def test_same_seed_same_graph(scene):
    s = SETTINGS.merged(samples=8)
    g1 = ReachabilityGraph.from_scene(scene, s)
    g2 = ReachabilityGraph.from_scene(scene, s)
    assert sorted(g1.G.edges()) == sorted(g2.G.edges())
    for n in g1.G:
        assert np.array_equal(g1.G.nodes[n]["x"], g2.G.nodes[n]["x"])
        assert np.array_equal(g1.G.nodes[n]["q"], g2.G.nodes[n]["q"])
    g3 = ReachabilityGraph.from_scene(scene, s.merged(seed=7))
    assert not np.array_equal(g1.G.nodes[0]["x"], g3.G.nodes[0]["x"])
    assert all(g1.G.nodes[n]["kind"] == SAMPLE for n in g1.G)


def test_bad_settings_are_user_errors(scene):
    with pytest.raises(UserError, match="3-D box"):
        ReachSettings("left_arm", workspace=((0, 0), (1, 1)))
    with pytest.raises(UserError, match="not in scene"):
        ReachabilityGraph.from_scene(scene, ReachSettings("nobody"), build=False)
    with pytest.raises(UserError, match="no frame"):
        ReachabilityGraph.from_scene(scene, ReachSettings("left_arm", frame="panda_hnd"), build=False)


def test_isolated_node_is_replaced_by_connected_samples(scene, checker):
    g = ReachabilityGraph.from_scene(scene, SETTINGS.merged(samples=16, seed=5))
    w = g.nodes(SAMPLE)[0]
    x = g.G.nodes[w]["x"].copy()
    for v in list(g.G.neighbors(w)):
        g.G.remove_edge(v, w)
        g._invalid.add(frozenset((v, w)))
    g._replace_isolated(w)
    assert w not in g.G and g.stats.replaced_nodes == 1
    new = g.nodes(ENHANCE)
    assert new and all(g.G.degree(n) > 0 for n in new)
    for n in new:
        _assert_node_valid(g, n, checker)
        assert np.linalg.norm(g.G.nodes[n]["x"] - x) < 5 * SETTINGS.enhance_sigma


def test_snap_radius_reuses_a_nearby_node(scene):
    g = ReachabilityGraph.from_scene(scene, SETTINGS.merged(samples=8, snap_radius=0.05))
    x = g.G.nodes[0]["x"] + np.array([0.01, 0.0, 0.0])
    n = g.G.number_of_nodes()
    assert g.attach_position(x) == 0 and g.G.number_of_nodes() == n
    exact = ReachabilityGraph.from_scene(scene, SETTINGS.merged(samples=8))
    u = exact.attach_position(x)
    assert u not in (None, 0) and np.allclose(exact.G.nodes[u]["x"], x)
