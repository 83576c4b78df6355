"""Alg. 1's search with one start per NLP (`SolveOptions.lazy_search`,
`FeasibilityCheck.confirm`): the conflict it returns gets the skipped random restarts before it is learnt, and when a
restart finds it feasible the search is repeated with every verdict from all its starts.
Checked on the planar examples against independent re-checks (plans, factors, conflicts by
multi-start) and against the same solve without lazy search."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.solve import feasibility_check, plan_evaluation
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.plan_evaluation import LAZY_RETRIES
from solve_checks import check_conflict_infeasible, check_solution
from solve_lies import lie_when

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"


def _large_above(monkeypatch, n: int) -> None:
    """LAZY_MAX_FACTORS = n where the loop reads it: the check's one start for subgraphs above
    it, and the evaluation's second opinion (`recheck`) for ranges above it."""
    for module in (feasibility_check, plan_evaluation):
        monkeypatch.setattr(module, "LAZY_MAX_FACTORS", n)


@pytest.mark.parametrize("name,n", [("p3_occupied", 4), ("p6_clutter", 4)])
def test_lazy_and_strict_search_both_give_real_conflicts_and_the_same_length(name, n):
    compiled = load_and_compile(str(PLANAR / f"{name}.pntc"))
    runs = {}
    for lazy in (True, False):
        res = _solve_checked(compiled, SolveOptions(switches="trn", time_limit=60, lazy_search=lazy), n)
        runs[lazy] = res.stats
    # no more NLPs are solved (a lazy verdict is the first start of the same solve, a certified
    # one no solve at all: `FeasibilityCheck.certify`, which only the lazy search uses)...
    assert runs[True].nlp_solves <= runs[False].nlp_solves
    # ...from no more starts (a confirmed conflict may add one polish run of its best restart)
    assert runs[True].ipopt_runs <= runs[False].ipopt_runs + runs[True].conflicts


def test_a_wrong_one_start_verdict_is_caught_by_the_restarts_and_the_search_is_repeated(monkeypatch):
    """Every feasible verdict of the lazy search is turned into a false 'infeasible' (as a
    stuck first start would give): the subgraph the search ends on is then feasible, its
    restarts say so, and the strict search finds the real conflict; the answer is the same."""
    lies = lie_when(monkeypatch, lambda checker, g: checker.lazy)
    res = _solve_checked(load_and_compile(str(PLANAR / "p5_handover.pntc")),
                         SolveOptions(switches="trn", time_limit=60, lazy_search=True), 3)
    assert lies and res.stats.lazy_retries >= 1


def _solve_checked(compiled, options: SolveOptions, n: int):
    """Solved with N = n actions, its plan, values and conflicts checked independently."""
    res = solve_compiled(compiled, options)
    assert res.solved and res.stats.N == n, res.message
    check_solution(compiled, res)
    for c in res.conflicts:
        if c.source == "nlp":
            check_conflict_infeasible(compiled, c)
    return res


@pytest.mark.parametrize("name,n", [("p4_pair", 6), ("p6_clutter", 4)])
def test_large_subgraphs_from_one_start_give_real_conflicts_and_the_same_length(monkeypatch, name, n):
    """`SolveOptions.lazy_large` (default): subgraphs above LAZY_MAX_FACTORS get one start in
    the search. With the threshold lowered so that the planar subgraphs count as large, the
    search does solve them from one start, and the answer and its conflicts are as real as
    with every start."""
    _large_above(monkeypatch, 2)
    compiled = load_and_compile(str(PLANAR / f"{name}.pntc"))
    from gnppdsl.nlp.feasibility import FeasibilitySolver

    starts = []
    real = FeasibilitySolver.solve

    def counting(self, g, *a, **k):
        if "#" in g.name:                          # a component or slice: Alg. 1's search
            starts.append((g.n_factors, self.options.restarts))
        return real(self, g, *a, **k)

    monkeypatch.setattr(FeasibilitySolver, "solve", counting)
    for large in (True, False):
        starts.clear()
        # (certify=False: the certified subgraphs would not be solved at all)
        _solve_checked(compiled, SolveOptions(switches="trn", time_limit=60, lazy_large=large,
                                              certify=False), n)
        one_start = [k for k, restarts in starts if k > 2 and restarts == 0]
        assert bool(one_start) == large


def test_a_wrong_one_start_verdict_on_a_large_subgraph_is_not_learnt(monkeypatch):
    """Every feasible verdict on a large subgraph in the search is turned into a false
    'infeasible' (a stuck first start): the second opinion of `recheck` or the restarts of
    `confirm` catch it; the answer is the same and every conflict is real."""
    _large_above(monkeypatch, 2)
    lies = lie_when(monkeypatch, lambda checker, g: checker.lazy_large and g.n_factors > 2)
    # p4: its searches meet feasible subgraphs of more than 2 factors (p5's no longer do: the
    # support of its failed plans' convergence points is their conflict)
    _solve_checked(load_and_compile(str(PLANAR / "p4_pair.pntc")), SolveOptions(switches="trn", time_limit=60), 6)
    assert lies


def test_a_repeated_search_keeps_one_start_for_large_subgraphs_once_then_gives_all(monkeypatch):
    """After `confirm` overturns the conflict of a search, the first repeat (LAZY_RETRIES = 1)
    still solves large subgraphs from one start (the overturned one now in the memo with its
    solution); a repeat after that gives every subgraph all its starts. Lies on every large
    one-start feasible verdict (the second opinions of `recheck` too, not the restarts of
    `confirm`) force the repeats; the answer and its conflicts are checked as above."""
    import gnppdsl.nlp.subgraph as subgraph

    _large_above(monkeypatch, 2)
    lie_when(monkeypatch, lambda checker, g: checker.lazy_large and g.n_factors > 2, once=False)
    forgets: dict = {}
    searches: list = []
    real_forget, real_search = FeasibilityCheck.forget_unconfirmed, subgraph.find_infeasible_subgraph

    def forget(self):
        forgets[id(self)] = forgets.get(id(self), 0) + 1
        return real_forget(self)

    def search(graph, *a, check=None, **k):
        searches.append((forgets.get(id(check), 0), check.lazy_large))
        return real_search(graph, *a, check=check, **k)

    monkeypatch.setattr(FeasibilityCheck, "forget_unconfirmed", forget)
    monkeypatch.setattr(subgraph, "find_infeasible_subgraph", search)
    res = _solve_checked(load_and_compile(str(PLANAR / "p4_pair.pntc")),
                         SolveOptions(switches="trn", time_limit=60), 6)
    assert res.stats.lazy_retries >= 2
    assert {large for n, large in searches if n <= LAZY_RETRIES} == {True}
    assert {large for n, large in searches if n > LAZY_RETRIES} == {False}
