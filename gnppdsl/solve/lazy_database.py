"""The solve's subgraph database (switch g) with records whose semantic graphs are built only
when a query could match them.

A record's semantic graph (`conflicts.semantic.semantic_graph`) labels every factor by a hash
of its resolved body and the objects it names: on a fresh process that walks every body once
(lab2, seed 0: 0.50 s of a 2.1 s profiled solve for 4 checked graphs, networkx's import
included, and no lookup ever matched). A label-preserving monomorphism of `pattern` into
`target` maps distinct vertices to distinct vertices of equal labels, so the coarse labels
below (a variable's label; a factor's template and arity only) of `pattern` are a
sub-multiset of `target`'s. They cost no body walk. A record is kept pending (its factors and
variables, its coarse labels) until a query passes that necessary condition against some
record; then every pending record is built and inserted in the order it came (the same
records, the same pruning as `SubgraphDatabase.add` at once) and the query is decided by
`SubgraphDatabase` itself. A query that passes against no record is answered "unknown"
without its semantic graph: the answer the full match would give.
"""
from __future__ import annotations

from collections import Counter
from typing import Any

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.conflicts.database import Entry, Names, SubgraphDatabase
from gnppdsl.conflicts.mapping import factors_of
from gnppdsl.conflicts.semantic import SemanticGraph, semantic_graph, subgraph_variables, variable_label


def coarse_labels(factors: tuple[FactorInstance, ...], variables: tuple[VarInstance, ...]) -> Counter:
    """The vertex labels of `semantic_graph(factors, variables)` with a factor's label cut to
    its template and arity (what `coarse_of_graph` gives for the built graph)."""
    out: Counter = Counter()
    seen: set = set()
    for f in factors:
        out[f"h|{f.template}|{len(f.variables)}"] += 1
        for v in f.variables:
            if (v.key, v.step) not in seen:
                seen.add((v.key, v.step))
                out[variable_label(v)] += 1
    for v in variables:
        if (v.key, v.step) not in seen:
            seen.add((v.key, v.step))
            out[variable_label(v)] += 1
    return out


def coarse_of_graph(sg: SemanticGraph) -> Counter:
    """`coarse_labels` of a built semantic graph (a loaded record's, a matched query's)."""
    out: Counter = Counter()
    for label, n in sg.labels.items():
        out["|".join(label.split("|")[:3]) if label.startswith("h|") else label] += n
    return out


def _parts(subgraph: Any) -> tuple[tuple[FactorInstance, ...], tuple[VarInstance, ...]]:
    """The factors and the extra variables `semantic_graph(subgraph)` would read, copied now
    (a graph-NLP may change after it was checked)."""
    return tuple(factors_of(subgraph)), tuple(subgraph_variables(subgraph))


class LazyDatabase(SubgraphDatabase):
    """`SubgraphDatabase` whose `add` keeps the record pending until a query could match it
    (module docstring). Answers of `lookup` and `infeasible_inside` are those of the plain
    database given the same calls."""

    def __post_init__(self) -> None:
        super().__post_init__()
        # (factors, variables, feasible, conflict, coarse labels), in the order added
        self.pending: list[tuple[tuple, tuple, bool, Names | None, Counter]] = []
        self._coarse: dict[int, tuple[SemanticGraph, Counter]] = {}
        self.built_queries = 0       # queries whose semantic graph was built (a record could match)
        self.skipped_queries = 0     # ... and those answered without it
        # the last built query (object, its semantic graph): recorded by `add` after its solve
        # without a second build, as the graph it was looked up with
        self._last: tuple[Any, SemanticGraph] | None = None

    # ---- the coarse condition ----------------------------------------------------------------
    def _coarse_of(self, entry: Entry) -> Counter:
        hit = self._coarse.get(id(entry.graph))
        if hit is None or hit[0] is not entry.graph:
            hit = self._coarse[id(entry.graph)] = (entry.graph, coarse_of_graph(entry.graph))
        return hit[1]

    def _could_match(self, query: Counter, infeasible_only: bool) -> bool:
        """Might a record decide `query`: an infeasible one inside it, or (unless
        `infeasible_only`) a feasible one holding it?"""
        for factors, variables, feasible, _, coarse in self.pending:
            if (coarse <= query) if not feasible else (not infeasible_only and query <= coarse):
                return True
        if any(self._coarse_of(e) <= query for e in self.infeasible):
            return True
        return not infeasible_only and any(query <= self._coarse_of(e) for e in self.feasible)

    def flush(self) -> None:
        """Build and insert every pending record, in the order they were added."""
        pending, self.pending = self.pending, []
        for factors, variables, feasible, conflict, _ in pending:
            super().add(semantic_graph(factors, variables, object_key=self.object_key), feasible, conflict)

    def knows_infeasible(self) -> bool:
        """Is there an infeasible record, built or pending?"""
        return bool(self.infeasible) or any(not p[2] for p in self.pending)

    # ---- SubgraphDatabase's queries and updates ----------------------------------------------
    def _query(self, subgraph: Any) -> tuple[Any, Counter]:
        if isinstance(subgraph, SemanticGraph):
            return subgraph, coarse_of_graph(subgraph)
        return subgraph, coarse_labels(*_parts(subgraph))

    def _built(self, subgraph: Any) -> SemanticGraph:
        if isinstance(subgraph, SemanticGraph):
            return subgraph
        sg = self.graph_of(subgraph)
        self._last = (subgraph, sg)
        return sg

    def lookup(self, subgraph: Any) -> bool | None:
        subgraph, coarse = self._query(subgraph)
        if not self._could_match(coarse, infeasible_only=False):
            self.stats.queries += 1
            self.skipped_queries += 1
            return None
        self.flush()
        self.built_queries += 1
        return super().lookup(self._built(subgraph))

    def infeasible_inside(self, subgraph: Any) -> tuple[FactorInstance, ...] | None:
        subgraph, coarse = self._query(subgraph)
        if not self._could_match(coarse, infeasible_only=True):
            self.skipped_queries += 1
            return None
        self.flush()
        self.built_queries += 1
        return super().infeasible_inside(self._built(subgraph))

    def add(self, subgraph: Any, feasible: bool, conflict: Names | None = None) -> bool:
        """Record a verdict: pending (True), or at once for a built semantic graph (the plain
        database's answer: False when an equal or stronger record exists)."""
        if self._last is not None and self._last[0] is subgraph:
            subgraph = self._last[1]     # looked up and built: recorded as it was looked up
        self._last = None
        if isinstance(subgraph, SemanticGraph):
            self.flush()
            return super().add(subgraph, feasible, conflict)
        factors, variables = _parts(subgraph)
        if not factors and not variables:
            return False                 # (the plain database stores no empty graph either)
        self.pending.append((factors, variables, feasible, conflict, coarse_labels(factors, variables)))
        return True

    def close(self) -> None:
        if self.path is not None:        # a file: its records are written, pending ones too
            self.flush()
        super().close()
