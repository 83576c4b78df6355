"""Algorithm 1: double binary search, relaxations, convergence heuristic; conflicts are real."""
from __future__ import annotations

import math
import time

import numpy as np
import pytest

from gnppdsl.compile.factors import VarInstance
from gnppdsl.ir.expr import Constraint, Index, Num, Slot
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.nlp.subgraph import (Relaxation, binary_search_time, convergence_heuristic,
                                  find_infeasible_subgraph)

from nlp_toys import C, chain, discs, factor, in_box, no_overlap, pose
from test_nlp_feasibility import confirm_infeasible

TOL = 1e-6


def templates(g):
    return sorted((g.factor(r).template, g.factor(r).step) for r in g.factor_refs)


@pytest.mark.parametrize("n", [6, 16, 40])
def test_chain_conflict_is_exactly_steps_3_4_with_log_solves(n):
    vs, fs = chain(n, conflict_at=3)
    g = GraphNLP(fs)
    t = time.perf_counter()
    res = find_infeasible_subgraph(g, [], "trn", solver=FeasibilitySolver())
    dt = time.perf_counter() - t
    print(f"chain({n}): {res.stats.solves} solves, {1e3 * dt:.0f} ms")
    assert not res.feasible and res.time_range == (3, 4)
    assert templates(res.subgraph) == [("toy.left", 3), ("toy.move", 3), ("toy.right", 4)]
    # 1 full check + two binary searches over at most n+1 steps (+1 heuristic check at most)
    assert res.stats.solves <= 1 + 2 * math.ceil(math.log2(n + 1)) + 1
    assert confirm_infeasible(res.subgraph)


def _conflict_oracle(at, calls):
    def oracle(sub):
        calls.append(sub.steps)
        names = {sub.factor(r).template for r in sub.factor_refs}
        return not {"toy.left", "toy.right"} <= names or \
            not any(sub.factor(r).template == "toy.move" and sub.factor(r).step == at
                    for r in sub.factor_refs)
    return oracle


def test_binary_search_counts_checks_with_an_oracle():
    """With an exact oracle (infeasible iff the slice holds both conflict factors) the search
    finds (f, l) with O(log n) checks and never needs the solver."""
    for n, at in [(64, 3), (64, 60), (33, 0), (100, 50)]:
        vs, fs = chain(n, conflict_at=at)
        g = GraphNLP(fs)
        calls = []
        feasible, rng = binary_search_time(g, _conflict_oracle(at, calls))
        assert not feasible and rng == (at, at + 1)
        assert len(calls) <= 1 + 2 * math.ceil(math.log2(n + 1))


@pytest.mark.parametrize("n,at", [(64, 3), (64, 60), (33, 0), (100, 50), (10, 1), (10, 8)])
def test_hinted_search_finds_the_same_range_within_the_same_bound(n, at):
    """Any hint, right or misleading, gives the same (f, l) as the plain search, within
    log2(n) + 1 checks per index; a hint naming the conflict's steps goes straight to them."""
    vs, fs = chain(n, conflict_at=at)
    g = GraphNLP(fs)
    plain = []
    expected = binary_search_time(g, _conflict_oracle(at, plain))
    assert expected == (False, (at, at + 1))
    bound = 1 + 2 * (math.ceil(math.log2(n + 1)) + 1)
    rng = np.random.default_rng(n + at)
    hints = [lambda s: (at, at + 1), lambda s: None, lambda s: s.steps]
    for _ in range(20):             # misleading hints inside the slice asked about
        hints.append(lambda s, u=rng.uniform(size=2): tuple(sorted(
            int(s.steps[0] + x * (s.steps[1] - s.steps[0])) for x in u)))
    for hint in hints:
        calls = []
        assert binary_search_time(g, _conflict_oracle(at, calls), hint) == expected
        assert len(calls) <= bound
    right = []
    binary_search_time(g, _conflict_oracle(at, right), lambda s: (at, at + 1))
    # the first probes are the hinted slices G[0..at+1] and G[at..at+1], no larger halves
    assert right[1] == (0, at + 1) or at + 1 >= n // 2
    assert max(b - a for a, b in right[1:]) <= max(b - a for a, b in plain[1:])


def test_violated_steps_reads_the_large_violations_of_a_convergence_point():
    """The hint is the step range of the factors carrying the violation at x*, not of every
    residual left by a solve that stopped early."""
    from gnppdsl.nlp.feasibility import FeasibilityResult
    from gnppdsl.nlp.subgraph import violated_steps

    vs, fs = chain(8, conflict_at=5)
    g = GraphNLP(fs)
    refs = {(g.factor(r).template, g.factor(r).step): r for r in g.factor_refs}
    viol = {r: 0.0 for r in g.factor_refs}
    viol[refs[("toy.move", 0)]] = 1e-4            # small residuals along the plan
    viol[refs[("toy.move", 7)]] = 2e-4
    viol[refs[("toy.move", 5)]] = 0.3             # the contradiction: steps 5..6
    viol[refs[("toy.right", 6)]] = 0.2
    r = FeasibilityResult(False, {}, viol, 0.3, 0.5, 0.0, 10, "stall")
    assert violated_steps(g, r, TOL) == (5, 6)
    assert violated_steps(g, True, TOL) is None
    assert violated_steps(g, FeasibilityResult(True, {}, {}, 0.0, 0.0, 0.0, 1, "ok"), TOL) is None
    # a real search on the chain, hinted by the solver's own convergence points, is exact
    res = find_infeasible_subgraph(g, [], "tn", solver=FeasibilitySolver())
    assert res.time_range == (5, 6) and confirm_infeasible(res.subgraph)


def test_binary_search_feasible_graph():
    vs, fs = chain(8, conflict_at=None)
    s = FeasibilitySolver()
    assert binary_search_time(GraphNLP(fs), lambda g: s.solve(g).feasible) == (True, None)


def two_objects_and_robot():
    """Objects b0 (stuck: must be in a box too small for it next to fixed obstacle b9) and b1
    (fine); a robot q touches both through collision factors. Under `drop robot, collision`
    only placement factors remain and the b0 conflict shows up alone."""
    b0, b1, b9 = pose("b0", 0), pose("b1", 0), pose("b9", 0)
    q = VarInstance("q", ("r",), 0, "SE2", 3, frozenset({"robot"}))
    fs = [
        in_box(b0, 0.1, 0), in_box(b1, 2.0, 0),
        factor("toy.fixed", [b9], [Constraint(Slot(0), "==", C("concat", Num(0.0), Num(0.0), Num(0.0)))], 0),
        no_overlap(b0, b9, 0.5, 0.5, 0, tags=("object",)),      # placement: object vs object
        no_overlap(q, b0, 0.1, 0.5, 0, tags=("collision",)),
        no_overlap(q, b1, 0.1, 0.5, 0, tags=("collision",)),
        in_box(q, 3.0, 0, tags=("robot",)),
    ]
    return fs


def test_relaxation_finds_the_small_conflict_first():
    fs = two_objects_and_robot()
    g = GraphNLP(fs)
    rel = [Relaxation.of("no_robot_col", ["robot", "collision"]), Relaxation.of("no_col", ["collision"])]
    res = find_infeasible_subgraph(g, rel, "trn")
    assert res.relaxation == "no_robot_col"
    assert templates(res.subgraph) == [("toy.fixed", 0), ("toy.in_box", 0), ("toy.no_overlap", 0)]
    assert confirm_infeasible(res.subgraph)
    # without relaxations the conflict comes from the full graph, still real
    res2 = find_infeasible_subgraph(g, rel, "tn")
    assert res2.relaxation == "full" and confirm_infeasible(res2.subgraph)
    print("r:", res.stats.solves, "solves; no r:", res2.stats.solves, "solves")


def test_convergence_heuristic_drops_unrelated_factors():
    # b0 must satisfy x <= 0 and x >= 1 (violated at x*); the other factors (b0-b1 and b1-b2
    # no_overlap, boxes) are satisfiable and satisfied at x*: the heuristic keeps only the two
    # contradicting factors and their variable.
    b0, b1, b2 = pose("b0", 0), pose("b1", 0), pose("b2", 0)
    fs = [factor("toy.left", [b0], [Constraint(Index(Slot(0), Num(0)), "<=", Num(0.0))], 0),
          factor("toy.right", [b0], [Constraint(Index(Slot(0), Num(0)), ">=", Num(1.0))], 0),
          no_overlap(b0, b1, 0.5, 0.5, 0), no_overlap(b1, b2, 0.5, 0.5, 0),
          in_box(b1, 3.0, 0), in_box(b2, 3.0, 0)]
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    r = s.solve(g)
    assert not r.feasible
    m = convergence_heuristic(g, r, lambda h: s.solve(h).feasible, TOL)
    assert templates(m) == [("toy.left", 0), ("toy.right", 0)] and m.variables == [b0]
    assert confirm_infeasible(m)
    assert templates(find_infeasible_subgraph(g, [], "tn").subgraph) == templates(m)
    whole = find_infeasible_subgraph(g, [], "t").subgraph
    assert whole.n_factors == g.n_factors and confirm_infeasible(whole)


def test_convergence_heuristic_tries_the_induced_subgraph_first():
    # b0 must satisfy x <= 0 and 2x >= 2: the elastic optimum (x* = 1) puts all the slack on
    # `toy.left` alone, which is satisfiable by itself. The heuristic goes straight to the
    # subgraph induced by b0 (both factors), infeasible, without solving the lone factor.
    b0, b1, b2 = pose("b0", 0), pose("b1", 0), pose("b2", 0)
    x = Index(Slot(0), Num(0))
    from gnppdsl.ir.expr import Call
    fs = [factor("toy.left", [b0], [Constraint(x, "<=", Num(0.0))], 0),
          factor("toy.right", [b0], [Constraint(Call("mul", (Num(2.0), x)), ">=", Num(2.0))], 0),
          no_overlap(b0, b1, 0.5, 0.5, 0), no_overlap(b1, b2, 0.5, 0.5, 0),
          in_box(b1, 3.0, 0), in_box(b2, 3.0, 0)]
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    r = s.solve(g)
    assert not r.feasible
    assert [g.factor(f).template for f in r.violated(TOL)] == ["toy.left"]
    checked = []

    def check(h):
        checked.append(templates(h))
        return s.solve(h)

    m = convergence_heuristic(g, r, check, TOL)
    assert templates(m) == [("toy.left", 0), ("toy.right", 0)] and m.variables == [b0]
    assert checked == [templates(m)]          # the lone violated factor is never solved
    assert confirm_infeasible(m)


def test_convergence_heuristic_keeps_graph_when_violated_part_is_feasible():
    # three discs in a tight box: at x* either only no_overlap or only in_box factors are
    # violated (the elastic optimum puts the slack on one kind), and each kind alone is
    # satisfiable, so M' is rejected and the whole graph stays the candidate
    vs, fs = discs(3)
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    r = s.solve(g)
    kinds = {g.factor(x).template for x in r.violated(TOL)}
    assert len(kinds) == 1
    assert s.solve(g.subgraph(factors=r.violated(TOL))).feasible
    m = convergence_heuristic(g, r, lambda h: s.solve(h).feasible, TOL)
    assert m.signature() == g.signature()


def test_feasible_graph_returns_checked_solution():
    vs, fs = chain(12, conflict_at=None)
    fs = fs + discs(2)[1]
    g = GraphNLP(fs)
    res = find_infeasible_subgraph(g, [Relaxation.of("no_col", ["collision"])], "trn")
    assert res.feasible and res.complete_values
    worst, f = max_violation(fs, res.values)
    assert worst <= TOL, f.label


def test_injected_check_with_bools_counts_and_heuristic_solves():
    vs, fs = chain(10, conflict_at=3)
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    seen = []

    def check(sub):
        seen.append(sub.signature())
        return s.solve(sub).feasible

    res = find_infeasible_subgraph(g, [], "trn", check=check, solver=s)
    assert len(seen) == len(set(seen)) == res.stats.checks     # memo: no subgraph twice
    assert res.stats.solves == 0 and res.stats.heuristic_solves == 1
    assert templates(res.subgraph) == [("toy.left", 3), ("toy.move", 3), ("toy.right", 4)]
    assert confirm_infeasible(res.subgraph)


def test_switches_validated():
    with pytest.raises(ValueError):
        find_infeasible_subgraph(GraphNLP(discs(1)[1]), [], "tx")


def test_unconstrained_variables_get_values_in_bounds():
    vs, fs = chain(3, conflict_at=None)
    free = VarInstance("q", ("r",), 1, "joints", 2, lower=(0.5, -1.0), upper=(1.0, 1.0))
    g = GraphNLP.from_factors(fs, [free])
    res = find_infeasible_subgraph(g, [], "trn")
    assert res.feasible and res.complete_values
    assert list(res.values[free]) == [0.5, 0.0]


def _flaky_whole(graph, solver):
    """A check that fails `graph` itself on its first solve (as a cold-started solver can on a
    large feasible graph) and solves every other subgraph for real."""
    state = {"failed": 0}

    def check(sub):
        if sub.signature() == graph.signature() and not state["failed"]:
            state["failed"] += 1
            r = solver.solve(sub)
            return type(r)(False, r.values, {ref: 1.0 for ref in sub.factor_refs}, 1.0, 1.0, 0.0, 0,
                           "forced failure", 1)
        return solver.solve(sub)
    return check, state


def test_recheck_rescues_a_failed_graph_whose_slices_are_feasible():
    vs, fs = chain(6, conflict_at=None)             # feasible
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    check, state = _flaky_whole(g, s)
    seen = []

    def recheck(sub):
        seen.append(sub.signature())
        return s.solve(sub)

    res = find_infeasible_subgraph(g, [], "tn", check=check, solver=s, recheck=recheck)
    assert state["failed"] == 1 and seen == [g.signature()]
    assert res.feasible and res.stats.rechecks_feasible == 1
    worst, _ = max_violation(fs, res.values)
    assert worst <= TOL
    # without a second opinion Alg. 1 returns the whole graph as the infeasible subgraph
    check, _ = _flaky_whole(g, s)
    res2 = find_infeasible_subgraph(g, [], "tn", check=check, solver=s)
    assert not res2.feasible and res2.subgraph.signature() == g.signature()


def test_recheck_keeps_a_real_whole_range_conflict():
    vs, fs = chain(1, conflict_at=0)                # steps 0..1 are exactly the conflict
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    calls = []

    def recheck(sub):
        calls.append(sub.signature())
        return s.solve(sub)

    res = find_infeasible_subgraph(g, [], "t", solver=s, recheck=recheck)
    assert not res.feasible and res.time_range == (0, 1) and calls == [g.signature()]
    assert confirm_infeasible(res.subgraph)


def test_recheck_of_an_inner_range_lets_the_search_go_on_past_a_false_verdict():
    """A solver that fails the whole graph and the slice G[0..4] of a feasible 8-step chain on
    their first solves (local minima): the time search ends at (0, 4) with G[0..3] and
    G[1..4] feasible, the second opinion solves G[0..4], the search resumes from its memo and
    ends at the whole range, whose second opinion solves it. Without `recheck`, G[0..4] is
    returned: a false conflict."""
    vs, fs = chain(8, conflict_at=None)             # feasible
    g = GraphNLP(fs)
    s = FeasibilitySolver()
    flaky = {g.signature(), g.time_slice(0, 4).signature()}

    def make_check():
        failed: set = set()

        def check(sub):
            r = s.solve(sub)
            key = sub.signature()
            if key in flaky and key not in failed:
                failed.add(key)
                return type(r)(False, r.values, {ref: 1.0 for ref in sub.factor_refs}, 1.0, 1.0,
                               0.0, 0, "forced failure", 1)
            return r
        return check

    seen = []

    def recheck(sub):
        seen.append(sub.steps)
        return s.solve(sub)

    res = find_infeasible_subgraph(g, [], "t", check=make_check(), solver=s, recheck=recheck)
    assert seen == [(0, 4), g.steps]
    assert res.feasible and res.stats.rechecks_feasible == 2
    assert max_violation(fs, res.values)[0] <= TOL
    plain = find_infeasible_subgraph(g, [], "t", check=make_check(), solver=s)
    assert not plain.feasible and plain.time_range == (0, 4)
    assert not confirm_infeasible(plain.subgraph)          # what the second opinion prevents
    # a range of at most `recheck_above` factors keeps its verdict without a second opinion
    seen.clear()
    n = g.time_slice(0, 4).n_factors
    small = find_infeasible_subgraph(g, [], "t", check=make_check(), solver=s, recheck=recheck,
                                     recheck_above=n)
    assert seen == [] and small.time_range == (0, 4)
    seen.clear()
    large = find_infeasible_subgraph(g, [], "t", check=make_check(), solver=s, recheck=recheck,
                                     recheck_above=n - 1)
    assert seen == [(0, 4), g.steps] and large.feasible


def test_the_heuristic_shrinks_a_long_component_before_the_time_search():
    """`shrink_before_time_search`: on a 40-step chain whose contradiction sits at steps
    30-31, the factors violated at the whole graph's convergence point induce a small
    infeasible candidate, and the time search runs on it: no half or quarter of the chain is
    ever solved (Alg. 1 as written solves G[0..20], G[0..30], ... first). The result is the
    same exact conflict, confirmed infeasible by a multi-start re-solve."""
    vs, fs = chain(40, conflict_at=30)
    g = GraphNLP(fs)
    res = find_infeasible_subgraph(g, [], "trn", solver=FeasibilitySolver())
    assert not res.feasible
    assert templates(res.subgraph) == [("toy.left", 30), ("toy.move", 30), ("toy.right", 31)]
    assert confirm_infeasible(res.subgraph)
    sizes = [n for _, n, _ in res.stats.log]
    assert sizes[0] == g.n_factors and max(sizes[1:], default=0) <= 10, res.stats.log
    # without the heuristic the time search starts with the first half of the chain
    plain = find_infeasible_subgraph(g, [], "tr", solver=FeasibilitySolver())
    assert templates(plain.subgraph) == templates(res.subgraph)
    assert max(n for _, n, _ in plain.stats.log[1:]) > 20


def test_a_shrunk_candidate_found_feasible_on_its_second_opinion_sends_the_search_back_to_the_component():
    """If the candidate of `shrink_before_time_search` is turned feasible by `recheck`, that
    says nothing about the (infeasible) component: the component itself is searched, and the
    search still returns an infeasible subgraph instead of "no conflict"."""
    vs, fs = chain(40, conflict_at=30)
    g = GraphNLP(fs)
    calls = []

    def recheck(sub):                  # a second opinion that (wrongly) clears the candidate
        calls.append(sub.name)
        return "{v}" in sub.name

    res = find_infeasible_subgraph(g, [], "trn", solver=FeasibilitySolver(), recheck=recheck)
    assert any("{v}" in name for name in calls)         # the candidate did get its second opinion
    assert not res.feasible and res.subgraph is not None
    names = {t for t, _ in templates(res.subgraph)}
    assert {("toy.left", 30), ("toy.right", 31)} <= set(templates(res.subgraph)) and "toy.move" in names
    assert confirm_infeasible(res.subgraph)
