"""The pre-built reachability graph kept across processes (gnppdsl.reach.persist): a graph
restored from the store equals the one built (nodes, edges, the random stream after the draws,
so every later query), the key follows each input, and a store that is off, foreign or corrupt
is not used."""
from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_checks import LEFT_BOX  # noqa: E402

from gnppdsl.reach import graph as graph_module  # noqa: E402
from gnppdsl.reach.graph import ReachabilityGraph  # noqa: E402
from gnppdsl.reach.settings import ReachSettings  # noqa: E402

SETTINGS = ReachSettings("left_arm", workspace=LEFT_BOX, samples=24, neighbours=5, seed=4)
A, B = (-0.75, 0.25, 0.7), (-0.15, 0.25, 0.7)          # the two sides of the scene's wall


def _snapshot(g: ReachabilityGraph) -> tuple:
    nodes = [(tuple(g.G.nodes[u]["x"]), tuple(g.G.nodes[u]["q"]), g.G.nodes[u]["c"]) for u in g._ids]
    edges = sorted((min(u, v), max(u, v), d["w"] if "w" in d else tuple(sorted(d))) for u, v, d in g.G.edges(data=True))
    return nodes, edges, g.stats.draws, vars(g.stats.validation).copy()


def test_a_restored_graph_equals_the_built_one_and_answers_alike(scene, store, monkeypatch):
    built = ReachabilityGraph.from_scene(scene, SETTINGS)
    assert not built.stats.restored and len(list(store.glob("*.json"))) == 1

    def no_ik(*a, **k):
        raise AssertionError("a restored graph validates no sample")
    with monkeypatch.context() as m:
        m.setattr(graph_module, "validate_position", no_ik)
        restored = ReachabilityGraph.from_scene(scene, SETTINGS)
    assert restored.stats.restored
    assert _snapshot(restored) == _snapshot(built)
    # the random stream goes on where the build left it: queries (IK restarts, enhancement) agree
    assert restored.rng.bit_generator.state == built.rng.bit_generator.state
    p1, p2 = built.query(A, B), restored.query(A, B)
    assert p1 is not None and p2 is not None        # the wall is passable: a path exists
    assert p1.nodes == p2.nodes and p1.cost == p2.cost
    assert np.array_equal(p1.path, p2.path)


def test_the_key_follows_the_settings_and_the_scene(scene, store):
    from gnppdsl.reach import persist
    ReachabilityGraph.from_scene(scene, SETTINGS)
    ReachabilityGraph.from_scene(scene, SETTINGS.merged(seed=5))
    ReachabilityGraph.from_scene(scene, SETTINGS.merged(margin=0.02))
    assert len(list(store.glob("*.json"))) == 3
    wall = next(n for n, o in scene.objects.items() if o.static and "wall" in n)
    g = ReachabilityGraph.from_scene(scene, SETTINGS, build=False)
    obstacles = list(g.checker.obstacles)
    spec = scene.robots["left_arm"]
    key = persist.graph_key(SETTINGS, spec, g.robot, g.home, obstacles, scene, frozenset(), True)

    def shifted(o):                     # the wall 1 cm along x
        T = o.T.copy()
        T[0, 3] += 0.01
        return type(o)(o.name, o.shape, T)
    shifted = [shifted(o) if o.name == wall else o for o in obstacles]
    assert persist.graph_key(SETTINGS, spec, g.robot, g.home, shifted, scene, frozenset(), True) != key
    assert persist.graph_key(SETTINGS, spec, g.robot, g.home + 0.1, obstacles, scene, frozenset(), True) != key
    assert persist.graph_key(SETTINGS, spec, g.robot, g.home, obstacles, scene, frozenset(), False) != key


def test_switched_off_foreign_or_corrupt_stores_are_not_used(scene, tmp_path, monkeypatch):
    monkeypatch.setenv("GNPP_REACH_CACHE", "off")
    assert not ReachabilityGraph.from_scene(scene, SETTINGS).stats.restored
    # a directory another user could write to: never read, never written
    shared = tmp_path / "shared"
    shared.mkdir(mode=0o777)
    os.chmod(shared, 0o777)
    link = tmp_path / "link"
    link.symlink_to(shared)
    monkeypatch.setenv("GNPP_REACH_CACHE", str(link))
    ReachabilityGraph.from_scene(scene, SETTINGS)
    assert list(shared.iterdir()) == []
    # a corrupt record or one of another robot size is a miss, and is written again
    d = tmp_path / "own"
    monkeypatch.setenv("GNPP_REACH_CACHE", str(d))
    first = ReachabilityGraph.from_scene(scene, SETTINGS)
    [f] = d.glob("*.json")
    for bad in ("{not json", json.dumps({**json.loads(f.read_text()), "nodes": [[[0, 0, 0], [0.0], 1.0]]})):
        f.write_text(bad)
        again = ReachabilityGraph.from_scene(scene, SETTINGS)
        assert not again.stats.restored and _snapshot(again) == _snapshot(first)
        assert json.loads(f.read_text())["nodes"] == json.loads(json.dumps(first._built()))["nodes"]
