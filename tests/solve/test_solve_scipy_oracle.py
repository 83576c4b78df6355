"""The scipy second opinion (scipy_oracle.py) can say both things: it finds the feasible graph
of a solved plan feasible (so "scipy finds no feasible point" in check_conflict_infeasible is a
real search, not a constant), and it finds no feasible point for p3's 2-step plan (b1 into the
target that b2 occupies), which the planar reference model also calls infeasible."""
from __future__ import annotations

from pathlib import Path

from scipy_oracle import scipy_feasible

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl import load_and_compile

P3 = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p3_occupied.pntc"


def _graph(c, plan: str):
    return c.factory.factors(plan_states(c.task, parse_plan(c.task, plan)))


def test_the_oracle_finds_a_feasible_plan_feasible_and_an_infeasible_one_not():
    c = load_and_compile(str(P3))
    ok = _graph(c, "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)")
    v = scipy_feasible(ok, c.geometry)
    assert v.feasible and v.best_violation <= 1e-6
    part = [f for f in ok if f.step <= 2]          # a subgraph of a feasible graph: a false conflict
    assert scipy_feasible(part, c.geometry).feasible
    bad = _graph(c, "pick(b1, g, s1); place(b1, g, target)")
    v = scipy_feasible(bad, c.geometry)
    assert not v.feasible and v.best_violation > 1e-3 and v.starts == 6
