"""What the feasibility check of one plan's graph-NLP remembers between its NLPs: the verdicts
by subgraph, the latest value of every variable (stamped, for consistent warm starts), the
convergence points of infeasible solves, the one-start verdicts still unconfirmed and the graphs
they were decided at. The check's parts (`feasibility_check`, `inferred_verdicts`,
`confirmation`, `motions`) all read and write this state, so it is their common base.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Any

from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.run import Run

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.feasibility import FeasibilityResult, FeasibilitySolver


class StampedValues(dict):
    """`FeasibilityCheck.values`: the latest value of each variable, and when it was set (`stamp`, one
    tick per `update`: the values of one solve share it), for `FeasibilityCheck.warm_start`."""

    def __init__(self, *args: Any, **kw: Any) -> None:
        super().__init__()
        self.stamp: dict = {}
        self.clock = 0
        self.update(*args, **kw)

    def __setitem__(self, key: Any, value: Any) -> None:
        self.clock += 1
        super().__setitem__(key, value)
        self.stamp[key] = self.clock

    def update(self, *args: Any, **kw: Any) -> None:       # type: ignore[override]
        self.clock += 1
        for key, value in dict(*args, **kw).items():
            super().__setitem__(key, value)
            self.stamp[key] = self.clock


class CheckMemory:
    """The state of one plan's feasibility check (`feasibility_check.FeasibilityCheck`)."""

    max_points = 3                       # infeasible convergence points kept for `known_solution`
    closest_point: dict | None = None    # set by `known_solution`: the start `solve` prefers
    local_first = False                  # set by `evaluate` around the first solves up to and
                                         # including the full graph's: see `local_solve`

    def __init__(self, run: Run, solver: FeasibilitySolver, graph: GraphNLP, use_db: bool):
        self.run, self.solver, self.graph, self.use_db = run, solver, graph, use_db
        self.values: StampedValues = StampedValues()
        self.results: dict[frozenset, FeasibilityResult] = {}
        self.points: list[dict] = []      # convergence points of infeasible solves, newest first
        self.lazy = False                 # Alg. 1's search: one start per small NLP (see `confirm`)
        self.lazy_large = False           # ... and per NLP above LAZY_MAX_FACTORS factors
        self.unconfirmed: set = set()     # signatures of infeasible verdicts from one start
        self.derived: dict = {}           # graph -> its mode-switch graph, whose infeasible
                                          # verdict it took as its own (see `overturned`)
        self.parents: list[tuple] = []    # (factor refs, graph, result) of the newest cheap
                                          # infeasible solves: what `certify` decides subgraphs at
        self.parent_of: dict = {}         # signature -> the graph at whose convergence point it was
                                          # decided (certified, or its only violated component)
        self.cold_checked: set = set()    # signatures `cold_refutes` solved from their initial guess
        self.misled = False               # a one-start verdict was overturned (`forget_unconfirmed`)
        self.components: set = set()      # ... of those, the components (`infer_components`)
