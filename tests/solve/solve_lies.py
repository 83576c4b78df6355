"""A solver that lies: false one-start 'infeasible' verdicts injected into
`FeasibilityCheck.solve`, to test that the loop never learns them as conflicts and recovers the same answer."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from gnppdsl.solve.feasibility_check import FeasibilityCheck


def lie_when(monkeypatch, condition, once: bool = True, shift: float = 0.0) -> list:
    """`FeasibilityCheck.solve` turns each feasible verdict for which `condition(checker, g)`
    holds into a false one-start 'infeasible' (what a stuck first start gives), once per subgraph (or every
    time: `once=False`); its convergence point is the solution moved by `shift` in every
    coordinate (0: the solution itself). The returned list names the lies."""
    real = FeasibilityCheck.solve
    lies: list = []

    def lying(self, g):
        r = real(self, g)
        if r.feasible and condition(self, g) and not (once and g.signature() in lies):
            lies.append(g.signature())
            fake = replace(r, feasible=False, max_violation=1.0,
                           violations={ref: 1.0 for ref in g.factor_refs},
                           values={v: np.asarray(x) + shift for v, x in r.values.items()} if shift else r.values)
            self.results[g.signature()] = fake
            self.unconfirmed.add(g.signature())
            return fake
        return r

    monkeypatch.setattr(FeasibilityCheck, "solve", lying)
    return lies
