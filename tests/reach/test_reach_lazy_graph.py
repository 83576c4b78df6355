"""The LazyPRM's graph without networkx (`reach.graph.LazyGraph`, `_dijkstra`): the same
shortest paths as networkx's Dijkstra, ties included (so R-LGP's paths, costs and plans are
those of before), the same components; and building and querying a reachability graph does
not import networkx (its import was ~0.12 s CPU of every R-LGP solve)."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import networkx as nx
import numpy as np
import pytest

from gnppdsl.reach.graph import LazyGraph, _dijkstra

ROOT = Path(__file__).resolve().parents[2]


def _random_graphs(seed: int) -> tuple[LazyGraph, nx.Graph]:
    """The same random additions and removals on both graphs (adjacency order decides ties)."""
    rng = np.random.default_rng(seed)
    g, h = LazyGraph(), nx.Graph()
    n = int(rng.integers(2, 30))
    for u in range(n):
        g.add_node(u, kind="sample")
        h.add_node(u, kind="sample")
    for _ in range(int(rng.integers(0, 3 * n))):
        u, v = (int(x) for x in rng.integers(0, n, 2))
        if u != v:                                   # integer costs: many equal paths
            d = {"cost": float(rng.integers(1, 4)), "checked": bool(rng.integers(0, 2))}
            g.add_edge(u, v, **d)
            h.add_edge(u, v, **d)
    for _ in range(int(rng.integers(0, 3))):         # removals, as failed checks and replacements do
        edges = list(g.edges())
        if edges:
            e = edges[int(rng.integers(0, len(edges)))]
            g.remove_edge(*e)
            h.remove_edge(*e)
    if n > 3:
        u = int(rng.integers(0, n))
        g.remove_node(u)
        h.remove_node(u)
    return g, h


@pytest.mark.parametrize("seed", range(40))
def test_dijkstra_and_components_as_networkx(seed):
    g, h = _random_graphs(seed)
    assert g.number_of_edges() == h.number_of_edges()
    assert sorted(g.edges(data="checked")) == sorted(h.edges(data="checked"))
    assert sorted(g.nodes(data="kind")) == sorted(h.nodes(data="kind"))
    nodes = list(g)
    for s in nodes[:4]:
        assert g.component(s) == nx.node_connected_component(h, s)
        for t in nodes:
            mine = _dijkstra(g, s, t)
            assert g.has_path(s, t) == nx.has_path(h, s, t) == (mine is not None)
            if mine is not None:
                assert mine == nx.single_source_dijkstra(h, s, t, weight="cost")


def test_a_reachability_query_does_not_import_networkx():
    code = ("import sys\nfrom pathlib import Path\n"
            "sys.path.insert(0, 'tests/reach')\n"
            "from reach_checks import LEFT_BOX, lab_scene_with_wall\n"
            "from gnppdsl.reach.graph import ReachabilityGraph\n"
            "from gnppdsl.reach.settings import ReachSettings\n"
            "g = ReachabilityGraph.from_scene(lab_scene_with_wall(Path('.')), ReachSettings("
            "'left_arm', workspace=LEFT_BOX, samples=12, neighbours=4, seed=1))\n"
            "print(g.travel_cost((-0.75, 0.25, 0.7), (-0.45, 0.1, 0.98)) > 0, 'networkx' in sys.modules)\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT), "GNPP_REACH_CACHE": "0"}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True, cwd=ROOT)
    assert out.stdout.split()[-2:] == ["True", "False"], out.stdout + out.stderr
