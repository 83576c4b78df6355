"""Semantic graphs: the time-free, solver-free identity of a (sub)graph-NLP (paper 000, Sec. VI-E).

Why: graph-NLPs of different plans share subgraphs at different time indices. To reuse a
feasibility verdict we need a representation of a subgraph that says exactly which NLP it is,
and nothing about where in time it came from, so that subgraph monomorphism decides containment:

- a *variable vertex* is labelled by its variable index k (`VarInstance.key`, e.g. `pose(b1)`,
  i.e. kind + objects) and by everything else that enters the NLP for it: space, dimension,
  waypoints and bounds. The time index is NOT part of the label (paper: "the variable-index k
  (without considering the time index)"); factor time-invariance (Property 4.2) makes that sound.
- a *factor vertex* is labelled by its template name plus a hash of its resolved body (the
  constraint functions after scene constants are folded and `world(o)` is expanded). The paper
  keys on the template name only; that is unsound in our language because one template yields
  different functions for different objects or kinematic chains (e.g. `keep_world(o)` with `o` on
  `s1` or on `s2` folds a different constant), so the body is part of the identity.
- an *edge* (factor, variable) is labelled by the slot(s) the variable fills in the factor body.

A monomorphism pattern -> target that preserves these labels maps every factor of the pattern to
a factor of the target computing the same function of correspondingly labelled variables, so the
pattern's NLP is literally a sub-NLP of the target's: feasible target => feasible pattern, and
infeasible pattern => infeasible target (Property 4.4).

Vertex ids keep the relative time (`x|pose(b1)|2`) for readability and stable serialisation.
"""
from __future__ import annotations

import hashlib
import re
import weakref
from collections import Counter
from dataclasses import dataclass, field
from functools import lru_cache
from typing import TYPE_CHECKING, Any, Callable, Iterable

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.conflicts.mapping import factors_of
from gnppdsl.ir.expr import Obj

if TYPE_CHECKING:
    import networkx as nx


def _nx() -> Any:
    """networkx, imported when a semantic graph is first built or matched: a solve that learns
    no conflict and keeps no database never needs it (~0.1 s CPU to import; `gnppdsl.nlp.graph`)."""
    import networkx

    return networkx

_BY_ID: dict[tuple[str, int], tuple[Any, Any]] = {}


def by_identity(kind: str, body: Any, compute: Callable[[Any], Any]) -> Any:
    """`compute(body)` remembered by the identity of `body` (the entry holds the body, so its
    id is not reused while the entry lives). Why not only a dict keyed by the body: a resolved
    body is a tree of frozen dataclasses whose hash is recomputed, node by node in Python, at
    every lookup (lab5_paper profile: 25 M hash calls, ~1/10 of the solve, from the semantic
    graphs of the database's lookups, which label the same factor instances again and again)."""
    key = (kind, id(body))
    hit = _BY_ID.get(key)
    if hit is not None and hit[0] is body:
        return hit[1]
    value = compute(body)
    if len(_BY_ID) > 400_000:
        _BY_ID.clear()
    _BY_ID[key] = (body, value)
    return value


def body_hash(body: tuple) -> str:
    """A stable hash of a resolved factor body (spans excluded: they are repr=False)."""
    return by_identity("labels", body, _body_labels)[0]


#: an `Obj` node in a body's repr (`Obj(name='b1')`: its span is repr=False)
_OBJ_REPR = re.compile(r"\bObj\(name='([^'\\]*)'\)")


def _body_labels(body: Any) -> tuple[str, frozenset[str]]:
    """(`body_hash`, `body_objects`) of a body from one repr of it: the objects are the names
    of its `Obj` nodes, which the repr spells out (the repr the hash needs anyway, instead of a
    second walk of the tree in Python: that walk and the two caches keyed by the body were 0.4
    s of work2's 1.25 s of semantic graphs, profiled, seed 0)."""
    hit = _BODY_LABELS.get(body)
    if hit is None:
        text = repr(body)
        hit = (hashlib.sha256(text.encode()).hexdigest()[:20], frozenset(_OBJ_REPR.findall(text)))
        if len(_BODY_LABELS) > 200_000:
            _BODY_LABELS.clear()
        _BODY_LABELS[body] = hit
    return hit


_BODY_LABELS: dict[Any, tuple[str, frozenset[str]]] = {}


def variable_label(v: VarInstance, named: bool = True) -> str:
    """A variable vertex's label: its key (`q(g)`), or only its kind when not `named` (the
    anonymous graph of lifting), then space, dimension, waypoints and bounds."""
    return f"x|{v.key if named else v.kind}|{v.space}|{v.dim}|{v.waypoints}|{v.lower}|{v.upper}"


ObjectKey = Callable[[str], str]


def body_objects(body: Any) -> frozenset[str]:
    """Names of the objects a resolved body refers to (`Obj` nodes: sdist bodies, fk robots)."""
    return by_identity("labels", body, _body_labels)[1]


def factor_label(f: FactorInstance, object_key: ObjectKey | None = None) -> str:
    """Template, arity, body hash and -- when `object_key` is given -- the identity of every
    object the body names (its shape or robot model), which the body itself does not contain:
    `sdist(b1, ...)` is a different function when b1 has another shape."""
    label = f"h|{f.template}|{len(f.variables)}|{body_hash(f.body)}"
    if object_key is not None:
        objs = sorted(body_objects(f.body))
        if objs:
            label += "|" + ",".join(f"{o}:{object_key(o)}" for o in objs)
    return label


def anonymous_text(body: Any, object_key: ObjectKey) -> str:
    """A canonical text of a resolved body in which every object with geometry is named by its
    identity (`object_key`: shape, robot model) instead of its name; numbers (folded scene
    poses, sizes, margins) stay exact. Two bodies with equal texts compute the same function of
    their slots, whichever objects they were instantiated for: the label of `anonymous_graph`."""
    if isinstance(body, Obj):
        key = object_key(body.name)
        return f"Obj({body.name})" if key == "-" else f"Obj#{key}"
    if isinstance(body, (tuple, list)):
        return "(" + ",".join(anonymous_text(e, object_key) for e in body) + ")"
    if hasattr(body, "__dataclass_fields__"):
        fields = ",".join(f"{n}={anonymous_text(getattr(body, n), object_key)}"
                          for n in body.__dataclass_fields__ if n != "span")
        return f"{type(body).__name__}({fields})"
    return repr(body)


def anonymous_graph(factors: Iterable[FactorInstance], object_key: ObjectKey) -> nx.Graph:
    """The semantic graph of a set of factors with object names left out of every label: a
    variable vertex is labelled by its kind, space, dimension and bounds; a factor vertex by its
    template, arity and `anonymous_text` body; edges by slots. Isomorphic anonymous graphs are
    the same NLP up to renaming objects of equal geometry (used to lift conflicts,
    `gnppdsl.conflicts.lifting`; the database keeps the named labels of `semantic_graph`)."""
    g = _nx().Graph()
    try:
        texts = _ANON.setdefault(object_key, {})
    except TypeError:                       # not weakly referenceable (a builtin's method): no cache
        texts = {}
    for i, f in enumerate(factors):
        fid = ("h", i)
        text = texts.get(f.body)
        if text is None:
            text = texts[f.body] = hashlib.sha256(anonymous_text(f.body, object_key).encode()).hexdigest()[:20]
        g.add_node(fid, label=f"h|{f.template}|{len(f.variables)}|{text}")
        slots: dict[tuple, list[int]] = {}
        for j, v in enumerate(f.variables):
            vid = ("x", v.key, v.step)
            if vid not in g:
                g.add_node(vid, label=variable_label(v, named=False))
            slots.setdefault(vid, []).append(j)
        for x, js in slots.items():
            g.add_edge(fid, x, slots=",".join(map(str, js)))
    return g


#: anonymous body texts per object key (one per compiled problem): weak, so a problem's texts go
#: with it and a later problem never meets them (an `id()` key could be reused after collection)
_ANON: "weakref.WeakKeyDictionary[ObjectKey, dict[Any, str]]" = weakref.WeakKeyDictionary()


@dataclass
class SemanticGraph:
    """A labelled bipartite graph plus the precomputed data that makes matching cheap."""

    graph: nx.Graph
    labels: Counter = field(default_factory=Counter)
    n_edges: int = 0
    # factor vertex id -> the FactorInstance it came from (not persisted; empty after loading)
    factor_of: dict[str, FactorInstance] = field(default_factory=dict, repr=False)

    @staticmethod
    def from_graph(graph: nx.Graph) -> "SemanticGraph":
        labels = Counter(d["label"] for _, d in graph.nodes(data=True))
        return SemanticGraph(graph, labels, graph.number_of_edges())

    @property
    def n_factors(self) -> int:
        return sum(c for lab, c in self.labels.items() if lab.startswith("h|"))

    def wl_hash(self) -> str:
        """Weisfeiler-Lehman hash: equal for isomorphic graphs (used to find duplicates fast)."""
        return _nx().weisfeiler_lehman_graph_hash(self.graph, node_attr="label", edge_attr="slots")

    def to_json(self) -> dict:
        return {
            "nodes": [[n, d["label"]] for n, d in sorted(self.graph.nodes(data=True))],
            "edges": sorted([sorted([u, v]) + [d["slots"]] for u, v, d in self.graph.edges(data=True)]),
        }

    @staticmethod
    def from_json(data: dict) -> "SemanticGraph":
        g = _nx().Graph()
        for n, label in data["nodes"]:
            g.add_node(n, label=label)
        for u, v, slots in data["edges"]:
            g.add_edge(u, v, slots=slots)
        return SemanticGraph.from_graph(g)


def subgraph_variables(subgraph: Any) -> list[VarInstance]:
    """The variables a subgraph names itself (its `variables` attribute, method or dict; none
    for a single factor): vertices of its semantic graph even where no factor touches them."""
    sub_vars = getattr(subgraph, "variables", None)
    if sub_vars is None or isinstance(subgraph, FactorInstance):
        return []
    if callable(sub_vars):
        sub_vars = sub_vars()
    if isinstance(sub_vars, dict):
        sub_vars = sub_vars.values()
    return [v for v in sub_vars if isinstance(v, VarInstance)]


def semantic_graph(subgraph: Any, variables: Iterable[VarInstance] = (),
                   object_key: ObjectKey | None = None) -> SemanticGraph:
    """Build the semantic graph of a subgraph-NLP.

    `subgraph` is anything `factors_of` accepts; `variables` adds variable vertices that no
    factor touches (their bounds still belong to the NLP). If `subgraph` has a `variables`
    attribute, those are added too. `object_key` names the geometry of objects (see
    `factor_label`); without it the caller must scope the database to one scene.
    """
    factors = factors_of(subgraph)
    extra = list(variables) + subgraph_variables(subgraph)
    all_vars = [v for f in factors for v in f.variables] + extra
    t0 = min((v.step for v in all_vars), default=0)

    def vid(v: VarInstance) -> str:
        return f"x|{v.key}|{v.step - t0}"

    g = _nx().Graph()
    origin: dict[str, FactorInstance] = {}
    for v in all_vars:
        if vid(v) not in g:
            g.add_node(vid(v), label=variable_label(v))
    order = sorted(factors, key=lambda f: (f.step, f.template, f.label, tuple(v.name for v in f.variables)))
    for i, f in enumerate(order):
        fid = f"h|{f.template}|{f.step - t0}|{i}"
        g.add_node(fid, label=factor_label(f, object_key))
        origin[fid] = f
        slots: dict[str, list[int]] = {}
        for j, v in enumerate(f.variables):
            slots.setdefault(vid(v), []).append(j)
        for x, js in slots.items():
            g.add_edge(fid, x, slots=",".join(map(str, js)))
    sg = SemanticGraph.from_graph(g)
    sg.factor_of = origin
    return sg


def _node_match(a: dict, b: dict) -> bool:
    return a["label"] == b["label"]


def _edge_match(a: dict, b: dict) -> bool:
    return a["slots"] == b["slots"]


#: expansions (VF2 candidate pairs tested) one `monomorphism` may spend before it gives up with
#: "unknown" (None). A lookup measured on lab5_paper spent > 90 s CPU in one VF2 call; at roughly
#: 10^5 pairs per CPU second this bounds a call to about a second. None: unlimited.
MATCH_BUDGET: int | None = 100_000


@dataclass
class MatchStats:
    """Process-wide counters of `monomorphism` (read by the solve's statistics)."""

    calls: int = 0
    prefiltered: int = 0       # rejected by a necessary condition before VF2
    vf2_runs: int = 0
    expansions: int = 0        # candidate pairs VF2 tested, all calls
    budget_exceeded: int = 0   # calls that gave up ("unknown", answered None)


MATCH_STATS = MatchStats()


class BudgetExceeded(Exception):
    """A single match spent its expansion budget."""


def _profile(sg: "SemanticGraph") -> dict:
    """Per-graph data for the necessary conditions, computed once per graph (cached on it):
    node -> signature class (label + the multiset of (slots, neighbour label) of its edges), the
    classes' signatures, per-label degree sequences and the multiset of edge types."""
    prof = sg.__dict__.get("_profile")
    if prof is not None:
        return prof
    g = sg.graph
    lab = {n: d["label"] for n, d in g.nodes(data=True)}
    cls_of_sig: dict[tuple, int] = {}
    node_cls: dict[Any, int] = {}
    degrees: dict[str, list[int]] = {}
    for n in g:
        nb = Counter((d["slots"], lab[m]) for m, d in g.adj[n].items())
        sig = (lab[n], tuple(sorted(nb.items())))
        node_cls[n] = cls_of_sig.setdefault(sig, len(cls_of_sig))
        degrees.setdefault(lab[n], []).append(len(g.adj[n]))
    for ds in degrees.values():
        ds.sort(reverse=True)
    sigs = [None] * len(cls_of_sig)
    for (label, items), i in cls_of_sig.items():
        sigs[i] = (label, Counter(dict(items)))
    edges = Counter(tuple(sorted((lab[u], lab[v]))) + (d["slots"],) for u, v, d in g.edges(data=True))
    prof = {"node_cls": node_cls, "sigs": sigs, "degrees": degrees, "edges": edges}
    sg.__dict__["_profile"] = prof
    return prof


def _compatible_classes(pp: dict, tp: dict) -> dict[int, frozenset[int]] | None:
    """pattern class -> target classes a pattern vertex of it may map to (same label, the
    target's neighbour multiset contains the pattern's: an injective, label- and slot-preserving
    map of the neighbours needs it); None when some pattern class has no candidate."""
    by_label: dict[str, list[int]] = {}
    for j, (label, _) in enumerate(tp["sigs"]):
        by_label.setdefault(label, []).append(j)
    out: dict[int, frozenset[int]] = {}
    for i, (label, nb) in enumerate(pp["sigs"]):
        ok = frozenset(j for j in by_label.get(label, ()) if nb <= tp["sigs"][j][1])
        if not ok:
            return None
        out[i] = ok
    return out


def prefilter(pattern: "SemanticGraph", target: "SemanticGraph") -> dict[int, frozenset[int]] | None:
    """Necessary conditions for a label-preserving monomorphism pattern -> target; None rejects
    the pair (no monomorphism exists), else the compatible classes (`_compatible_classes`).
    Each condition follows from an injective map that preserves node labels and edges with
    their slots: label multiset containment, per label the sorted degree sequence of the
    pattern dominated by the target's, edge-type multiset containment, and every pattern vertex
    having a target vertex whose labelled neighbourhood contains its own."""
    if pattern.graph.number_of_nodes() > target.graph.number_of_nodes() or pattern.n_edges > target.n_edges:
        return None
    if not pattern.labels <= target.labels:
        return None
    pp, tp = _profile(pattern), _profile(target)
    for label, ds in pp["degrees"].items():
        dt = tp["degrees"][label]
        if any(a > b for a, b in zip(ds, dt)):
            return None
    if not pp["edges"] <= tp["edges"]:
        return None
    return _compatible_classes(pp, tp)


@lru_cache(maxsize=1)
def _matcher_class() -> type:
    """`_Matcher`, defined on first use (it subclasses networkx's GraphMatcher: see `_nx`)."""

    class _Matcher(_nx().algorithms.isomorphism.GraphMatcher):
        """VF2 (G1 = target, G2 = pattern) whose node test also requires compatible signature
        classes -- a necessary condition, so it prunes without changing the search order or the
        first monomorphism found -- and which counts tested pairs against a budget."""

        def __init__(self, target: "SemanticGraph", pattern: "SemanticGraph",
                     compat: dict[int, frozenset[int]], budget: int | None) -> None:
            super().__init__(target.graph, pattern.graph, node_match=_node_match, edge_match=_edge_match)
            self._tcls = _profile(target)["node_cls"]
            self._pcls = _profile(pattern)["node_cls"]
            self._compat = compat
            self._budget = budget
            self.expansions = 0

        def syntactic_feasibility(self, G1_node, G2_node):  # noqa: N803 (networkx's names)
            self.expansions += 1
            if self._budget is not None and self.expansions > self._budget:
                raise BudgetExceeded
            if self._tcls[G1_node] not in self._compat[self._pcls[G2_node]]:
                return False
            return super().syntactic_feasibility(G1_node, G2_node)

    return _Matcher


def monomorphism(pattern: SemanticGraph, target: SemanticGraph,
                 budget: int | None | str = "default") -> dict | None:
    """A label-preserving subgraph monomorphism pattern -> target (as {target: pattern}), or None.

    Necessary conditions first (`prefilter`), then networkx's VF2 GraphMatcher restricted to
    compatible vertex classes. VF2 is exponential in the worst case (weakly discriminating labels
    on graphs of hundreds of vertices: one lab5_paper lookup ran > 90 s), so a call tests at most
    `budget` candidate pairs (default `MATCH_BUDGET`) and then answers None, "not shown" -- sound
    for every caller: a cache miss costs an NLP solve, a missed domination stores a redundant
    record. Within the budget the answer is plain VF2's.
    """
    if budget == "default":
        budget = MATCH_BUDGET
    stats = MATCH_STATS
    stats.calls += 1
    compat = prefilter(pattern, target)
    if compat is None:
        stats.prefiltered += 1
        return None
    stats.vf2_runs += 1
    gm = _matcher_class()(target, pattern, compat, budget)
    try:
        for mapping in gm.subgraph_monomorphisms_iter():
            return mapping
        return None
    except BudgetExceeded:
        stats.budget_exceeded += 1
        return None
    finally:
        stats.expansions += gm.expansions


def contains(target: SemanticGraph, pattern: SemanticGraph) -> bool:
    """pattern ⊆ target as NLPs (up to renaming variables and shifting time)."""
    return monomorphism(pattern, target) is not None


def isomorphic(a: SemanticGraph, b: SemanticGraph) -> bool:
    if a.labels != b.labels or a.n_edges != b.n_edges:
        return False
    return _nx().is_isomorphic(a.graph, b.graph, node_match=_node_match, edge_match=_edge_match)
