"""The expected N0 / N of the planar examples, re-derived with an independent reference model.

Other helpers' tests and the benchmarks read examples/planar/expected.yaml; these tests make
sure those numbers are right without trusting gnppdsl's own front end, compiler or solver
(see planar_reference.py): N0 by breadth-first search over the hand-coded logic, N by checking
every logical plan of length N0..N with a hand-written elastic NLP.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_reference import PLANAR, Logic, plan_feasible, read_problem, shortest_feasible  # noqa: E402

EXPECTED = yaml.safe_load((PLANAR / "expected.yaml").read_text())["problems"]


QUICK = sorted(n for n, e in EXPECTED.items() if e.get("reference") is not False)
# p6/p7 enumerate many logical plans (an elastic NLP each): minutes, so only with GNPP_SLOW=1.
SLOW = sorted(n for n, e in EXPECTED.items() if e.get("reference") is False)


@pytest.mark.parametrize("name", QUICK + [pytest.param(n, marks=pytest.mark.slow) for n in SLOW])
def test_planar_expected_lengths(name):
    e = EXPECTED[name]
    p = read_problem(PLANAR / e["file"])
    lg = Logic(p)
    n0 = lg.shortest_length()
    assert n0 == e["n0"], f"{name}: BFS gives N0 = {n0}, expected.yaml says {e['n0']}"
    hi = e["n"] if e["n"] is not None else p.max_horizon
    assert hi is not None, f"{name}: an unsolvable problem must set max_horizon"
    n, stats = shortest_feasible(p, n0, hi)
    assert n == e["n"], f"{name}: shortest feasible plan has length {n}, expected {e['n']} ({stats})"
    if e["n"] is not None and e["n"] > n0:
        assert stats["plans"] > 1, "N > N0 must come from geometrically infeasible shorter plans"


def test_reference_model_detects_overlap():
    """The reference NLP itself can fail: p3's two-action plan puts b1 onto b2."""
    p = read_problem(PLANAR / "p3_occupied.pntc")
    lg = Logic(p)
    (acts, states), = list(lg.plans(2))
    assert [a[0] for a in acts] == ["pick", "place"]
    assert not plan_feasible(p, states)
    # and with b2 logically elsewhere the same placement is fine
    par = dict(zip(lg.blocks, states[-1][0]))
    assert par["b1"] == "target" and par["b2"] == "s2"


def test_reference_model_respects_reach():
    """In p5 picking with g2 is infeasible (s1 lies outside g2's reach box)."""
    p = read_problem(PLANAR / "p5_handover.pntc")
    lg = Logic(p)
    for acts, states in lg.plans(2):
        assert not plan_feasible(p, states), acts
