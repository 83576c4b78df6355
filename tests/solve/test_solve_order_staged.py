"""The loop's evaluation order "staged" (small relaxations, the full graph, then the large ones)
and the `order` key of `solver { }` blocks: the order of levels follows from the factor counts,
the answers are the same as the other orders' and are checked independently, and a bad order
in a solver block is a located diagnostic."""
from __future__ import annotations

import textwrap
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.errors import UserError
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.plan_evaluation import PlanEvaluation, STAGED_FRACTION
from gnppdsl.solve.plan_graph import plan_graph, TRAJ
from solve_checks import check_conflict_infeasible, check_solution

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"


class _G:
    """A stand-in for a GraphNLP: only factor counts and factor sets matter to the level order."""

    def __init__(self, n: int, modes: int | None = None, tag: str = ""):
        self.n_factors, self._modes = n, modes
        self.factor_refs = [(tag, i) for i in range(n)]

    def apply_relaxation(self, dropped, name=""):
        assert set(dropped) == {TRAJ}
        return _G(self._modes, tag="modes")


def test_staged_puts_small_levels_first_and_large_ones_after_the_full_graph():
    full = (None, _G(300, modes=100))
    a, b, c, d = ("a", _G(30, tag="a")), ("b", _G(50, tag="b")), ("c", _G(51, tag="c")), ("d", _G(90, tag="d"))
    # a and b have at most half of the 100 mode-switch factors; c and d more
    assert PlanEvaluation.staged(full[1], [a, b, c, d, full]) == [a, b, full, c, d, full]
    # no large level: the full graph once, last (Alg. 1 searches it if it is infeasible)
    assert PlanEvaluation.staged(full[1], [a, b, full]) == [a, b, full]
    # no trajectories: the mode-switch graph is the full graph
    plain = (None, _G(80, modes=0))
    assert PlanEvaluation.staged(plain[1], [a, c, plain]) == [a, plain, c, plain]
    # a large level that is the mode-switch graph itself is the only one searched
    modes_level = ("no_traj", _G(100, tag="modes"))
    assert PlanEvaluation.staged(full[1], [a, c, d, modes_level, full]) == [a, full, modes_level, full]


def test_staged_weighs_levels_by_the_cost_it_is_given():
    """With a cost per iteration (the loop passes `FeasibilitySolver.iteration_cost`), a level
    with more than half of the mode-switch graph's factors but a small share of its cost is a
    small level, and a level with few factors but most of the cost a large one."""
    full = (None, _G(300, modes=100))
    cheap, dear = ("cheap", _G(80, tag="cheap")), ("dear", _G(20, tag="dear"))
    cost = {"cheap": 100.0, "dear": 900.0, "modes": 1000.0}
    by_cost = PlanEvaluation.staged(full[1], [cheap, dear, full], lambda g: cost[g.factor_refs[0][0]])
    assert by_cost == [cheap, full, dear, full]
    assert PlanEvaluation.staged(full[1], [cheap, dear, full]) == [dear, full, cheap, full]   # by factors


def test_on_lab3_the_level_without_collisions_goes_before_the_full_graph():
    """Lab 3's first plan (the right arm puts b5 on pad_l, out of its reach): the level without
    collisions keeps 20 of the mode-switch graph's 38 factors, so by factor count it would wait
    for the full graph; its distance rows are few (the fingers' clearance), so by the cost of an
    iteration it goes first, where its small NLPs find the reach conflict."""
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.nlp.feasibility import FeasibilitySolver

    c = load_and_compile(str(PLANAR.parent / "lab" / "lab3.pntc"))
    states = plan_states(c.task, parse_plan(c.task, "pick(b5, right_arm, table); put(b5, right_arm, pad_l)"))
    g = plan_graph(c.factory, states)
    levels = [(r, g.apply_relaxation(r.dropped, r.name)) for r in c.relaxations if r.dropped] + [(None, g)]
    names = {id(lv[1]): (lv[0].name if lv[0] else "full") for lv in levels}
    solver = FeasibilitySolver(c.geometry, compiler=c.body_compiler("off"))
    modes = g.apply_relaxation({TRAJ}, "modes")
    no_col = dict((r.name, h) for r, h in levels[:-1])["no_col_traj"]
    assert no_col.n_factors > STAGED_FRACTION * modes.n_factors
    assert solver.iteration_cost(no_col) <= STAGED_FRACTION * solver.iteration_cost(modes)

    def order(cost=None):
        got = PlanEvaluation.staged(g, levels) if cost is None else PlanEvaluation.staged(g, levels, cost)
        return [names[id(h)] for _, h in got]

    by_cost, by_count = order(solver.iteration_cost), order()
    assert by_cost.index("no_col_traj") < by_cost.index("full")
    assert "no_col_traj" not in by_count[:by_count.index("full")]     # after it, or not at all


@pytest.mark.parametrize("name, n", [("p3_occupied", 4), ("t1_swap", None)])
def test_staged_answers_are_checked_independently(name, n):
    c = load_and_compile(str(PLANAR / f"{name}.pntc"))
    staged = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, order="staged"))
    full = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, order="full_first"))
    assert staged.solved and full.solved
    assert staged.stats.N == full.stats.N and (n is None or staged.stats.N == n)
    check_solution(c, staged)
    for conflict in staged.conflicts:
        check_conflict_infeasible(c, conflict)


def _problem(tmp_path, solver_line: str, domain_order: bool = True) -> Path:
    tmp_path.mkdir(parents=True, exist_ok=True)
    dom = (PLANAR / "domain.pntc").read_text()
    if not domain_order:
        assert "order = staged  " in dom
        dom = dom.replace("order = staged  ", "")
    (tmp_path / "domain.pntc").write_text(dom)
    prob = (PLANAR / "p1_one_block.pntc").read_text()
    (tmp_path / "p1_one_block.pntc").write_text(prob + "\n" + solver_line + "\n")
    for extra in PLANAR.glob("*.yaml"):
        (tmp_path / extra.name).write_text(extra.read_text())
    return tmp_path / "p1_one_block.pntc"



def test_order_in_a_solver_block_reaches_the_options_and_the_command_line_wins(tmp_path):
    c = load_and_compile(str(_problem(tmp_path, "solver { order = staged }")))
    assert c.problem.settings.order == "staged"
    assert SolveOptions.from_settings(c.problem.settings).order == "staged"
    assert SolveOptions.from_settings(c.problem.settings, order="relaxed_first").order == "relaxed_first"
    # the problem's block wins over its domain's (the planar domain says staged)
    c = load_and_compile(str(_problem(tmp_path / "p", "solver { order = full_first }")))
    assert SolveOptions.from_settings(c.problem.settings).order == "full_first"
    assert load_and_compile(str(PLANAR / "p1_one_block.pntc")).problem.settings.order == "staged"
    # without the key anywhere: the solver's default
    plain = load_and_compile(str(_problem(tmp_path / "q", "", domain_order=False)))
    assert plain.problem.settings.order is None
    assert SolveOptions.from_settings(plain.problem.settings).order == SolveOptions().order


def test_unknown_order_in_a_solver_block_is_a_located_error(tmp_path):
    path = _problem(tmp_path, "solver { order = stagd }")
    with pytest.raises(UserError) as e:
        load_and_compile(str(path))
    text = str(e.value)
    assert "unknown order 'stagd'" in text and "staged" in text
    line = len(path.read_text().splitlines())
    assert f"p1_one_block.pntc:{line}:" in text, text


def test_unknown_order_option_is_a_user_error():
    with pytest.raises(UserError, match="full_first, relaxed_first or staged"):
        SolveOptions(order="sideways").validated()


# ---------------------------------------------------------------- motions between fixed keyframes

def _toy():
    from solve_toy import occupied_problem

    return occupied_problem(waypoints=8)


def _check_toy(compiled, res):
    assert res.solved and res.stats.N == 4, res.message
    check_solution(compiled, res)
    for conflict in res.conflicts:
        assert conflict.source == "nlp"
        check_conflict_infeasible(compiled, conflict)


@pytest.mark.parametrize("order", ["full_first", "staged"])
def test_motions_are_solved_phase_by_phase_between_fixed_keyframes(monkeypatch, order, zigzag_starts):
    from gnppdsl.nlp.feasibility import FeasibilitySolver

    real_solve = FeasibilitySolver.solve
    fixed_bounds = []

    def spy_solve(self, g, warm_start=None, initial_guess=None, seed=0, **kw):
        if "{motion" in g.name:
            # every keyframe variable of a phase NLP is fixed by its bounds, the motion is free
            keys = [v for v in g.variables if not v.waypoints]
            assert keys and all(v.lower is not None and v.lower == v.upper for v in keys)
            assert all(v.lower is None or v.lower != v.upper for v in g.variables if v.waypoints)
            fixed_bounds.append(g.name)
        return real_solve(self, g, warm_start=warm_start, initial_guess=initial_guess, seed=seed, **kw)

    results = []
    real = FeasibilityCheck.motions_between_keyframes

    def spy(self, g, trajs, warm, **kw):
        r = real(self, g, trajs, warm, **kw)
        results.append(r is not None)
        return r

    monkeypatch.setattr(FeasibilitySolver, "solve", spy_solve)
    monkeypatch.setattr(FeasibilityCheck, "motions_between_keyframes", spy)
    compiled = _toy()
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=6, order=order))
    _check_toy(compiled, res)
    assert fixed_bounds and results and results[-1]   # the solution came from the phases


def test_a_failed_phase_falls_back_to_the_joint_solve_and_is_no_verdict(monkeypatch, zigzag_starts):
    """Every phase NLP (keyframes fixed) is forced to fail: the loop solves all motions jointly
    and finds the same answer, without a conflict from the failed phases."""
    from gnppdsl.nlp.feasibility import FeasibilityResult, FeasibilitySolver

    real = FeasibilitySolver.solve
    forced = []

    def flaky(self, g, warm_start=None, initial_guess=None, seed=0, **kw):
        if "{motion" in g.name:
            forced.append(g.name)
            return FeasibilityResult(False, {}, {ref: 1.0 for ref in g.factor_refs}, 1.0, 1.0, 0.0, 0, "forced", 1)
        return real(self, g, warm_start=warm_start, initial_guess=initial_guess, seed=seed, **kw)

    monkeypatch.setattr(FeasibilitySolver, "solve", flaky)
    compiled = _toy()
    res = solve_compiled(compiled, SolveOptions(switches="trn", time_limit=60, max_horizon=6, order="staged"))
    assert forced
    _check_toy(compiled, res)
