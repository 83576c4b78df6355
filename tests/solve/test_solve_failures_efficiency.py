"""User-facing failures of `gnpp solve` / `gnpp bench` (one clear line, right exit code), the
deadline between ipopt runs, the public world-pose API, and the evaluation orders of the loop
(full graph first / relaxations first) giving the same, independently checked answers."""
from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.cli.main import main

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"

from gnppdsl.solve import loop  # noqa: E402
from gnppdsl.solve.compiled import load_and_compile  # noqa: E402
from gnppdsl.solve.deadline import deadline_solver, TimeUp  # noqa: E402
from gnppdsl.solve.feasibility_check import FeasibilityCheck  # noqa: E402
from gnppdsl.solve.inferred_verdicts import CLOSE_START  # noqa: E402
from gnppdsl.solve.loop import Loop, solve_compiled  # noqa: E402
from gnppdsl.solve.options import SolveOptions  # noqa: E402
from gnppdsl.solve.plan_graph import bound_violation  # noqa: E402
from solve_checks import check_conflict_infeasible, check_solution  # noqa: E402

_C: dict = {}


def compiled(name: str):
    if name not in _C:
        _C[name] = load_and_compile(str(PLANAR / f"{name}.pntc"))
    return _C[name]


def _one_line(text: str) -> str:
    lines = [ln for ln in text.strip().splitlines() if ln.strip()]
    assert len(lines) == 1, text
    assert "Traceback" not in text
    return lines[0]


def test_bad_db_file_is_one_line_exit_2(capsys, tmp_path):
    bad = tmp_path / "bad.db"
    bad.write_text("this is not an SQLite file\n" * 20)
    code = main(["solve", str(PLANAR / "p1_one_block.pntc"), "--db", str(bad), "--quiet"])
    err = capsys.readouterr().err
    assert code == 2
    assert "not a usable subgraph database" in _one_line(err) and "bad.db" in err
    # a missing directory is created (as for --json: README commands work on a fresh clone)
    code = main(["solve", str(PLANAR / "p1_one_block.pntc"), "--db", str(tmp_path / "no" / "x.db"), "--quiet"])
    assert code == 0 and (tmp_path / "no" / "x.db").is_file()
    (tmp_path / "file").write_text("")
    code = main(["solve", str(PLANAR / "p1_one_block.pntc"), "--db", str(tmp_path / "file" / "x.db")])
    assert code == 2 and "not a directory" in _one_line(capsys.readouterr().err)


def test_bad_problem_file_names_the_place_exit_2(capsys, tmp_path):
    (tmp_path / "domain.pntc").write_text((PLANAR / "domain.pntc").read_text())
    bad = tmp_path / "bad.pntc"
    bad.write_text("problem bad for planar_blocks\nobjects { b1 : blok }\ngoal { parent(b1) = b1 }\n")
    assert main(["solve", str(bad), "--quiet"]) == 2
    err = capsys.readouterr().err
    assert f"{bad}:2:" in err and "unknown type 'blok'" in err and "Traceback" not in err


def test_solver_failure_exit_1_with_reason(capsys, monkeypatch):
    """A solution failing the independent re-check is reported, never returned as solved:
    a re-check threshold below floating-point noise makes the real p1 solution fail it."""
    real = loop.solve_compiled

    def strict(c, options, progress=None):
        return real(c, replace(options, check_tolerance=1e-300), progress)

    monkeypatch.setattr(loop, "solve_compiled", strict)
    code = main(["solve", str(PLANAR / "p1_one_block.pntc"), "--quiet"])
    out = capsys.readouterr()
    assert code == 1
    assert "solver_failure" in out.out and "independent re-check" in _one_line(out.err)


def test_bench_csv_directory_checked_before_running(capsys, tmp_path):
    """A CSV that cannot be written is refused before any run (a missing directory is created:
    tests/cli/test_cli_bench_sweep.py; here the would-be directory is a file)."""
    (tmp_path / "afile").write_text("x")
    code = main(["bench", str(PLANAR / "p1_one_block.pntc"), "--seeds", "1", "--csv",
                 str(tmp_path / "afile" / "x.csv")])
    captured = capsys.readouterr()
    assert code == 2 and "--csv" in _one_line(captured.err)
    assert "GNPP" not in captured.out            # nothing was run


def test_broken_pipe_is_quiet_for_every_command(monkeypatch, capsys):
    import gnppdsl.cli.check as check_cmd
    import gnppdsl.cli.main as cli_main

    silenced = []

    def broken(args):
        raise BrokenPipeError()

    monkeypatch.setattr(check_cmd, "run", broken)
    monkeypatch.setattr(cli_main, "_silence_stdout", lambda: silenced.append(True))
    assert main(["check", str(PLANAR / "p1_one_block.pntc")]) == 0
    assert silenced and capsys.readouterr().err == ""


def test_deadline_stops_between_ipopt_runs():
    """The solver of a run refuses to start another ipopt run after the deadline (restarts and
    the polish re-solve would otherwise each get ipopt's full per-run limit)."""
    from gnppdsl.nlp.feasibility import FeasibilitySolver
    from gnppdsl.nlp.graph import GraphNLP

    c = compiled("p1_one_block")
    plan_states = [c.task.initial]
    graph = GraphNLP.from_factors(c.factory.factors(plan_states), c.factory.variables(plan_states))
    solver = deadline_solver(FeasibilitySolver)(c.geometry)
    solver.deadline = 0.0
    with pytest.raises(TimeUp):
        solver.solve(graph)
    solver.deadline = float("inf")
    assert solver.solve(graph).feasible
    assert deadline_solver(FeasibilitySolver) is type(solver)


def test_time_of_a_solve_stopped_inside_a_run_counts_in_solve_time(monkeypatch):
    """A solve stopped inside an ipopt run (the run's time limit, a signal) still adds the time
    it spent to `solve_time` (Stats.nlp_time). A fake clock: the stopped run takes exactly 7 s."""
    import time

    from gnppdsl.nlp.feasibility import FeasibilitySolver
    from gnppdsl.nlp.graph import GraphNLP

    c = compiled("p1_one_block")
    plan_states = [c.task.initial]
    graph = GraphNLP.from_factors(c.factory.factors(plan_states), c.factory.variables(plan_states))
    solver = deadline_solver(FeasibilitySolver)(c.geometry)
    clock = [1000.0]
    monkeypatch.setattr(time, "perf_counter", lambda: clock[0])

    def run_stopped_after_7_s(self, *args, **kwargs):
        clock[0] += 7.0
        raise TimeUp()

    monkeypatch.setattr(FeasibilitySolver, "_run", run_stopped_after_7_s)
    with pytest.raises(TimeUp):
        solver.solve(graph)
    assert solver.solve_time == 7.0


def test_time_of_a_logic_search_stopped_by_the_alarm_counts_in_logic_time(monkeypatch):
    """A planner search cut off by the run's alarm or a signal (`interrupt.Interrupted`, raised
    inside the search) still adds its time to Stats.logic_time. A fake clock: 11 s."""
    import time

    from gnppdsl import interrupt
    from gnppdsl.solve.run import Run

    c = compiled("p1_one_block")
    run = Run(c, SolveOptions.from_settings(c.problem.settings), None)
    before = run.stats.logic_time
    clock = [5000.0]
    monkeypatch.setattr(time, "perf_counter", lambda: clock[0])

    def search_cut_off(*args, **kwargs):
        clock[0] += 11.0
        raise interrupt.Interrupted("time_limit")

    monkeypatch.setattr(run.planner, "shortest_plan", search_cut_off)
    monkeypatch.setattr(run.planner, "next_plan", search_cut_off)
    for enumerate_ in (False, True):
        with pytest.raises(interrupt.Interrupted):
            run.next_plan(enumerate_)
    assert run.stats.logic_time - before == 22.0


@pytest.mark.parametrize("order", ["full_first", "relaxed_first"])
def test_orders_agree_and_are_checked_independently(order):
    c = compiled("p3_occupied")
    res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, order=order, switches="trn"))
    assert res.solved and res.stats.N == 4 and res.stats.N0 == 2
    check_solution(c, res)
    for conflict in res.conflicts:
        check_conflict_infeasible(c, conflict)


def test_full_first_costs_one_nlp_on_a_feasible_first_plan():
    """p2's first plan is feasible: the full graph-NLP alone decides it (no relaxation solved).
    relaxed_first checks its relaxation levels first, but the plan's initial guess (blocks on
    their spots, grippers at home) satisfies them: they are answered without an NLP."""
    c = compiled("p2_two_blocks")
    full = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, switches="trn",
                                                        order="full_first"))
    relaxed = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, switches="trn",
                                                           order="relaxed_first"))
    assert full.solved and relaxed.solved and full.stats.plans == relaxed.stats.plans == 1
    assert full.stats.nlp_solves == 1 and full.stats.reused_solutions == 0
    assert relaxed.stats.nlp_solves == 1 and relaxed.stats.reused_solutions >= 1
    check_solution(c, relaxed)


def test_a_graph_its_start_satisfies_is_feasible_without_an_nlp():
    """`known_solution` answers from the start an NLP would get (earlier values completed by the
    initial guess) only when the factors really hold there: re-evaluated here with the numpy
    evaluator, and refused once the guess is moved off a block's spot."""
    from gnppdsl.nlp.evaluate import max_violation

    c = compiled("p1_one_block")
    run = Loop(c, SolveOptions.from_settings(c.problem.settings), None)
    graph = run.build_graph([c.task.initial])          # with the factory's initial guess
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    r = checker.known_solution(graph)
    assert r is not None and r.feasible and set(r.values) == set(graph.variables)
    assert r.status.startswith("its start")
    assert max_violation(graph.factor_instances, r.values, c.geometry)[0] <= 1e-6
    assert run.nlp_calls == 0

    off = run.build_graph([c.task.initial])
    pose = next(v for v in off.variables if v.kind == "pose")
    off.initial_guess[pose] = off.initial_guess[pose] + 0.05
    assert FeasibilityCheck(run, run.new_solver(), off, use_db=False).known_solution(off) is None


def test_bad_order_is_a_user_error():
    from gnppdsl.errors import UserError

    with pytest.raises(UserError, match="order 'sideways'"):
        SolveOptions(order="sideways").validated()


def test_world_pose_expr_matches_the_solution():
    """factory.world_pose_expr: a held block's world pose is its gripper's pose composed with
    its relative pose; a block on a spot sits at the spot's scene pose."""
    from gnppdsl.compile.factors import FactorInstance
    from gnppdsl.compile.sas import PartialState
    from gnppdsl.ir.expr import Constraint, Num
    from gnppdsl.nlp.evaluate import constraint_rows

    c = compiled("p1_one_block")
    res = solve_compiled(c, SolveOptions.from_settings(c.problem.settings))
    assert res.solved
    states, values = res.extras["plan"].states, res.extras["values"]

    def world(obj, i):
        expr, variables = c.factory.world_pose_expr(obj, states, i)
        probe = FactorInstance("t.world", "t", (), frozenset(), i, 1, (PartialState(),), variables,
                               (Constraint(expr, "==", Num(0.0)),))
        return np.array([h for _, h in constraint_rows(probe, values, c.geometry)])

    s1 = c.problem.scene.entity("s1").pose
    assert np.allclose(world("b1", 0)[:2], np.asarray(s1, float)[:2], atol=1e-6)
    # step 1: b1 held by g -> world(b1) = q(g) * pose(b1); the grasp keeps it within 1 cm
    by = {(v.key, v.step): np.asarray(x, float) for v, x in values.items()}
    q, rel = by[("q(g)", 1)], by[("pose(b1)", 1)]
    c_, s_ = np.cos(q[2]), np.sin(q[2])
    expected = q[:2] + np.array([c_ * rel[0] - s_ * rel[1], s_ * rel[0] + c_ * rel[1]])
    assert np.allclose(world("b1", 1)[:2], expected, atol=1e-9)
    with pytest.raises(IndexError):
        c.factory.world_pose_expr("b1", states, len(states))
    # the factory keeps the derived states of the last plan asked: another plan is derived anew
    # (its step 1 does not exist: the one-state plan, asked right after the whole one)
    with pytest.raises(IndexError):
        c.factory.world_pose_expr("b1", states[:1], 1)
    assert np.allclose(world("b1", 1)[:2], expected, atol=1e-9)


def _first_plan_graph(run):
    res = run.planner.shortest_plan(time_limit=30)
    assert res.found
    return res.plan, run.build_graph(res.plan.states)


@pytest.mark.parametrize("name", ["p5_handover", "p6_clutter"])
def test_verdicts_without_nlps_are_right(name):
    """Every verdict the checker derives without solving -- components of an infeasible graph
    located at its convergence point, subgraphs satisfied by an earlier point -- is checked
    here on its own: feasible ones by evaluating their values with numpy, infeasible ones by
    solving them from many random starts."""
    from gnppdsl.nlp.evaluate import max_violation
    from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

    c = compiled(name)
    run = Loop(c, SolveOptions.from_settings(c.problem.settings, switches="trn"), None)
    plan, graph = _first_plan_graph(run)
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    r = checker.solve(graph)
    assert not r.feasible                     # the first plan of both problems fails
    for rule in c.relaxations:
        checker.solve(graph.apply_relaxation(rule.dropped, rule.name))
    derived = [(sig, v) for sig, v in checker.results.items() if v.starts == 0]
    assert derived, "no verdict was derived without an NLP"
    strict = FeasibilitySolver(c.geometry, SolverOptions(restarts=6, noise=1.0))
    for sig, verdict in derived:
        sub = graph._derive(sig, "{check}")
        if verdict.feasible:
            worst, _ = max_violation(sub.factor_instances, verdict.values, c.geometry)
            assert worst <= 1e-6 and bound_violation(sub.variables, verdict.values) <= 1e-6
        else:
            assert not strict.solve(sub, seed=3).feasible, sub.describe()


def test_no_start_certificate_for_a_trajectory():
    """A trajectory's initial guess (the arm resting at home) satisfies its own limits, speed,
    smoothness and clearance factors, but it must not be certified: certified values join the
    plan's solved values, and a trajectory found there is taken as solved, so later graphs
    holding it would skip the keyframes-first solve (lab5 seed 8 timed out that way)."""
    from gnppdsl.nlp.evaluate import max_violation

    c = load_and_compile(str(Path(__file__).resolve().parents[2] / "examples" / "lab" / "lab1.pntc"))
    run = Loop(c, SolveOptions.from_settings(c.problem.settings), None)
    graph = run.build_graph([c.task.initial, c.task.initial])
    path = next(v for v in graph.variables if v.waypoints)
    sub = graph.subgraph(variables=[path])
    assert sub.n_factors > 0
    assert max_violation(sub.factor_instances, {path: graph.initial_guess[path]}, c.geometry)[0] <= 1e-9
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    assert checker.start_point(sub) is None and checker.known_solution(sub) is None
    assert path not in checker.values


@pytest.mark.parametrize("shift,used", [(2e-4, True), (5e-2, False)])
def test_a_subgraph_starts_from_a_convergence_point_only_when_it_nearly_holds(shift, used):
    """`FeasibilityCheck.solve` starts a subgraph from an earlier convergence point when that point
    violates the subgraph by less than CLOSE_START and less than the earlier solutions do;
    a point farther off (the local minimum of the solve that produced it) is not used. The
    point here is a solution of the slice (solved apart) moved by `shift`; the verdict
    reached from either start is re-evaluated with numpy."""
    from gnppdsl.nlp.evaluate import max_violation

    c = compiled("p5_handover")
    run = Loop(c, SolveOptions.from_settings(c.problem.settings, switches="trn"), None)
    plan, graph = _first_plan_graph(run)
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    lo, hi = graph.steps
    for a, b in [(a, b) for a in range(lo, hi + 1) for b in range(a, hi + 1)]:
        s = graph.time_slice(a, b)       # a feasible slice its initial guess does not satisfy
        start = checker.start_point(s)
        if s.n_factors and start and max_violation(s.factor_instances, start, c.geometry)[0] > 0.1:
            sol = run.new_solver().solve(s, seed=1)
            if sol.feasible:
                break
    else:
        raise AssertionError("no feasible slice away from its initial guess")
    pose = next(v for v in s.variables if v.kind == "pose")
    point = {**sol.values, pose: sol.values[pose] + shift}
    at_point = max_violation(s.factor_instances, point, c.geometry)[0]
    assert 1e-6 < at_point
    checker.points = [point]
    starts = []
    inner = checker.solver.solve

    def spy(g, warm_start=None, **kw):
        starts.append(dict(warm_start or {}))
        return inner(g, warm_start=warm_start, **kw)

    checker.solver.solve = spy
    r = checker.solve(s)
    assert starts, "the slice was answered without an NLP"
    from_point = all(np.array_equal(starts[0].get(v), point[v]) for v in s.variables)
    assert from_point is used
    if used:
        assert at_point < CLOSE_START
    if r.feasible:
        assert max_violation(s.factor_instances, r.values, c.geometry)[0] <= 1e-6


def test_a_stricter_resolve_cut_short_by_ipopt_is_no_verdict():
    """`Run.infeasible` (a sweeping conflict's check, the minimiser's smaller subgraphs): an
    infeasible answer whose ipopt run hit its own time limit ("walltime") is TimeUp, not a
    verdict, as in `FeasibilityCheck.solve`; a real infeasible answer is True."""
    from types import SimpleNamespace

    from gnppdsl.solve.run import Run

    class Answer:
        def __init__(self, status):
            self.status = status

        def solve(self, graph, seed):
            return SimpleNamespace(feasible=False, status=self.status)

    run = SimpleNamespace(deadline=float("inf"), nlp_calls=0)
    assert Run.infeasible(run, Answer("Infeasible_Problem_Detected"), [], 0) is True
    with pytest.raises(TimeUp):
        Run.infeasible(run, Answer("Maximum_WallTime_Exceeded"), [], 0)
    assert run.nlp_calls == 2
