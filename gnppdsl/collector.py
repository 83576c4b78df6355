"""Python's cyclic garbage collector during a solve (`collector.solving`).

Why: a solve allocates millions of small, long-lived Python objects (factor instances, graphs,
casadi wrappers, memo entries) and few cycles that die young, so the collector's default
policy (a young pass every 700 net allocations, a full pass whenever the heap has grown by a
quarter) walks the same live objects again and again: measured on lab3_paper (seed 0,
`gc.callbacks`), 1.1 s of ~12 s CPU in 660 passes, 0.84 s of them full passes. During a solve
the young threshold is 10,000 and everything alive when it starts (the modules, the loaded
problem, the compiled task and factory) is frozen (`gc.freeze`: kept out of every pass): 0.37 s
in 48 passes, no full pass. Both are undone when the solve ends (threshold restored, objects
unfrozen), so a process that goes on with other work has the default policy again.
"""
from __future__ import annotations

import gc
from contextlib import contextmanager
from typing import Iterator

YOUNG_THRESHOLD = 10_000
"""Net allocations between two young passes during a solve (Python's default: 700)."""


@contextmanager
def solving() -> Iterator[None]:
    """The collector's policy for the body of the `with` (module docstring). Not nested: an
    inner use (or objects frozen by someone else before) leaves the freezing to the outer."""
    old = gc.get_threshold()
    freeze = gc.get_freeze_count() == 0
    if freeze:
        gc.freeze()
    gc.set_threshold(max(old[0], YOUNG_THRESHOLD), *old[1:])
    try:
        yield
    finally:
        gc.set_threshold(*old)
        if freeze:
            gc.unfreeze()
