"""`FeasibilitySolver.iteration_cost`: rows of templates that query signed distances weigh
DISTANCE_ROW_COST, every other row 1. Checked against an independent count: the rows the numpy
evaluator returns for each factor, and a walk of the factor's constraint expressions for an
`sdist`/`sdist2` call."""
from __future__ import annotations

import dataclasses

import numpy as np

from gnppdsl.ir.expr import Call
from gnppdsl.nlp.evaluate import constraint_rows
from gnppdsl.nlp.feasibility import DISTANCE_ROW_COST, FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP

from nlp_toys import ARM_GEOM as GEOM, arm_reach_graph as graph


def _queries_distance(node) -> bool:
    """Does an IR expression (or a tuple of them) call sdist or sdist2 anywhere?"""
    if isinstance(node, Call) and node.fn in ("sdist", "sdist2"):
        return True
    if isinstance(node, tuple):
        return any(_queries_distance(n) for n in node)
    if dataclasses.is_dataclass(node) and not isinstance(node, type):
        return any(_queries_distance(getattr(node, f.name)) for f in dataclasses.fields(node))
    return False


def _reference_cost(g: GraphNLP) -> float:
    values = {v: np.zeros(v.dim) for v in g.variables}
    total = 0.0
    for f in g.factor_instances:
        rows = len(constraint_rows(f, values, GEOM))
        total += rows * (DISTANCE_ROW_COST if _queries_distance(f.body) else 1)
    return total


def test_distance_rows_weigh_more_than_plain_rows():
    g = graph()
    solver = FeasibilitySolver(GEOM, SolverOptions(restarts=0))
    reach = g.subgraph(factors=[r for r in g.factor_refs if g.factor(r).template == "toy.reach"])
    clear = g.subgraph(factors=[r for r in g.factor_refs if g.factor(r).template == "toy.clear"])
    assert solver.iteration_cost(reach) == _reference_cost(reach) == 3       # FK and a norm: plain rows
    assert solver.iteration_cost(clear) == _reference_cost(clear) == DISTANCE_ROW_COST
    assert solver.iteration_cost(g) == _reference_cost(g) == 3 + DISTANCE_ROW_COST
    assert DISTANCE_ROW_COST > 1
