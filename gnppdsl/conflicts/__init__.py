"""gnppdsl.conflicts: infeasible subgraphs as partial states, and the database of solved subgraphs.

    to_partial_states(subgraph) -> tuple[PartialState, ...]     (paper 000, Sec. VII)
    SubgraphDatabase(path=None, scope=..., fingerprint=...)      (Sec. VI-E; SQLite optional)
    semantic_graph(subgraph) / contains(target, pattern)         (labelled subgraph matching)

Names are loaded lazily so that importing a submodule stays cheap.
"""
from __future__ import annotations

from gnppdsl.lazy import lazy_getattr

__all__ = ["to_partial_states", "conflict_str", "SubgraphDatabase", "semantic_graph", "contains"]

_WHERE = {
    "to_partial_states": "gnppdsl.conflicts.mapping", "conflict_str": "gnppdsl.conflicts.mapping",
    "SubgraphDatabase": "gnppdsl.conflicts.database",
    "semantic_graph": "gnppdsl.conflicts.semantic", "contains": "gnppdsl.conflicts.semantic",
}


__getattr__ = lazy_getattr(__name__, _WHERE)
