"""A plan's graph-NLP (paper 000, Sec. IV): built by the factory at the plan's states, with its
initial guess; which of its variables are trajectories (Appendix C: solved after the mode
switches); how far values lie outside the variables' bounds (part of the NLP, not factors).
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Iterable, Sequence

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.nlp.graph import GraphNLP

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.compile.factory import GraphNLPFactory


TRAJ = "traj"


def plan_graph(factory: GraphNLPFactory, states: Sequence[Sequence[int]], name: str = "G") -> GraphNLP:
    """The graph-NLP of a state sequence: the factory's factors and variables, with its initial
    guess for each variable at these states (e.g. a held object's pose; see
    `GraphNLPFactory.initial_guess`) as the start of every NLP built from it, and the base
    placements of mobile robots (`gnppdsl.compile.placement`) for the solver's restarts."""
    from gnppdsl.nlp.graph import GraphNLP

    variables = factory.variables(states)
    guess = {}
    if hasattr(factory, "initial_guess"):
        for v in variables:
            g = factory.initial_guess(v, states)
            if g is not None:
                guess[v] = np.asarray(g, float)
    restart = {}
    if getattr(factory, "scene", None) is not None and hasattr(factory, "_relative_to"):
        from gnppdsl.compile.placement import restart_guesses

        restart = {v: np.asarray(q, float) for v, q in restart_guesses(factory, variables, states).items()}
    return GraphNLP.from_factors(factory.factors(states), variables, name=name, initial_guess=guess,
                                 restart_guess=restart)


def is_trajectory(v: VarInstance) -> bool:
    """A motion variable (tagged `traj` or with waypoints), solved after the mode switches."""
    return TRAJ in v.tags or bool(v.waypoints)


def bound_violation(variables: Iterable[VarInstance], values: dict) -> float:
    """Largest violation of the variables' lower/upper bounds (part of the NLP, not factors)."""
    worst = 0.0
    for v in variables:
        if v not in values:
            continue
        x = np.asarray(values[v], float).reshape(-1)
        for bound, sign in ((v.lower, -1.0), (v.upper, 1.0)):
            if bound is None:
                continue
            b = np.asarray(bound, float).reshape(-1)
            if b.size != x.size and x.size % max(b.size, 1) == 0:
                b = np.tile(b, x.size // b.size)     # per-point bounds of a trajectory
            if b.size != x.size:
                continue
            d = sign * (x - b)
            d = d[np.isfinite(d)]
            if d.size:
                worst = max(worst, float(d.max()))
    return worst
