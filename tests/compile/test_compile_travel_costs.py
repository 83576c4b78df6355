"""Action costs that call the reachability graph's travel: `travel(r, a, b)` and its
straight-line lower bound `travel_lb(r, a, b)` (issue 22). At this layer there is no graph: the
compiled task carries the bound for both (the solve layer puts the graph's travel in,
tests/solve/test_solve_travel_costs.py).

Oracles: the costs recomputed in the test from the scene YAML's coordinates and the block's w_x
(not through the scene loader); the cheapest assignment of items to trays by enumerating the
four assignments (plain Python); a uniform-cost search over the compiled task's semantics
(tests/compile/sas_semantics.py). The misuses are located errors of `gnpp check` (exit 2).
"""
from __future__ import annotations

from itertools import product

import pytest

from delivery import DOMAIN as PLANAR_DOMAIN
from delivery import write as write_planar
from mobile_travel import W_X, arguments, lower_bound, scene_xy, write
from sas_semantics import optimal_cost

from gnppdsl.cli.main import main
from gnppdsl.compile.costs import uses_travel
from gnppdsl.compile.sas import COST_RESOLUTION
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem
from gnppdsl.logic.planner import IncrementalPlanner
from gnppdsl.logic.validate import validate_plan


@pytest.fixture(scope="module")
def mobile(tmp_path_factory):
    return write(tmp_path_factory.mktemp("travel"))


def test_compiled_costs_are_the_lower_bound_from_the_scene(mobile):
    """pick: 0.5 + travel_lb(r, from, o); drop: 1 + travel(r, o, to), which the compiled task
    (no graph) carries as its lower bound: w_x * the horizontal distance, by hand."""
    xy = scene_xy(mobile)
    task = build_task(load_problem(mobile / "sort2.pntc"))
    seen = {"pick": 0, "drop": 0}
    for op in task.operators:
        o, r, where = arguments(op.name)
        assert r == "mm"
        if op.action == "pick":
            assert op.cost == pytest.approx(0.5 + lower_bound(xy, where, o), abs=1e-12)
        else:
            assert op.cost == pytest.approx(1 + lower_bound(xy, o, where), abs=1e-12)
        seen[op.action] += 1
    assert seen == {"pick": 6, "drop": 4}     # picks from the table and from both trays
    # the weight matters: a drop to the far tray costs more than w_x = 1 would give
    drop = next(op for op in task.operators if op.name == "drop(red1, mm, blue_tray)")
    assert drop.cost > 1 + lower_bound(xy, "red1", "blue_tray") / W_X + 1.0


def test_clingo_optimum_is_the_cheapest_assignment_to_trays(mobile):
    """Each item into either tray: the planner's optimum under the travel costs is the cheapest
    of the four assignments, enumerated by hand, and the naive search agrees."""
    xy = scene_xy(mobile)
    trays = ("red_tray", "blue_tray")

    def total(red_to: str, blue_to: str) -> float:
        return sum(0.5 + lower_bound(xy, "center", o) + 1 + lower_bound(xy, o, to)
                   for o, to in (("red1", red_to), ("blue1", blue_to)))

    expected = min(total(a, b) for a, b in product(trays, trays))
    assert expected == pytest.approx(total("red_tray", "blue_tray"))      # each to its near tray
    assert total("blue_tray", "red_tray") > expected + 1
    task = build_task(load_problem(mobile / "either.pntc"))
    res = IncrementalPlanner(task).optimal_plan(4)
    assert res.plan.optimal and validate_plan(task, res.plan.operators).valid
    assert res.plan.cost == pytest.approx(expected, abs=4 * 0.5 / COST_RESOLUTION)
    assert optimal_cost(task) == pytest.approx(expected, abs=1e-9)
    names = {task.operators[o].name for o in res.plan.operators}
    assert {"drop(red1, mm, red_tray)", "drop(blue1, mm, blue_tray)"} <= names


def test_uses_travel_finds_the_calls(mobile):
    dom = load_problem(mobile / "sort2.pntc").domain
    pick, drop = dom.actions["pick"].cost_expr, dom.actions["drop"].cost_expr
    assert uses_travel(pick) and not uses_travel(pick, ("travel",))
    assert uses_travel(drop, ("travel",))


def _check(tmp, problem: str, capsys) -> str:
    assert main(["check", str(tmp / "domain.pntc"), str(tmp / problem)]) == 2
    err = capsys.readouterr().err
    assert "Traceback" not in err
    return err


@pytest.mark.parametrize("drop, line_col, message", [
    ("cost 1 + travel(r, to)", "34:12", "travel takes 3 arguments (robot, from, to), got 2"),
    ("cost 1 + travel(r, 1, to)", "34:22", "expected an object (where the end effector starts)"),
    ("cost -travel(r, o, to)", "34:8", "but an action cost is a finite number >= 0"),
    ("cost 1 + travel(o, o, to)", "34:12", "'red1' (not a scene robot) has no reachability graph"),
    ("cost 1 + travel_lb(r, r, to)", "34:12", "'mm' (a robot) is no target of travel_lb"),
    ("cost 1 + travel(r, o, to) + q(r)[0]", "34:31", "cannot use the continuous variable 'q'"),
])
def test_misuses_are_located_errors(tmp_path, capsys, drop, line_col, message):
    err = _check(write(tmp_path, drop=drop), "sort2.pntc", capsys)
    assert f"domain.pntc:{line_col}: error:" in err, err
    if message is not None:
        assert message in err, err


def test_travel_without_a_reachability_block(tmp_path, capsys):
    err = _check(write(tmp_path, pick="cost 1", block=False), "sort2.pntc", capsys)
    assert "domain.pntc:34:12: error: the cost of drop(red1, mm, red_tray): travel(...) needs a " \
           "`reachability` block for robot 'mm', and problem 'sort2' has none" in err
    assert "hint: add `reachability NAME { robot = mm ... }`" in err


def test_travel_outside_a_cost(tmp_path, capsys):
    """In a template (here a `minimize` term) travel is not a function: located, kind cost; the
    domain alone is enough to find it."""
    tmp = write(tmp_path)
    dom = (tmp / "domain.pntc").read_text().replace("    minimize dot(", "    minimize travel(r, r, r) + dot(", 1)
    (tmp / "domain.pntc").write_text(dom)
    assert main(["check", str(tmp / "domain.pntc")]) == 2
    err = capsys.readouterr().err
    line = next(i for i, t in enumerate(dom.splitlines(), 1) if "minimize travel(" in t)
    assert f"domain.pntc:{line}:14: error: travel(...) is the reachability graph's travel, usable only in " \
           "an action's `cost`" in err and "Traceback" not in err


@pytest.mark.parametrize("fn", ["travel", "travel_lb"])
def test_travel_on_a_planar_scene(tmp_path, capsys, fn):
    """A planar scene has no reachability graph: the error is at the call, with a scene distance
    as the way out."""
    dom = PLANAR_DOMAIN.replace("cost step + norm(pos(pose0(a)) - pos(pose0(b)))", f"cost step + {fn}(r, a, b)")
    write_planar(tmp_path, "visited(p1)", dom)
    err = _check(tmp_path, "tour.pntc", capsys)
    assert f"domain.pntc:12:15: error: the cost of move(r, p0, p1): {fn}(...) is the travel of a " \
           "reachability graph, which needs a 3-D scene with a URDF robot; scene 'tour' is planar" in err
    assert "hint: use a scene distance instead" in err
