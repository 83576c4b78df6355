"""The graph-NLP G(<s_0 ... s_n>) as a bipartite graph (paper 000, Sec. IV).

Vertices: variable vertices x_i^k keyed by their `VarInstance`, and factor vertices keyed by
`FactorRef(index)` (the factor's position in the factory's list, shared by every subgraph so
that vertices of a subgraph are vertices of the full graph). Edges connect a factor to the
variables it depends on, labelled with the slot position(s).

Every subgraph operation returns a new `GraphNLP` over the same factor list: Definition 4.2
(`subgraph`), relaxations that delete tagged variables and constraints (`apply_relaxation`),
connected components (Property 4.5) and time slices G(<s_f ... s_l>) (Sec. VI-A).

Semantic vertex attributes for subgraph matching (Sec. VI-E, used by `gnppdsl.conflicts`):
`label` is the variable key k without time (`pose(b1)`) or the template name, `kind` is the
variable kind (`pose`) or the template, `step` the absolute time index; `relative_labels()`
adds `rel_step` = step - first step of the graph.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Hashable, Iterable, Iterator, Mapping, Sequence

from gnppdsl.compile.factors import FactorInstance, VarInstance


class _NodeView:
    """`graph.nodes`: iterate, `in`, `len`, `nodes[n]` (the attribute dict), `nodes(data=True)`,
    `nodes(data=KEY)` (each node with that attribute, None where it has none; networkx's)."""

    __slots__ = ("_node",)

    def __init__(self, node: dict) -> None:
        self._node = node

    def __iter__(self) -> Iterator:
        return iter(self._node)

    def __len__(self) -> int:
        return len(self._node)

    def __contains__(self, n: Any) -> bool:
        return n in self._node

    def __getitem__(self, n: Any) -> dict:
        return self._node[n]

    def __call__(self, data: bool | str = False) -> Iterator:
        if isinstance(data, str):
            return ((n, d.get(data)) for n, d in self._node.items())
        return iter(self._node.items()) if data else iter(self._node)


class _EdgeView:
    """`graph.edges`: `edges[u, v]` (the attribute dict), `edges(data=True)` (each edge once)."""

    __slots__ = ("_adj",)

    def __init__(self, adj: dict) -> None:
        self._adj = adj

    def __getitem__(self, uv: tuple) -> dict:
        u, v = uv
        return self._adj[u][v]

    def __call__(self, data: bool = False) -> Iterator:
        seen: set = set()
        for u, nbrs in self._adj.items():
            for v, d in nbrs.items():
                if v not in seen:
                    yield (u, v, d) if data else (u, v)
            seen.add(u)

    def __iter__(self) -> Iterator:
        return self()

    def __len__(self) -> int:
        return sum(len(nbrs) + (u in nbrs) for u, nbrs in self._adj.items()) // 2


class Graph:
    """An undirected graph with node and edge attribute dicts: the part of `networkx.Graph`'s
    interface graph-NLPs use (`add_node`, `add_nodes_from`, `add_edge`, `add_edges_from`,
    `has_edge`, `remove_nodes_from`, `nodes`, `edges`, `adj`, `neighbors`, `degree`,
    `number_of_nodes`, `copy`, iteration and `in`), with networkx's semantics: attribute dicts
    are copied on insertion (their values shared), an edge's dict is shared by both ends.
    `to_networkx()` gives the networkx graph for what needs its algorithms. Why not
    `networkx.Graph` itself: importing networkx cost ~0.1 s CPU of every cold `gnpp solve`
    (issue 20), and a graph-NLP uses none of its algorithms; only conflict matching
    (`gnppdsl.conflicts`) does, and it imports networkx when it runs.
    `tests/nlp/test_nlp_graph.py` holds this class to networkx's behaviour (hypothesis)."""

    __slots__ = ("_node", "_adj")

    def __init__(self) -> None:
        self._node: dict[Hashable, dict] = {}
        self._adj: dict[Hashable, dict[Hashable, dict]] = {}

    # -- construction -------------------------------------------------------------------------
    def add_node(self, n: Hashable, **attr: Any) -> None:
        if n in self._node:
            self._node[n].update(attr)
        else:
            self._node[n] = attr
            self._adj[n] = {}

    def add_nodes_from(self, nodes: Iterable) -> None:
        """Nodes, or (node, attribute dict) pairs (the dict copied)."""
        for item in nodes:
            if type(item) is tuple and len(item) == 2 and isinstance(item[1], Mapping):
                n, d = item
            else:
                n, d = item, {}
            if n in self._node:
                self._node[n].update(d)
            else:
                self._node[n] = dict(d)
                self._adj[n] = {}

    def add_edge(self, u: Hashable, v: Hashable, **attr: Any) -> None:
        for n in (u, v):
            if n not in self._node:
                self._node[n] = {}
                self._adj[n] = {}
        d = self._adj[u].get(v)
        if d is None:
            d = {}
        d.update(attr)
        self._adj[u][v] = d
        self._adj[v][u] = d

    def add_edges_from(self, edges: Iterable[tuple]) -> None:
        """(u, v) pairs or (u, v, attribute dict) triples (the dict copied into the edge's)."""
        for e in edges:
            if len(e) == 3:
                self.add_edge(e[0], e[1], **e[2])
            else:
                self.add_edge(e[0], e[1])

    def remove_nodes_from(self, nodes: Iterable) -> None:
        for n in nodes:
            nbrs = self._adj.pop(n, None)
            if nbrs is None:
                continue
            del self._node[n]
            for m in nbrs:
                if m != n:
                    del self._adj[m][n]

    # -- queries ------------------------------------------------------------------------------
    @property
    def nodes(self) -> _NodeView:
        return _NodeView(self._node)

    @property
    def edges(self) -> _EdgeView:
        return _EdgeView(self._adj)

    @property
    def adj(self) -> dict[Hashable, dict[Hashable, dict]]:
        return self._adj

    def __getitem__(self, n: Hashable) -> dict[Hashable, dict]:
        return self._adj[n]

    def has_edge(self, u: Hashable, v: Hashable) -> bool:
        return u in self._adj and v in self._adj[u]

    def neighbors(self, n: Hashable) -> Iterator:
        return iter(self._adj[n])

    def degree(self, n: Hashable) -> int:
        nbrs = self._adj[n]
        return len(nbrs) + (n in nbrs)           # a self-loop counts twice, as in networkx

    def number_of_nodes(self) -> int:
        return len(self._node)

    def __len__(self) -> int:
        return len(self._node)

    def __iter__(self) -> Iterator:
        return iter(self._node)

    def __contains__(self, n: Any) -> bool:
        try:
            return n in self._node
        except TypeError:                        # unhashable: not a node (networkx says False)
            return False

    def copy(self) -> "Graph":
        """Node and edge attribute dicts copied (values shared), as `networkx.Graph.copy`."""
        return self.relabelled({})

    def relabelled(self, mapping: Mapping) -> "Graph":
        """A copy whose node n is mapping.get(n, n) (`networkx.relabel_nodes(g, mapping,
        copy=True)`): the new graph holds the mapped objects themselves as its nodes; nodes
        mapped to one node merge (the last one's attributes, the edges' attributes updated in
        edge order, as networkx does)."""
        g = Graph()
        get = mapping.get
        for n, d in self._node.items():
            m = get(n, n)
            g._node[m] = dict(d)
            g._adj[m] = {}
        done: set = set()
        for u, nbrs in self._adj.items():
            mu = get(u, u)
            for v, d in nbrs.items():
                if v in done:
                    continue
                mv = get(v, v)
                dd = g._adj[mu].get(mv)
                if dd is None:               # (a mapping that merges nodes merges their edges)
                    dd = g._adj[mu][mv] = g._adj[mv][mu] = {}
                dd.update(d)
            done.add(u)
        return g

    def to_networkx(self) -> Any:
        """The same graph as a `networkx.Graph` (imports networkx)."""
        import networkx as nx

        g = nx.Graph()
        g.add_nodes_from(self._node.items())
        g.add_edges_from(self.edges(data=True))
        return g


def connected_components(graph: Graph) -> Iterator[set]:
    """The node sets of `graph`'s connected components (`networkx.connected_components`)."""
    adj = graph.adj
    seen: set = set()
    for start in adj:
        if start in seen:
            continue
        comp = {start}
        todo = [start]
        while todo:
            for m in adj[todo.pop()]:
                if m not in comp:
                    comp.add(m)
                    todo.append(m)
        seen |= comp
        yield comp


@dataclass(frozen=True, order=True)
class FactorRef:
    """A factor vertex: the index of the factor in the graph's factor list."""

    index: int

    def __str__(self) -> str:
        return f"h{self.index}"


class GraphNLP:
    """A (sub)graph-NLP: a `Graph` + the factor list its factor vertices point into."""

    def __init__(self, factors: Sequence[FactorInstance], graph: Graph | None = None,
                 name: str = "G", initial_guess: dict | None = None, restart_guess: dict | None = None):
        self.factors: tuple[FactorInstance, ...] = tuple(factors)
        self.name = name
        # Optional start values per VarInstance (e.g. scene poses, R-LGP waypoints), shared by
        # every subgraph; `solve_feasibility` uses them when no warm start is given.
        self.initial_guess: dict = initial_guess if initial_guess is not None else {}
        # Values that replace the initial guess in the solver's restarts from it (e.g. a mobile
        # base placed next to the object it picks: `gnppdsl.compile.placement`), shared too
        self.restart_guess: dict = restart_guess if restart_guess is not None else {}
        if graph is None:
            graph = Graph()
            for i, f in enumerate(self.factors):
                ref = FactorRef(i)
                graph.add_node(ref, bipartite=1, vertex="factor", label=f.template,
                               kind=f.template, template=f.template, step=f.step, span=f.span,
                               tags=f.tags, generator=f.generator, factor=f)
                for j, v in enumerate(f.variables):
                    if v not in graph:
                        graph.add_node(v, bipartite=0, vertex="variable", label=v.key,
                                       kind=v.kind, step=v.step, tags=v.tags)
                    if graph.has_edge(ref, v):
                        graph.edges[ref, v]["slots"] += (j,)
                    else:
                        graph.add_edge(ref, v, slots=(j,))
        self.graph = graph

    # -- construction ----------------------------------------------------------------------
    @classmethod
    def from_factors(cls, factors: Sequence[FactorInstance],
                     variables: Iterable[VarInstance] = (), name: str = "G",
                     initial_guess: dict | None = None, restart_guess: dict | None = None) -> "GraphNLP":
        """The graph-NLP of a factory output; extra `variables` are added even if unconstrained."""
        g = cls(factors, name=name, initial_guess=initial_guess, restart_guess=restart_guess)
        for v in variables:
            if v not in g.graph:
                g.graph.add_node(v, bipartite=0, vertex="variable", label=v.key, kind=v.kind,
                                 step=v.step, tags=v.tags)
        return g

    def _derive(self, nodes: Iterable, suffix: str) -> "GraphNLP":
        """The subgraph induced by `nodes`, as its own graph (what networkx's
        `subgraph(nodes).copy()` gives: attribute dicts copied, values shared). Built directly,
        each edge from its factor end (the graph is bipartite): the filtered views of
        `subgraph().copy()` cost 0.4 ms per derivation on planar plans, a quarter of the
        loop's time outside ipopt on p5."""
        keep = {n for n in nodes if n in self.graph}
        g = Graph()
        node_data, adj = self.graph.nodes, self.graph.adj
        g.add_nodes_from((n, node_data[n]) for n in keep)
        g.add_edges_from((f, v, d) for f in keep if isinstance(f, FactorRef)
                         for v, d in adj[f].items() if v in keep)
        return GraphNLP(self.factors, g, f"{self.name}{suffix}", self.initial_guess, self.restart_guess)

    # -- views ----------------------------------------------------------------------------
    @property
    def variables(self) -> list[VarInstance]:
        return sorted((n for n in self.graph if isinstance(n, VarInstance)),
                      key=lambda v: (v.step, v.key))

    @property
    def factor_refs(self) -> list[FactorRef]:
        return sorted(n for n in self.graph if isinstance(n, FactorRef))

    @property
    def factor_instances(self) -> list[FactorInstance]:
        return [self.factors[r.index] for r in self.factor_refs]

    def factor(self, ref: FactorRef) -> FactorInstance:
        return self.factors[ref.index]

    def neighbours(self, node) -> list:
        return list(self.graph.neighbors(node))

    def __len__(self) -> int:
        return self.graph.number_of_nodes()

    def __contains__(self, node) -> bool:
        return node in self.graph

    @property
    def n_factors(self) -> int:
        return sum(1 for n in self.graph if isinstance(n, FactorRef))

    @property
    def steps(self) -> tuple[int, int] | None:
        """(first, last) time index covered by the factors (a transition factor covers 2)."""
        refs = self.factor_refs
        if not refs:
            return None
        fs = [self.factor(r) for r in refs]
        lo = min(min([f.step, *f.steps]) for f in fs)
        hi = max(max([f.step + f.span - 1, *f.steps]) for f in fs)
        return lo, hi

    def signature(self) -> frozenset:
        """Hashable identity of the vertex set (for memoising solves of the same subgraph)."""
        return frozenset(self.graph.nodes)

    def relative_labels(self) -> Graph:
        """A copy with `rel_step` = step - first step, for matching at any time offset."""
        g = self.graph.copy()
        first = min((d["step"] for _, d in g.nodes(data=True)), default=0)
        for _, d in g.nodes(data=True):
            d["rel_step"] = d["step"] - first
        return g

    def __repr__(self) -> str:
        return (f"GraphNLP({self.name}: {self.n_factors} factors, "
                f"{len(self.variables)} variables, steps {self.steps})")

    def describe(self) -> str:
        """Multi-line listing of the factors (for conflict reports and debugging)."""
        return "\n".join(self.factor(r).label for r in self.factor_refs)

    # -- subgraphs ------------------------------------------------------------------------
    def subgraph(self, variables: Iterable[VarInstance] | None = None,
                 factors: Iterable[FactorRef | int] | None = None, suffix: str = "'") -> "GraphNLP":
        """Subgraph-NLP M ⊆ G (Definition 4.2).

        - only `variables`: X_M = variables, H_M = every factor whose neighbours are all in X_M;
        - only `factors`: H_M = factors, X_M = the variables they depend on (spanned subgraph);
        - both: X_M = variables, H_M = the given factors whose neighbours are all in X_M.
        """
        fset = None if factors is None else {
            f if isinstance(f, FactorRef) else FactorRef(f) for f in factors}
        if fset is not None:
            fset = {f for f in fset if f in self.graph}
        if variables is None:
            if fset is None:
                return self._derive(self.graph.nodes, suffix)
            xs = {v for f in fset for v in self.graph.neighbors(f)}
        else:
            xs = {v for v in variables if v in self.graph}
        cand = self.factor_refs if fset is None else fset
        hs = [f for f in cand if all(v in xs for v in self.graph.neighbors(f))]
        return self._derive([*xs, *hs], suffix)

    def apply_relaxation(self, dropped_tags: Iterable[str], name: str = "") -> "GraphNLP":
        """Delete every variable and factor carrying a dropped tag, and every factor touching a
        deleted variable (a factor is only kept if all its variables are: Definition 4.2)."""
        dropped = frozenset(dropped_tags)
        xs = [n for n in self.graph if isinstance(n, VarInstance) and not (n.tags & dropped)]
        hs = [r for r in self.factor_refs if not (self.factor(r).tags & dropped)]
        return self.subgraph(variables=xs, factors=hs, suffix=f"[{name or ','.join(sorted(dropped))}]")

    def connected_components(self, with_factors_only: bool = True) -> list["GraphNLP"]:
        """Connected components (Property 4.5), ordered by first step then size. Components
        without factors have no constraint and are always feasible; skipped by default."""
        comps = []
        for nodes in connected_components(self.graph):
            if with_factors_only and not any(isinstance(n, FactorRef) for n in nodes):
                continue
            comps.append(self._derive(nodes, f"#{len(comps)}"))
        comps.sort(key=lambda g: ((g.steps or (0, 0))[0], len(g)))
        return comps

    def time_slice(self, first: int, last: int) -> "GraphNLP":
        """G(<s_first ... s_last>): factors generated by those states (a transition factor at
        step i needs i and i+1 in range) and only variables of those steps."""
        xs = [n for n in self.graph if isinstance(n, VarInstance) and first <= n.step <= last]
        hs = [r for r in self.factor_refs
              if first <= self.factor(r).step and self.factor(r).step + self.factor(r).span - 1 <= last]
        m = self.subgraph(variables=xs, factors=hs, suffix=f"[{first}..{last}]")
        m.graph.remove_nodes_from([n for n in list(m.graph) if m.graph.degree(n) == 0])
        return m

    def iter_factors(self) -> Iterator[tuple[FactorRef, FactorInstance]]:
        for r in self.factor_refs:
            yield r, self.factor(r)
