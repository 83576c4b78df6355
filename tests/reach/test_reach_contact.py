"""A query end that is itself in collision (a keyframe in contact with a pair its graph-NLP does
not constrain yet): the graph joins it by segments that leave the contact (`_attach_contact`),
keeps it out of every other path, and adds no enhancement around it.

Collisions are re-checked independently of gnppdsl.reach (pinocchio + coal, `reach_checks`)."""
from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_checks import LEFT_BOX, IndependentChecker, lab_scene_with_wall  # noqa: E402

from gnppdsl.reach.graph import CONTACT, CONTACT_SHARE, ReachabilityGraph  # noqa: E402
from gnppdsl.reach.settings import ReachSettings  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
A, B = (-0.75, 0.25, 0.7), (-0.15, 0.25, 0.7)          # on both sides of the wall
SETTINGS = ReachSettings("left_arm", workspace=LEFT_BOX, samples=36, neighbours=6, seed=1)


@pytest.fixture(scope="module")
def scene():
    return lab_scene_with_wall(ROOT)


def _contact_config(g, checker):
    """A configuration between A's and B's nodes that is in contact (-5 cm < distance < 0)."""
    qa = g.G.nodes[g.attach_position(A)]["q"]
    qb = g.G.nodes[g.attach_position(B)]["q"]
    for t in np.linspace(0.0, 1.0, 41)[1:-1]:
        q = qa + t * (qb - qa)
        if -0.05 < checker.min_distance(q) < -0.002:
            return q, qa
    pytest.skip("no shallow contact configuration between A and B")


def test_a_colliding_end_gets_a_path_that_leaves_the_contact(scene):
    g = ReachabilityGraph.from_scene(scene, SETTINGS)
    checker = IndependentChecker(g.robot, scene)
    q, qa = _contact_config(g, checker)
    enhanced = g.stats.enhanced_nodes
    sol = g.query_configs(q, qa)
    assert math.isfinite(sol.cost) and len(sol.path) >= 2
    assert np.allclose(sol.path[0], q) and np.allclose(sol.path[-1], qa)
    # after its first segment the path is collision-free; the first segment collides at most
    # over its first CONTACT_SHARE and is free from its first free configuration on
    for q1, q2 in zip(sol.path[1:], sol.path[2:]):
        assert checker.segment_min_distance(q1, q2, 30) > 0.0
    ts = np.linspace(0.0, 1.0, 41)[1:]
    free = [checker.min_distance(sol.path[0] + t * (sol.path[1] - sol.path[0])) > 0.0 for t in ts]
    first = free.index(True)
    assert ts[first] <= CONTACT_SHARE + 0.05 and all(free[first:])
    # the colliding end is gone from the graph afterwards, and it brought no enhancement
    assert not any(np.allclose(g.G.nodes[n]["q"], q) for n in g.G)
    assert not [n for n, k in g.G.nodes(data="kind") if k == CONTACT]
    assert g.stats.contact_ends == 1 and g.stats.enhanced_nodes == enhanced
    for n in g.G:                              # every node that stays is free
        assert checker.min_distance(g.G.nodes[n]["q"]) > 0.0
    # the solution library answers the same query again
    assert g.query_configs(q, qa).cost == sol.cost
