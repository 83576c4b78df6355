"""The solve's time limit inside the feasibility checks: `TimeUp`, raised when the deadline has
passed (no verdict, never a conflict), and `deadline_solver`, a FeasibilitySolver that checks the
deadline before each of its ipopt runs.
"""
from __future__ import annotations

import time
from typing import Any


class TimeUp(Exception):
    """Raised inside a feasibility check when the deadline has passed."""


def deadline_solver(base: type) -> type:
    """A FeasibilitySolver subclass that stops between ipopt runs at the solve's deadline.

    Why: ipopt's `max_wall_time` applies to one run and is fixed when an NLP is assembled,
    while one feasibility solve may run ipopt several times (random restarts, the polish
    re-solve). Checking the deadline before every run bounds the overshoot to one run started
    before the deadline (whose own limit is the time that was left at assembly)."""
    cached = _DEADLINE_SOLVERS.get(base)
    if cached is not None:
        return cached

    class DeadlineSolver(base):      # type: ignore[misc, valid-type]
        deadline: float = float("inf")

        def _run(self, *args: Any, **kwargs: Any) -> Any:
            if time.perf_counter() >= self.deadline:
                raise TimeUp()
            return super()._run(*args, **kwargs)

        def solve(self, *args: Any, **kwargs: Any) -> Any:
            t0 = time.perf_counter()
            try:
                return super().solve(*args, **kwargs)
            except BaseException:
                # stopped by the deadline or a signal inside ipopt: the time spent still counts
                # in `solve_time` (Stats.nlp_time); without this, a run that ended at its time
                # limit reported only the NLPs that finished (lab5_paper: 15 s of 240 s)
                self.solve_time += time.perf_counter() - t0
                raise

    DeadlineSolver.__name__ = DeadlineSolver.__qualname__ = f"Deadline{base.__name__}"
    _DEADLINE_SOLVERS[base] = DeadlineSolver
    return DeadlineSolver


_DEADLINE_SOLVERS: dict[type, type] = {}
