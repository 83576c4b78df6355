"""The bounded subgraph matcher of `conflicts.semantic`: its necessary conditions never reject a
pair plain VF2 accepts, within the budget it answers as plain VF2, and past the budget it answers
"unknown" (None), which the database turns into a miss, never into a wrong verdict."""
from __future__ import annotations

import networkx as nx
import pytest
from hypothesis import given, settings
from hypothesis import strategies as st
from networkx.algorithms import isomorphism

from gnppdsl.conflicts import semantic
from gnppdsl.conflicts.database import Entry, SubgraphDatabase
from gnppdsl.conflicts.semantic import MATCH_STATS, SemanticGraph, monomorphism, prefilter


def _plain(pattern: SemanticGraph, target: SemanticGraph) -> dict | None:
    """The oracle: networkx's GraphMatcher with the label matches and no extras."""
    gm = isomorphism.GraphMatcher(target.graph, pattern.graph,
                                  node_match=lambda a, b: a["label"] == b["label"],
                                  edge_match=lambda a, b: a["slots"] == b["slots"])
    return next(gm.subgraph_monomorphisms_iter(), None)


@st.composite
def labelled_pair(draw):
    """A random labelled graph (target) and a pattern: often a relabelled-free subgraph of it
    (so monomorphisms exist), sometimes perturbed (a node label, an edge, a slot)."""
    n = draw(st.integers(1, 9))
    labels = draw(st.lists(st.sampled_from("abc"), min_size=n, max_size=n))
    t = nx.Graph()
    for i, lab in enumerate(labels):
        t.add_node(i, label=lab)
    pairs = [(i, j) for i in range(n) for j in range(i + 1, n)]
    for (i, j) in draw(st.lists(st.sampled_from(pairs), unique=True, max_size=14)) if pairs else []:
        t.add_edge(i, j, slots=draw(st.sampled_from(["0", "1", "0,1"])))
    keep = draw(st.lists(st.sampled_from(range(n)), min_size=1, max_size=n, unique=True))
    p = nx.Graph()
    for i in keep:
        p.add_node(f"p{i}", label=t.nodes[i]["label"])
    for u, v, d in t.subgraph(keep).edges(data=True):
        if draw(st.booleans()) or draw(st.booleans()):
            p.add_edge(f"p{u}", f"p{v}", slots=d["slots"])
    how = draw(st.sampled_from(["none", "label", "edge", "slot"]))
    nodes = sorted(p)
    if how == "label":
        p.nodes[draw(st.sampled_from(nodes))]["label"] = draw(st.sampled_from("abc"))
    elif how == "edge" and len(nodes) > 1:
        u, v = draw(st.lists(st.sampled_from(nodes), min_size=2, max_size=2, unique=True))
        p.add_edge(u, v, slots=draw(st.sampled_from(["0", "1", "0,1"])))
    elif how == "slot" and p.number_of_edges():
        u, v = sorted(p.edges())[0]
        p.edges[u, v]["slots"] = draw(st.sampled_from(["0", "1", "0,1"]))
    return SemanticGraph.from_graph(p), SemanticGraph.from_graph(t)


@settings(max_examples=400, deadline=None)
@given(labelled_pair())
def test_prefilter_and_pruning_never_change_vf2s_answer(pair):
    pattern, target = pair
    oracle = _plain(pattern, target)
    if oracle is not None:
        assert prefilter(pattern, target) is not None       # a necessary condition holds
    # unbudgeted: the very mapping plain VF2 finds first (pruning only cuts dead branches)
    assert monomorphism(pattern, target, budget=None) == oracle


def _ring(prefix: str, k: int) -> list[tuple[str, str, str]]:
    """A cycle of k factor and k variable vertices, all labelled alike (h, x) and slots alike."""
    edges = []
    for i in range(k):
        edges += [(f"{prefix}h{i}", f"{prefix}x{i}", "0"), (f"{prefix}h{i}", f"{prefix}x{(i + 1) % k}", "1")]
    return edges


def _graph(edges) -> SemanticGraph:
    g = nx.Graph()
    for u, v, s in edges:
        for n in (u, v):
            g.add_node(n, label=n.split("_")[-1][0])
        g.add_edge(u, v, slots=s)
    return SemanticGraph.from_graph(g)


def _adversarial(decoys: int, k: int) -> tuple[SemanticGraph, SemanticGraph]:
    """Pattern: a ring of size k. Target: many rings of size k-1 (every vertex passes every
    necessary condition: same labels, degrees, neighbourhoods) and, last, one ring of size k.
    A monomorphism exists; VF2 walks every decoy ring from every start before it finds it."""
    pattern = _graph(_ring("p_", k))
    target_edges = []
    for d in range(decoys):
        target_edges += _ring(f"d{d}_", k - 1)
    target_edges += _ring("t_", k)
    return pattern, _graph(target_edges)


def test_labels_of_the_adversarial_case_do_not_discriminate():
    pattern, target = _adversarial(3, 6)
    assert set(pattern.labels) == set(target.labels) == {"h", "x"}
    assert prefilter(pattern, target) is not None


def test_budget_gives_up_with_unknown_and_counts_expansions():
    pattern, target = _adversarial(30, 12)
    assert _plain(pattern, target) is not None               # the true answer is "contained"
    before = MATCH_STATS.budget_exceeded
    assert monomorphism(pattern, target, budget=None) is not None
    full = MATCH_STATS.expansions
    assert monomorphism(pattern, target, budget=500) is None  # gave up: unknown, not "no"
    assert MATCH_STATS.budget_exceeded == before + 1
    assert MATCH_STATS.expansions - full <= 501                # bounded work, counted not timed


def test_database_turns_a_budget_exhausted_lookup_into_a_miss(monkeypatch: pytest.MonkeyPatch):
    pattern, target = _adversarial(30, 12)
    db = SubgraphDatabase()
    db.infeasible.append(Entry(pattern, False, None, ""))     # a known infeasible ring
    monkeypatch.setattr(semantic, "MATCH_BUDGET", None)
    assert db.lookup(target) is False                         # unbudgeted: the target contains it
    monkeypatch.setattr(semantic, "MATCH_BUDGET", 500)
    assert db.lookup(target) is None                          # budget out: a miss (solve it)
    db2 = SubgraphDatabase()
    db2.feasible.append(Entry(target, True, None, ""))
    monkeypatch.setattr(semantic, "MATCH_BUDGET", None)
    assert db2.lookup(pattern) is True
    monkeypatch.setattr(semantic, "MATCH_BUDGET", 500)
    assert db2.lookup(pattern) is None
    assert db2.stats.budget_exceeded >= 1


def test_matching_while_loading_the_file_is_counted(tmp_path, monkeypatch: pytest.MonkeyPatch):
    """Opening a database re-checks domination between its records (one match per pair): that
    work is in `stats.budget_exceeded` / `match_time` too (before, a reopened lab5 database spent
    1.9 s CPU and 2 give-ups at open that no statistic showed)."""
    pattern, target = _adversarial(30, 12)
    path = tmp_path / "db.sqlite"
    monkeypatch.setattr(semantic, "MATCH_BUDGET", None)
    with SubgraphDatabase(path, scope="s", fingerprint="f") as db:
        assert db.add(pattern, True)
        assert db.add(target, True)            # contains the pattern: it replaces it in memory
        assert len(db.feasible) == 1
    monkeypatch.setattr(semantic, "MATCH_BUDGET", 500)
    with SubgraphDatabase(path, scope="s", fingerprint="f") as again:
        assert again.stats.loaded == 2
        assert again.stats.budget_exceeded >= 1 and again.stats.match_time > 0
        assert len(again.feasible) == 2          # domination not shown: both kept (sound, larger)
