"""Motions and keyframes in the solve loop (`FeasibilityCheck.motions_between_keyframes`,
`keyframes_with_motions`, `consistent_keyframes`, `overturned`), on the 1-D toy with
trajectories: a motion that cannot be found between fixed keyframes is solved together with the
keyframes instead of sending the plan to the joint solve of every motion; keyframes gathered
from different solves are made consistent before motions are fixed between them; a graph whose
infeasible verdict was its keyframes' is solved again once they prove feasible. Every answer is
re-checked independently (plan validity, every factor with the numpy evaluator)."""
from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver
from gnppdsl.solve import motions
from gnppdsl.solve.check_memory import StampedValues
from gnppdsl.solve.feasibility_check import equality_pair, FeasibilityCheck
from gnppdsl.solve.loop import Loop, solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.timing import result_states
from solve_checks import check_solution
from solve_lies import lie_when
from solve_toy import occupied_problem

OPTIONS = SolveOptions(switches="trn", time_limit=60, max_horizon=6, order="staged")


def _far_keyframes():
    """The toy (N = 4: b2 to `side`, then b1 to `target`) with b2's initial guess at the far
    end of `side` (2.25): the keyframes start there, b2's held pose stays there, and its first
    motion (from its spot at 1.0, 4 waypoints of at most 0.3) is out of reach between them."""
    compiled = occupied_problem(waypoints=4)
    compiled.factory.initial_guess = lambda v, states=None: [2.25] if v.kind == "pose" and v.args == ("b2",) else None
    return compiled


def _spy_nlps(monkeypatch) -> list:
    """(name, has trajectories, trajectory steps, feasible) of every NLP solved."""
    seen = []
    real = FeasibilitySolver.solve

    def spy(self, g, *a, **k):
        r = real(self, g, *a, **k)
        seen.append((g.name, any(v.waypoints for v in g.variables),
                     {v.step for v in g.variables if v.waypoints}, r.feasible))
        return r

    monkeypatch.setattr(FeasibilitySolver, "solve", spy)
    return seen


def _solved(compiled):
    res = solve_compiled(compiled, OPTIONS)
    assert res.solved and res.stats.N == 4, res.message
    check_solution(compiled, res)
    return res


def test_a_motion_out_of_reach_between_fixed_keyframes_is_solved_with_the_keyframes(monkeypatch):
    seen = _spy_nlps(monkeypatch)
    _solved(_far_keyframes())
    joined = [s for s in seen if "{keyframes+motions" in s[0]]
    assert joined and all(ok for *_, ok in joined)
    # the motion that failed between fixed keyframes is one of those solved with them
    failed = {steps.pop() for name, _, steps, ok in seen if "{motion" in name and not ok}
    assert failed and failed <= set().union(*(steps for _, _, steps, _ in joined))
    # no joint solve of several motions outside the keyframes NLPs
    assert not [s for s in seen if s[1] and len(s[2]) > 1 and "{keyframes+motions" not in s[0]]


def test_without_keyframes_with_motions_the_plan_goes_to_the_joint_solve(monkeypatch):
    """The counterfactual of the test above (it can fail): with no motion allowed to join the
    keyframes, the same plan is solved by the joint NLP of all its motions."""
    monkeypatch.setattr(motions, "MAX_JOINED_MOTIONS", 0)
    seen = _spy_nlps(monkeypatch)
    _solved(_far_keyframes())
    assert not [s for s in seen if "{keyframes+motions" in s[0]]
    assert [s for s in seen if s[1] and len(s[2]) > 1]


@pytest.mark.parametrize("overturn", [True, False])
def test_a_plan_whose_keyframes_prove_feasible_is_solved_again_not_searched(monkeypatch, overturn):
    """The plan's keyframes fail their first solve (a lie), Alg. 1 finds the mode-switch level
    feasible; the full graph, which took the keyframes' verdict, is then solved again through
    its motions, and no slice of it with trajectories goes through Alg. 1's search. Without
    `overturned` (the counterfactual) it is searched slice by slice."""
    if not overturn:
        monkeypatch.setattr(FeasibilityCheck, "overturned", lambda self, key: False)
    # the first feasible verdict on the 4-step plan's mode switches becomes a one-start
    # 'infeasible' whose convergence point is away from the solution (a stuck start)
    lies = lie_when(monkeypatch, lambda checker, g: g.name == "G[modes]" and checker.graph.steps == (0, 4),
                    shift=0.37)
    seen = _spy_nlps(monkeypatch)
    _solved(occupied_problem(waypoints=4))
    assert lies
    searched = [s for s in seen if s[1] and "#" in s[0]]        # a component or slice with motions
    assert bool(searched) == (not overturn), searched


def _checker_on_the_toy_plan():
    compiled = occupied_problem(waypoints=4)
    run = Loop(compiled, OPTIONS, None)
    names = ["pick(b2, g, s2)", "place(b2, g, side)", "pick(b1, g, s1)", "place(b1, g, target)"]
    graph = run.build_graph([tuple(x) for x in result_states(compiled.task, names)])
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    return run, checker, graph.apply_relaxation({"traj"}, "modes")


def _violation(run, g, values) -> float:
    return max_violation(g.factor_instances, {v: values[v] for v in g.variables}, run.compiled.geometry)[0]


def test_keyframes_from_two_solves_are_made_consistent_near_them():
    run, checker, modes = _checker_on_the_toy_plan()
    r0 = checker.solve(modes)
    assert r0.feasible
    # b2 rests in `side` from step 2 on; steps 3-4 come from another solve 0.2 further
    mixed = dict(checker.values)
    b2 = {v.step: v for v in modes.variables if v.args == ("b2",)}
    for i in (3, 4):
        mixed[b2[i]] = np.asarray(mixed[b2[i]]) + 0.2
    checker.values = StampedValues(mixed)
    assert _violation(run, modes, checker.values) > 0.1         # a `stay` row broken at the seam
    calls = run.nlp_calls
    checker.consistent_keyframes(modes, r0)
    assert run.nlp_calls == calls + 1
    assert _violation(run, modes, checker.values) <= 1e-6
    # a local repair (one start from the mixture): the other keyframes move by little
    # (ipopt's interior point steps off bounds it started on), b2's in `side` end between the
    # two solves' values
    for v in modes.variables:
        x = float(np.asarray(checker.values[v]).reshape(-1)[0])
        if v in b2.values() and v.step >= 2:
            assert float(r0.values[v][0]) - 1e-6 <= x <= float(r0.values[v][0]) + 0.2 + 1e-6, v
        else:
            assert abs(x - float(np.asarray(mixed[v]).reshape(-1)[0])) <= 0.02, v
    # consistent keyframes are left as they are, without an NLP
    before = dict(checker.values)
    checker.consistent_keyframes(modes, r0)
    assert run.nlp_calls == calls + 1
    assert all(np.array_equal(before[v], checker.values[v]) for v in modes.variables)


def test_a_failed_repair_takes_the_keyframes_solution(monkeypatch):
    run, checker, modes = _checker_on_the_toy_plan()
    r0 = checker.solve(modes)
    checker.values = StampedValues({v: np.asarray(x) + 0.3 for v, x in checker.values.items()})
    real = FeasibilitySolver.solve
    monkeypatch.setattr(FeasibilitySolver, "solve",
                        lambda self, g, *a, **k: replace(real(self, g, *a, **k), feasible=False))
    checker.consistent_keyframes(modes, r0)
    assert all(np.array_equal(checker.values[v], r0.values[v]) for v in modes.variables)
    assert _violation(run, modes, checker.values) <= 1e-6


def test_warm_starts_follow_the_newest_value_along_equality_chains():
    """`FeasibilityCheck.warm_start`: where `self.values` mixes two solves across an equality
    factor (`toy.same`: b2 stays in `side` from step 2 to 4), the whole chain starts from the value
    set last; variables on no chain keep their own values."""
    run, checker, modes = _checker_on_the_toy_plan()
    b = {(v.args[0], v.step): v for v in modes.variables}
    pairs = [equality_pair(modes.factor(ref)) for ref in modes.factor_refs]
    chain = {frozenset(p) for p in pairs if p is not None and p[0].args == ("b2",)}
    assert chain == {frozenset({b["b2", 2], b["b2", 3]}), frozenset({b["b2", 3], b["b2", 4]})}
    # an inequality factor is no equality pair
    assert all(equality_pair(modes.factor(ref)) is None for ref in modes.factor_refs
               if modes.factor(ref).template in ("toy.inside", "toy.apart"))
    checker.values = StampedValues({v: np.array([0.5 + 0.01 * v.step]) for v in modes.variables})
    checker.values.update({b["b2", 3]: np.array([2.1])})            # a later solve of step 3 alone
    warm = checker.warm_start(modes)
    assert all(float(warm[b["b2", i]][0]) == 2.1 for i in (2, 3, 4))
    assert float(warm[b["b1", 3]][0]) == 0.53 and float(warm[b["b2", 1]][0]) == 0.51
    # values themselves are not changed, only the start
    assert float(checker.values[b["b2", 2]][0]) == 0.52
