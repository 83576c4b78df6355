"""The solution library of paper 002 (Sec. IV-B1, Eq. 4): solved paths keyed by their two ends.

Why: the symbolic search asks for the same travel many times and in both directions (A -> B,
later B -> A). A key is the *sorted* pair of ends, so one entry answers both directions; the
stored path runs from key[0] to key[1] and is reversed on a lookup the other way round.
Ends are rounded (default 1e-6) so that float noise does not defeat the cache.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass(frozen=True)
class Solution:
    """Eq. 4: key (x1, x2), path [q_10 .. q_1n] (n x nq), cost h. `nodes` are graph node ids."""

    key: tuple
    path: np.ndarray
    cost: float
    nodes: tuple[int, ...] = ()

    def reversed(self) -> "Solution":
        return Solution((self.key[1], self.key[0]), self.path[::-1].copy(), self.cost, self.nodes[::-1])


class SolutionLibrary:
    def __init__(self, digits: int = 6):
        self.digits = digits
        self._store: dict[tuple, Solution] = {}
        self.hits = 0
        self.misses = 0

    def end(self, kind: str, value) -> tuple:
        """A hashable end: ("x", rounded position) or ("q", rounded configuration)."""
        return (kind, tuple(float(v) for v in np.round(np.asarray(value, dtype=float).ravel(), self.digits)))

    def get(self, a: tuple, b: tuple) -> Solution | None:
        key = (a, b) if a <= b else (b, a)
        sol = self._store.get(key)
        if sol is None:
            self.misses += 1
            return None
        self.hits += 1
        return sol if key == (a, b) else sol.reversed()

    def put(self, a: tuple, b: tuple, sol: Solution) -> None:
        """Store the solution of a -> b (its path runs from a to b)."""
        if a <= b:
            self._store[(a, b)] = Solution((a, b), sol.path, sol.cost, sol.nodes)
        else:
            self._store[(b, a)] = Solution((b, a), sol.path[::-1].copy(), sol.cost, sol.nodes[::-1])

    def clear(self) -> None:
        self._store.clear()

    def __len__(self) -> int:
        return len(self._store)

    def __contains__(self, key) -> bool:
        a, b = key
        return ((a, b) if a <= b else (b, a)) in self._store
