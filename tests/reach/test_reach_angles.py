"""Angles on the circle in the reachability graph (issue 22): the mobile base's heading (a planar
joint's third coordinate) is turned the short way round by edge checks and edge costs, and graph
waypoints become continuous warm-start paths that end at the keyframe's own angle values."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.reach.graph import SAMPLE
from gnppdsl.reach.ik_validation import NodeValidation
from gnppdsl.reach.integration import build_from_problem, graph_waypoints
from gnppdsl.reach.library import Solution

ROOT = Path(__file__).resolve().parents[2]
YAW = 2                      # sort2's mobile Panda: planar base (x, y, yaw), then the arm


@pytest.fixture(scope="module")
def graph():
    from gnppdsl.ir import load_problem
    problem = load_problem(ROOT / "examples/mobile/sort2.pntc")
    return build_from_problem(problem, build=False)


def _q(graph, yaw: float) -> np.ndarray:
    q = np.array(graph.home, dtype=float)
    q[YAW] = yaw
    return q


def test_angle_mask_comes_from_the_coordinate_kinds(graph):
    m = graph.robot.angle_mask
    assert m.dtype == bool and m.shape == (graph.robot.nc,)
    assert np.flatnonzero(m).tolist() == [YAW]


def test_edge_interpolates_the_heading_through_pi(graph):
    qs = graph.checker.segment_configs(_q(graph, -3.0), _q(graph, 3.0), steps=8, max_step=0.05)
    assert len(qs) >= 8
    yaw = qs[:, YAW]
    # the short way: from -3.0 down through -pi (== pi) to 3.0, never near 0
    assert np.all(np.abs(np.cos(yaw) + 1.0) < 1 - math.cos(0.15))
    assert np.all(np.abs(np.angle(np.exp(1j * yaw))) > 3.0 - 1e-9)
    turn = np.abs(np.diff(np.r_[-3.0, yaw, -3.0 - (2 * math.pi - 6.0)]))
    assert turn.max() < 0.1


def test_edge_cost_measures_the_short_turn(graph):
    g = graph
    x = np.array([0.5, 0.0, 0.5])
    u = g._add_node(NodeValidation(x, _q(g, -3.0), 0.0, 0), SAMPLE)
    v = g._add_node(NodeValidation(x, _q(g, 3.0), 0.0, 0), SAMPLE)
    w = g._add_node(NodeValidation(x, _q(g, 3.0 + 4 * math.pi), 0.0, 0), SAMPLE)
    try:
        wq = g.settings.weights[1]
        short = 2 * math.pi - 6.0                       # ~0.283
        assert g.edge_cost(u, v) == pytest.approx(wq * short, abs=1e-9)
        assert g.edge_cost(v, w) == pytest.approx(0.0, abs=1e-9)   # the same heading, two turns apart
    finally:
        for n in (u, v, w):
            g._remove_node(n)


class _StubGraph:
    """A graph whose only path is a fixed list of node configurations (angles as IK left them)."""

    def __init__(self, robot, path):
        self.robot = robot
        self._path = np.asarray(path, dtype=float)

    def query_configs(self, qa, qb):
        return Solution((("q", ()), ("q", ())), self._path, 1.0, tuple(range(len(self._path))))


def test_warm_start_path_is_continuous_and_ends_at_the_keyframe(graph):
    qa = _q(graph, 3.0)
    qb = _q(graph, 3.3)                                 # the keyframe's own value (== -2.983 on the circle)
    nodes = [qa, _q(graph, 3.1 - 2 * math.pi), _q(graph, -3.05), _q(graph, 3.25 - 4 * math.pi), qb]
    pts, used = graph_waypoints(_StubGraph(graph.robot, nodes), qa, qb, 12)
    assert used
    assert pts.shape == (12, graph.robot.nc)
    assert np.array_equal(pts[0], qa) and np.array_equal(pts[-1], qb)
    assert np.max(np.abs(np.diff(pts[:, YAW]))) < 0.1
    assert np.all((pts[:, YAW] >= 3.0 - 1e-9) & (pts[:, YAW] <= 3.3 + 1e-9))


def test_warm_start_spreads_a_whole_turn_to_reach_the_keyframe(graph):
    """The graph path winds to qb's heading minus 2*pi: the remainder is spread over the rows,
    the path stays continuous (no 2*pi jump) and ends exactly at qb."""
    qa = _q(graph, 0.0)
    qb = _q(graph, 2 * math.pi + 0.2)
    nodes = [qa, _q(graph, 0.1), _q(graph, 0.2)]
    pts, _ = graph_waypoints(_StubGraph(graph.robot, nodes), qa, qb, 30)
    assert np.array_equal(pts[-1], qb) and np.array_equal(pts[0], qa)
    assert np.max(np.abs(np.diff(pts[:, YAW]))) < 2 * math.pi / 29 + 0.2 / 29 + 1e-9
