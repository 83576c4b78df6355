"""The lazy edge checks' outcomes kept with the pre-built graph (`ReachabilityGraph.check_edge`,
`keep_checks`, `reach.persist.load_checks` / `save_checks`): a later graph of the same key asks
the store instead of coal and answers every query alike (same nodes, edges removed, paths);
no store, or a corrupt one, changes nothing."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_checks import LEFT_BOX  # noqa: E402

from gnppdsl.reach import persist  # noqa: E402
from gnppdsl.reach.collision import CollisionChecker  # noqa: E402
from gnppdsl.reach.graph import ReachabilityGraph  # noqa: E402
from gnppdsl.reach.settings import ReachSettings  # noqa: E402

SETTINGS = ReachSettings("left_arm", workspace=LEFT_BOX, samples=24, neighbours=5, seed=4)
A, B = (-0.75, 0.25, 0.7), (-0.15, 0.25, 0.7)          # the two sides of the scene's wall


def _answers(g: ReachabilityGraph):
    sol = g.query(A, B)
    return sol.nodes, sol.cost, sol.path.copy(), g.stats.edge_checks, g.stats.edges_removed


def test_a_later_graph_answers_its_edge_checks_from_the_store_alike(scene, store, monkeypatch):
    first = ReachabilityGraph.from_scene(scene, SETTINGS)
    a = _answers(first)
    assert a[3] > 0 and a[4] > 0            # checks made, some edges through the wall removed
    assert first.stats.stored_checks == 0
    assert first.keep_checks() and len(list(store.glob("*.checks.json"))) == 1
    assert not first.keep_checks()          # nothing new since

    def no_coal(*args, **kw):
        raise AssertionError("a stored segment is not checked again")
    monkeypatch.setattr(CollisionChecker, "segment_free", no_coal)
    later = ReachabilityGraph.from_scene(scene, SETTINGS)
    b = _answers(later)
    assert b[0] == a[0] and b[1] == a[1] and np.array_equal(b[2], a[2]) and b[3:] == a[3:]
    assert later.stats.stored_checks == later.stats.edge_checks == a[3]


def test_without_a_store_or_with_a_corrupt_one_every_check_is_made(scene, store, monkeypatch):
    first = ReachabilityGraph.from_scene(scene, SETTINGS)
    a = _answers(first)
    first.keep_checks()
    for f in store.glob("*.checks.json"):
        f.write_text("{not json")
    again = ReachabilityGraph.from_scene(scene, SETTINGS)
    assert _answers(again)[:2] == a[:2] and again.stats.stored_checks == 0
    monkeypatch.setenv("GNPP_REACH_CACHE", "0")
    off = ReachabilityGraph.from_scene(scene, SETTINGS)
    assert _answers(off)[:2] == a[:2] and off.stats.stored_checks == 0
    assert not off.keep_checks()


def test_the_store_keeps_the_latest_outcomes(store, monkeypatch):
    monkeypatch.setattr(persist, "MAX_CHECKS", 3)
    assert persist.save_checks("k", {"a": True, "b": False})
    assert persist.save_checks("k", {"c": True, "d": False})      # merged with what is stored
    assert persist.load_checks("k") == {"b": False, "c": True, "d": False}
    assert persist.load_checks("other") == {}
