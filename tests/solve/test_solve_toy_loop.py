"""The loop on a hand-made 1-D problem (real clingo planner, real casadi/ipopt, no front end)."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from solve_checks import check_conflict_infeasible, check_solution
from solve_toy import occupied_problem, unsolvable_problem
from gnppdsl.errors import UserError
from gnppdsl.solve.brute import brute_force
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.result import NO_PLAN, SOLVED, TIME_LIMIT

ALGORITHMS = [("gnpp", "t"), ("gnpp", "tr"), ("gnpp", "trn"), ("gnpp", "trng"), ("gnpp", ""), ("oneway", "")]


@pytest.mark.parametrize("algorithm,switches", ALGORITHMS)
def test_every_algorithm_solves_the_occupied_target(algorithm, switches):
    compiled = occupied_problem()
    res = solve_compiled(compiled, SolveOptions(algorithm=algorithm, switches=switches, time_limit=60, max_horizon=6))
    assert res.status == SOLVED, res.message
    assert res.stats.N0 == 2 and res.stats.N == 4
    check_solution(compiled, res)
    # b2 had to leave s2 before b1 entered the target
    assert res.plan.index("place(b1, g, target)") > res.plan.index("pick(b2, g, s2)")
    for c in res.conflicts:
        if c.source != "plan":
            check_conflict_infeasible(compiled, c)


def test_relaxations_give_the_small_conflict():
    res = solve_compiled(occupied_problem(), SolveOptions(switches="trn", time_limit=60, max_horizon=6))
    assert [c.text for c in res.conflicts] == ["{parent(b1) = target, parent(b2) = s2}"]
    assert res.conflicts[0].relaxation == "no_time_traj"


def test_without_time_search_the_conflict_spans_the_plan():
    res = solve_compiled(occupied_problem(), SolveOptions(switches="", time_limit=60, max_horizon=6))
    assert res.solved
    assert len(res.conflicts[0].partial_states) == 3        # the whole first plan, s_0 .. s_2


def test_no_geometric_solution_is_reported_honestly():
    compiled = unsolvable_problem()
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=5))
    assert res.status == NO_PLAN and not res.solved
    assert "no plan up to horizon 5" in res.message
    assert res.conflicts and res.conflicts[0].text == "{parent(b1) = slot}"
    check_conflict_infeasible(compiled, res.conflicts[0])
    assert brute_force(compiled, 5).shortest is None


def test_time_limit_is_honoured():
    res = solve_compiled(occupied_problem(), SolveOptions(time_limit=1e-4, max_horizon=6))
    assert res.status == TIME_LIMIT and "time limit" in res.message


@pytest.mark.parametrize("make", [occupied_problem, unsolvable_problem])
def test_gnpp_is_complete_against_brute_force(make):
    compiled = make()
    bf = brute_force(compiled, 5)
    assert bf.exhausted
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=5))
    assert res.stats.N == bf.shortest
    assert res.solved == (bf.shortest is not None)
    assert bf.plans_checked > res.stats.plans     # brute force had to look at more plans


def test_database_persists_what_was_learned(tmp_path: Path):
    db = tmp_path / "toy.sqlite"
    first = solve_compiled(occupied_problem(), SolveOptions(switches="trn", database=str(db), time_limit=60,
                                                            max_horizon=6))
    assert first.switches == "trng" and first.solved
    second = solve_compiled(occupied_problem(), SolveOptions(switches="trn", database=str(db), time_limit=60,
                                                             max_horizon=6))
    assert second.solved and second.stats.N == first.stats.N
    assert second.stats.nlp_solves < first.stats.nlp_solves
    assert second.conflicts[0].source == "database"
    assert second.conflicts[0].text == first.conflicts[0].text
    check_solution(occupied_problem(), second)


def test_oneway_with_a_database_is_a_user_error():
    with pytest.raises(UserError, match="needs the gnpp algorithm"):
        SolveOptions(algorithm="oneway", database="x.sqlite").validated()
    with pytest.raises(UserError):
        SolveOptions(switches="trx").validated()


def test_json_result(tmp_path: Path):
    res = solve_compiled(occupied_problem(), SolveOptions(time_limit=60, max_horizon=6))
    out = tmp_path / "r.json"
    res.write_json(out)
    data = json.loads(out.read_text())
    assert data["status"] == "solved" and data["stats"]["N"] == 4 and data["stats"]["N0"] == 2
    assert len(data["steps"]) == 5 and data["steps"][0]["action"] is None
    assert data["steps"][4]["values"]["pose(b1)"][0] == pytest.approx(1.0, abs=0.02)
    assert data["conflicts"][0]["text"] == "{parent(b1) = target, parent(b2) = s2}"
    assert data["conflicts"][0]["named"] == [[["parent(b1)", "target"], ["parent(b2)", "s2"]]]
    assert data["plan"] == res.plan


@pytest.mark.parametrize("algorithm,switches", [("gnpp", "trn"), ("oneway", "")])
def test_trajectories_after_mode_switches(algorithm, switches):
    compiled = occupied_problem(waypoints=8)
    res = solve_compiled(compiled, SolveOptions(algorithm=algorithm, switches=switches, time_limit=60,
                                                max_horizon=6))
    assert res.solved and res.stats.N == 4
    check_solution(compiled, res)
    # every motion phase has a trajectory from pose@i to pose@i+1 with bounded steps
    for i, st in enumerate(res.steps[:-1]):
        pts = st.trajectories["path(b2)"]
        assert len(pts) == 8
        assert pts[0][0] == pytest.approx(st.values["pose(b2)"][0], abs=1e-6)
        assert pts[-1][0] == pytest.approx(res.steps[i + 1].values["pose(b2)"][0], abs=1e-6)


def test_interpolation_and_keyframes():
    import numpy as np

    from gnppdsl.compile.factors import VarInstance
    from gnppdsl.solve.interpolation import interpolate_trajectories, keyframe_of
    from gnppdsl.solve.plan_graph import bound_violation

    q0 = VarInstance("q", ("r",), 0, "R", 2)
    q1 = VarInstance("q", ("r",), 1, "R", 2)
    other = VarInstance("pose", ("r",), 0, "R", 3)
    tr = VarInstance("path", ("r",), 0, "R", 8, frozenset({"traj"}), waypoints=4)
    assert keyframe_of(tr, [q0, other]) == "q(r)"
    warm = interpolate_trajectories([tr], {q0: np.array([0.0, 1.0]), q1: np.array([3.0, -2.0]), other: np.zeros(3)})
    pts = warm[tr].reshape(4, 2)
    assert np.allclose(pts, [[0, 1], [1, 0], [2, -1], [3, -2]])
    se3a = VarInstance("x", ("r",), 0, "SE3", 7)
    se3b = VarInstance("x", ("r",), 1, "SE3", 7)
    trs = VarInstance("xs", ("r",), 0, "SE3", 21, waypoints=3)
    w = interpolate_trajectories([trs], {se3a: np.array([0, 0, 0, 0, 0, 0, 1.0]),
                                         se3b: np.array([1, 0, 0, 0, 0, 1.0, 0])})[trs].reshape(3, 7)
    assert np.allclose(np.linalg.norm(w[:, 3:], axis=1), 1.0) and np.allclose(w[1, :3], [0.5, 0, 0])
    b = VarInstance("q", ("r",), 0, "R", 2, lower=(-1.0, -1.0), upper=(1.0, 1.0))
    assert bound_violation([b], {b: np.array([0.5, 1.25])}) == pytest.approx(0.25)
    assert bound_violation([b], {b: np.array([0.5, -0.5])}) == 0.0


def test_a_solution_failing_the_independent_recheck_is_not_returned(monkeypatch):
    import gnppdsl.nlp.evaluate as evaluate
    from gnppdsl.solve.result import SOLVER_FAILURE

    real = evaluate.max_violation

    def corrupted(factors, values, geometry=None):
        worst, arg = real(factors, values, geometry)
        return worst + 1.0, arg          # as if the solver's values violated a factor

    monkeypatch.setattr(evaluate, "max_violation", corrupted)
    res = solve_compiled(occupied_problem(), SolveOptions(time_limit=60, max_horizon=6))
    assert res.status == SOLVER_FAILURE and not res.solved
    assert "independent re-check" in res.message


def test_a_failed_joint_solve_of_feasible_components_is_never_a_conflict(monkeypatch):
    """Property 4.5: if every component of a relaxed graph is feasible, so is the graph. A
    solver that fails on the whole (here: forced to) must not produce a conflict."""
    from gnppdsl.nlp.feasibility import FeasibilityResult
    from gnppdsl.solve.feasibility_check import FeasibilityCheck

    real = FeasibilityCheck.solve
    failed = []

    def flaky(self, g):
        if g.name == "G[no_col_traj]" and g.signature() not in self.results:
            failed.append(g.name)
            r = FeasibilityResult(False, {}, {ref: 1.0 for ref in g.factor_refs}, 1.0, 1.0, 0.0, 0, "forced", 1)
            self.results[g.signature()] = r
            return r
        return real(self, g)

    monkeypatch.setattr(FeasibilityCheck, "solve", flaky)
    messages = []
    compiled = occupied_problem()
    # screening off: the relaxation's factors nearly hold at the full graph's convergence
    # point, so by default the level would be skipped and never reach the forced failure
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=6,
                                                screen_tolerance=0.0),
                         progress=messages.append)
    assert failed and res.solved and res.stats.N == 4
    assert any("components feasible" in m for m in messages)
    assert [c.text for c in res.conflicts] == ["{parent(b1) = target, parent(b2) = s2}"]
    check_solution(compiled, res)


def test_a_false_conflict_without_facts_is_refuted_not_learnt(monkeypatch):
    """A conflict made only of `always` factors has empty partial states and would forbid every
    plan. Here the first plan's evaluation is forced to claim a feasible `always` factor as
    the conflict: the stricter confirmation solves it, so only that plan is blocked and the
    problem is still solved."""
    from gnppdsl.solve.loop import Loop

    real = Loop.evaluate
    forced = []

    def lying(self, graph, use_db):
        if not forced:
            always = [f for f in graph.factor_instances if all(not p.facts for p in f.generator)]
            assert always, "the toy domain has always-rules"
            forced.append(always[0])
            return ("conflict", (always[0],), "")
        return real(self, graph, use_db)

    monkeypatch.setattr(Loop, "evaluate", lying)
    compiled = occupied_problem()
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=6))
    assert forced and res.solved and res.stats.N == 4
    check_solution(compiled, res)
    assert res.conflicts[0].source == "plan" and "without facts" in res.conflicts[0].text
    for c in res.conflicts[1:]:
        check_conflict_infeasible(compiled, c)


def test_a_no_plan_under_nlp_conflicts_says_they_are_local_solves():
    """The "no plan" of a problem whose only conflict an NLP found says what it rests on (the
    conflicts from the starts tried are not proofs); a "no plan" with no NLP conflict does not."""
    res = solve_compiled(unsolvable_problem(), SolveOptions(switches="trn", time_limit=60, max_horizon=5))
    assert res.status == NO_PLAN and [c.source for c in res.conflicts] == ["nlp"]
    assert "1 of the conflicts rests on NLPs infeasible from every start tried" in res.message
    logical = solve_compiled(unsolvable_problem(), SolveOptions(switches="trn", time_limit=60, max_horizon=1))
    assert logical.status == NO_PLAN and not logical.conflicts
    assert "on NLPs infeasible" not in logical.message
