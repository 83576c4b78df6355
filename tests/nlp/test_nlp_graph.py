"""GraphNLP: Definition 4.2 subgraphs, relaxations, components, time slices."""
from __future__ import annotations

from dataclasses import replace

import networkx as nx

from gnppdsl.compile.factors import VarInstance
from gnppdsl.nlp.graph import FactorRef, Graph, GraphNLP, connected_components

from nlp_toys import chain, discs, factor, no_overlap, pose, in_box
from gnppdsl.ir.expr import Constraint, Num, Slot


def test_bipartite_structure_and_labels():
    vs, fs = discs(3)
    g = GraphNLP(fs)
    assert nx.is_bipartite(g.graph.to_networkx())
    assert all(isinstance(u, FactorRef) != isinstance(v, FactorRef) for u, v in g.graph.edges())
    assert g.n_factors == 6 and set(g.variables) == set(vs)
    for r, f in g.iter_factors():
        assert set(g.neighbours(r)) == set(f.variables)
        assert g.graph.nodes[r]["label"] == f.template
        d = g.graph.nodes[r]
        assert (d["template"], d["step"], d["tags"], d["generator"], d["factor"]) == \
            (f.template, f.step, f.tags, f.generator, f)
    assert g.graph.nodes[vs[0]]["label"] == "pose(b0)"
    assert g.graph.nodes[vs[0]]["kind"] == "pose"
    assert g.graph.edges[FactorRef(3), vs[1]]["slots"] == (1,)


def test_subgraph_definition_4_2():
    vs, fs = discs(3)
    g = GraphNLP(fs)
    m = g.subgraph(variables=vs[:2])
    # keeps in_box(b0), in_box(b1), no_overlap(b0, b1); drops factors touching b2
    assert {g.factor(r).label for r in m.factor_refs} == {fs[0].label, fs[1].label, fs[3].label}
    assert all(set(m.neighbours(r)) <= set(vs[:2]) for r in m.factor_refs)
    spanned = g.subgraph(factors=[3])
    assert set(spanned.variables) == {vs[0], vs[1]} and spanned.factor_refs == [FactorRef(3)]
    both = g.subgraph(variables=[vs[0]], factors=[0, 3])
    assert both.factor_refs == [FactorRef(0)]
    # subgraphs share the full factor list and their vertices are vertices of G
    assert m.factors is g.factors and set(m.graph) <= set(g.graph)


def test_relaxation_drops_tagged_variables_and_their_factors():
    vs, fs = discs(2)
    robot = VarInstance("q", ("r",), 0, "SE2", 3, frozenset({"robot"}))
    fs = fs + [no_overlap(robot, vs[0], 0.1, 1.0, 0, tags=("robotcol",)),
               factor("toy.home", [robot], [Constraint(Slot(0), "==", Num(0.0))], 0, ("init",))]
    g = GraphNLP(fs)
    r = g.apply_relaxation({"robot"})
    assert robot not in r and all(robot not in r.factor(x).variables for x in r.factor_refs)
    assert r.n_factors == 3
    r2 = g.apply_relaxation({"collision"})
    assert {r2.factor(x).template for x in r2.factor_refs} == {"toy.in_box", "toy.no_overlap",
                                                               "toy.home"}
    assert r2.n_factors == 4


def test_connected_components_and_time_slice():
    vs, fs = discs(3)
    g = GraphNLP(fs).apply_relaxation({"collision"})
    comps = g.connected_components()
    assert len(comps) == 3 and all(c.n_factors == 1 for c in comps)
    vs, fs = chain(6)
    g = GraphNLP(fs)
    assert g.steps == (0, 6)
    s = g.time_slice(3, 4)
    assert {s.factor(r).template for r in s.factor_refs} == {"toy.move", "toy.left", "toy.right"}
    assert {v.step for v in s.variables} == {3, 4}
    assert g.time_slice(2, 2).n_factors == 0          # a transition factor needs both ends
    assert g.time_slice(0, 6).signature() == g.signature()
    rel = s.relative_labels()
    assert sorted(d["rel_step"] for _, d in rel.nodes(data=True)) == [0, 0, 0, 1, 1]


from hypothesis import given, settings, strategies as st  # noqa: E402


@settings(max_examples=60, deadline=None)
@given(n=st.integers(1, 8), seed=st.integers(0, 10_000), tags=st.sets(st.sampled_from(
    ["time", "collision", "object", "region", "init"])))
def test_subgraph_invariants_on_random_graphs(n, seed, tags):
    import random
    rnd = random.Random(seed)
    _, fs1 = chain(n, conflict_at=rnd.choice([None, 0]) if n > 0 else None)
    _, fs2 = discs(rnd.randint(1, 4))
    g = GraphNLP(fs1 + fs2)
    xs = [v for v in g.variables if rnd.random() < 0.6]
    m = g.subgraph(variables=xs)
    # Definition 4.2: every kept factor has all its variables kept; and every factor of G
    # whose variables are all kept is kept (the largest such subgraph)
    assert all(set(m.neighbours(r)) <= set(xs) for r in m.factor_refs)
    assert {r for r in g.factor_refs if set(g.neighbours(r)) <= set(xs)} == set(m.factor_refs)
    r = g.apply_relaxation(tags)
    assert not any(r.factor(x).tags & tags for x in r.factor_refs)
    assert not any(v.tags & tags for v in r.variables)
    assert all(set(r.neighbours(x)) == set(r.factor(x).variables) for x in r.factor_refs)
    comps = r.connected_components()
    assert sorted(x for c in comps for x in c.factor_refs) == r.factor_refs
    lo, hi = sorted(rnd.sample(range(n + 1), 2)) if n > 0 else (0, 0)
    s = g.time_slice(lo, hi)
    assert all(lo <= v.step <= hi for v in s.variables)
    assert all(lo <= s.factor(x).step <= s.factor(x).step + s.factor(x).span - 1 <= hi
               for x in s.factor_refs)
    assert set(s.graph) <= set(g.graph)


@settings(max_examples=80, deadline=None)
@given(ops=st.lists(st.tuples(st.sampled_from(["node", "edge", "edges", "remove"]),
                              st.integers(0, 7), st.integers(0, 7), st.integers(0, 3)), max_size=40),
       mapping=st.dictionaries(st.integers(0, 7), st.integers(10, 17), max_size=4))
def test_graph_behaves_as_networkx_graph(ops, mapping):
    """`Graph` (what a GraphNLP holds instead of networkx.Graph) against networkx.Graph as the
    oracle: the same operations give the same nodes, attributes, edges, degrees, neighbours,
    components, copies and relabellings (nodes as the mapped objects)."""
    ours, ref = Graph(), nx.Graph()
    for op, u, v, a in ops:
        if op == "node":
            ours.add_node(u, a=a)
            ref.add_node(u, a=a)
        elif op == "edge":
            ours.add_edge(u, v, w=a)
            ref.add_edge(u, v, w=a)
        elif op == "edges":
            ours.add_edges_from([(u, v, {"k": a}), (v, (v + 1) % 8)])
            ref.add_edges_from([(u, v, {"k": a}), (v, (v + 1) % 8)])
            ours.add_nodes_from([(u, {"b": a}), 7 - v])
            ref.add_nodes_from([(u, {"b": a}), 7 - v])
        else:
            ours.remove_nodes_from([u, v])
            ref.remove_nodes_from([u, v])

    def same(g: Graph, h) -> None:
        assert dict(g.nodes(data=True)) == dict(h.nodes(data=True))
        assert list(g) == list(h) and len(g) == g.number_of_nodes() == h.number_of_nodes()
        assert {frozenset((x, y)): d for x, y, d in g.edges(data=True)} == \
            {frozenset((x, y)): d for x, y, d in h.edges(data=True)}
        assert len(g.edges) == h.number_of_edges()
        for n in h:
            assert n in g and g.degree(n) == h.degree(n)
            assert set(g.neighbors(n)) == set(h.neighbors(n)) == set(g.adj[n])
            for m in h[n]:
                assert g.has_edge(n, m) and g.edges[n, m] == h.edges[n, m]
        assert sorted(map(sorted, connected_components(g))) == sorted(map(sorted, nx.connected_components(h)))

    same(ours, ref)
    same(ours.to_networkx(), ref)
    c = ours.copy()
    same(c, ref)
    for n in list(c)[:1]:
        c.nodes[n]["new"] = 1                   # a copy's attribute dicts are its own
        assert "new" not in ours.nodes[n]
    same(ours.relabelled(mapping), nx.relabel_nodes(ref, mapping, copy=True))
    assert [] not in ours and 99 not in ours


def test_relabelled_graph_holds_the_replacement_objects():
    """`GraphNLPView.with_variables` replaces variables by equal objects with other bounds: the
    relabelled graph's vertices and neighbours are those objects, not the originals."""
    vs, fs = discs(2)
    g = GraphNLP(fs)
    fixed = {v: replace(v, lower=(0.0,) * v.dim, upper=(0.0,) * v.dim) for v in vs}
    h = g.graph.relabelled(fixed)
    assert all(v == fixed[v] for v in vs)
    assert {id(n) for n in h if isinstance(n, VarInstance)} == {id(w) for w in fixed.values()}
    assert all(id(u) in {id(w) for w in fixed.values()} for r in g.factor_refs for u in h.neighbors(r))
