"""Conflicts certified at the plan's convergence point and confirmed by the plan's restarts
(`FeasibilityCheck.certify`, `FeasibilityCheck.confirm_by_parent`, SolveOptions.certify).

Planar p5 (two grippers, a handover): both direct plans fail, each on a contradiction that is
the support of its graph's convergence point. Certified there, each failed plan costs one NLP
(its own, with its restarts), so GNPP_trn needs fewer NLPs than One-way (the issue's target:
NLP counts are deterministic for a seed). Checked independently: the solution against every
factor of its graph (numpy), each conflict infeasible from many random starts of its own NLP.
When a restart of the plan does not certify the conflict, the conflict gets its own restarts
and counts as an NLP: the same conflicts and answer, one NLP more per conflict."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.nlp import certificate
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions

from solve_checks import check_conflict_infeasible, check_solution

P5 = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p5_handover.pntc"


@pytest.fixture(scope="module")
def p5():
    return load_and_compile(str(P5))


def _solved(c, **kw):
    res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=60, **kw))
    assert res.solved and res.stats.N0 == 2 and res.stats.N == 3, res.message
    check_solution(c, res)
    for conflict in res.conflicts:
        if conflict.source == "nlp":
            check_conflict_infeasible(c, conflict)
    return res


def _conflicts(res):
    return [(c.text, c.factors, c.source) for c in res.conflicts]


def test_certified_conflicts_make_gnpp_cheaper_than_oneway_on_the_handover(p5):
    gnpp = _solved(p5, switches="trn")
    oneway = _solved(p5, algorithm="oneway")
    solved = _solved(p5, switches="trn", certify=False)
    assert gnpp.stats.certified_verdicts >= 2 and solved.stats.certified_verdicts == 0
    assert _conflicts(gnpp) == _conflicts(solved)           # the same conflicts...
    assert gnpp.stats.nlp_solves < solved.stats.nlp_solves  # ...for fewer NLPs
    assert gnpp.stats.nlp_solves < oneway.stats.nlp_solves
    assert gnpp.stats.nlp_solves == gnpp.stats.plans        # one NLP per plan


def test_a_restart_that_does_not_certify_the_conflict_gives_it_its_own_restarts(p5, monkeypatch):
    real_certify, real_confirm = certificate.certify_infeasible, FeasibilityCheck.confirm_by_parent
    inside = []

    def confirm_by_parent(self, g, parent):
        inside.append(g.name)
        try:
            return real_confirm(self, g, parent)
        finally:
            inside.pop()

    def certify(solver, g, point, within):                  # the restarts never certify
        return None if inside else real_certify(solver, g, point, within)

    monkeypatch.setattr(certificate, "certify_infeasible", certify)
    monkeypatch.setattr(FeasibilityCheck, "confirm_by_parent", confirm_by_parent)
    fallback = _solved(p5, switches="trn")
    monkeypatch.undo()
    gnpp = _solved(p5, switches="trn")
    assert _conflicts(fallback) == _conflicts(gnpp)
    assert fallback.stats.nlp_solves == gnpp.stats.nlp_solves + gnpp.stats.conflicts


def test_an_inferred_component_is_confirmed_by_the_restarts_of_its_graph(monkeypatch):
    """t1_swap: each failed plan's graph has one component violated at its convergence point,
    which becomes the conflict (Property 4.5). The restarts of the (cheap) graph are the
    component's restarts: one NLP per plan. With the graph taken as expensive, each conflict
    gets its own restarts, an NLP each: the same conflicts, 3 NLPs more."""
    c = load_and_compile(str(P5.parent / "t1_swap.pntc"))

    def run():
        res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=60))
        assert res.solved and res.stats.N == 6, res.message
        check_solution(c, res)
        for conflict in res.conflicts:
            check_conflict_infeasible(c, conflict)
        return res

    cheap = run()
    assert cheap.stats.inferred_verdicts >= cheap.stats.conflicts > 0
    assert cheap.stats.nlp_solves == cheap.stats.plans
    monkeypatch.setattr(FeasibilityCheck, "cheap", lambda self, g: False)
    own = run()
    assert _conflicts(own) == _conflicts(cheap)
    assert own.stats.nlp_solves == cheap.stats.nlp_solves + cheap.stats.conflicts
