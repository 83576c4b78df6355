"""Action costs as expressions of the scene (`cost step + norm(pos(pose0(a)) - pos(pose0(b)))`).

Oracles: the costs recomputed in the test from the scene's coordinates; the cheapest tour by
enumerating every order of the places (plain Python over the coordinates, no SAS+ at all); a
uniform-cost search over the compiled task's semantics (tests/compile/sas_semantics.py); Fast
Downward's optimal A* on the `.sas` file (costs in thousandths, `SASTask.cost_scale`).
"""
from __future__ import annotations

import math
import subprocess
import sys
from itertools import permutations

import pytest

from delivery import PLACES, STEP, write
from fd_oracle import run_fd_on_sas
from sas_semantics import optimal_cost

from gnppdsl.compile.sas import COST_RESOLUTION
from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem
from gnppdsl.logic.planner import IncrementalPlanner
from gnppdsl.logic.validate import validate_plan


def _dist(a: str, b: str) -> float:
    return STEP + math.dist(PLACES[a], PLACES[b])


def _cheapest_tour(must: tuple[str, ...]) -> float:
    """Visit every place of `must` from p0 and come back: each order of the places tried."""
    return min(sum(_dist(x, y) for x, y in zip(("p0",) + order, order + ("p0",)))
               for order in permutations(must))


@pytest.fixture(scope="module")
def tour(tmp_path_factory):
    path = write(tmp_path_factory.mktemp("tour"), "visited(p1) visited(p2) visited(p3) at(r) = p0")
    return build_task(load_problem(path))


def test_each_ground_cost_is_the_scene_distance(tour):
    assert len(tour.operators) == 20
    for op in tour.operators:
        a, b = op.name[len("move(r, "):-1].split(", ")
        assert op.cost == pytest.approx(_dist(a, b), abs=1e-12)
    assert tour.cost_scale() == COST_RESOLUTION


def test_clingo_optimal_plan_is_the_cheapest_tour(tour):
    expected = _cheapest_tour(("p1", "p2", "p3"))
    res = IncrementalPlanner(tour).optimal_plan(6)
    assert res.plan.optimal
    assert res.plan.cost == pytest.approx(expected, abs=4 * 0.5 / COST_RESOLUTION)
    assert validate_plan(tour, res.plan.operators).valid
    assert optimal_cost(tour) == pytest.approx(expected, abs=1e-9)   # the naive search agrees


def test_fast_downward_optimum_in_thousandths(tour):
    expected = _cheapest_tour(("p1", "p2", "p3"))
    res = run_fd_on_sas(write_sas(tour))
    assert res.solved and len(res.plan) == 4
    assert abs(res.cost - expected * COST_RESOLUTION) <= 4 * 0.5 + 1e-9


def test_integer_costs_are_not_scaled(tmp_path):
    from delivery import DOMAIN
    path = write(tmp_path, "visited(p1)", DOMAIN.replace("step + norm(pos(pose0(a)) - pos(pose0(b)))", "2 * 3"))
    task = build_task(load_problem(path))
    assert {op.cost for op in task.operators} == {6.0} and task.cost_scale() == 1
    assert "\n6\nend_operator" in write_sas(task)


def test_gnpp_check_grounds_costs_and_locates_a_negative_one(tmp_path):
    """`gnpp check` evaluates the costs of problems whose domain has cost expressions: a ground
    value below 0 is a located error (exit 2), without importing numpy or the solvers."""
    from delivery import DOMAIN
    path = write(tmp_path, "visited(p1)", DOMAIN.replace("step + norm", "norm").replace(
        "pos(pose0(b)))", "pos(pose0(b))) - 1.1"))
    code = ("import sys\nfrom gnppdsl.cli.main import main\n"
            f"rc = main(['check', {str(tmp_path / 'domain.pntc')!r}, {str(path)!r}])\n"
            "print(rc, [m for m in ('casadi', 'clingo', 'numpy') if m in sys.modules])\n")
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120)
    assert proc.stdout.strip().endswith("2 []"), proc.stdout + proc.stderr
    assert "domain.pntc:12:8: error: the cost of move(r, p0, p1) is" in proc.stderr


def test_cost_bound_in_user_units(tour):
    """`optimal_plan(cost_bound=B)` (the anytime search's bound) is in the task's units although
    clasp sees thousandths: just below the optimum no plan, just above it the optimum."""
    expected = _cheapest_tour(("p1", "p2", "p3"))
    below = IncrementalPlanner(tour).optimal_plan(4, cost_bound=expected - 0.01)
    assert below.plan is None and below.status.value == "no plan"
    above = IncrementalPlanner(tour).optimal_plan(4, cost_bound=expected + 0.01)
    assert above.plan.cost == pytest.approx(expected, abs=4 * 0.5 / COST_RESOLUTION)


def test_a_cost_with_a_complex_power_is_a_located_error(tmp_path, capsys):
    """A negative base to a fractional power (the distance minus 1.1, to the 0.5) has no real
    value: a located error naming the ground action, exit 2 (it was a TypeError traceback)."""
    from delivery import DOMAIN

    from gnppdsl.cli.main import main
    path = write(tmp_path, "visited(p1)", DOMAIN.replace("step + norm", "(norm").replace(
        "pos(pose0(b)))", "pos(pose0(b))) - 1.1) ^ 0.5"))
    assert main(["check", str(tmp_path / "domain.pntc"), str(path)]) == 2
    err = capsys.readouterr().err
    assert "domain.pntc:12:" in err and "pow fails" in err and "Traceback" not in err


def test_lifted_pddl_refuses_a_cost_expression_at_its_location(tmp_path, capsys):
    """The lifted PDDL export cannot write a cost expression: the error is at the expression
    (file:line:col), exit 2; the grounded export writes the ground costs."""
    from delivery import DOMAIN

    from gnppdsl.cli.main import main
    path = write(tmp_path, "visited(p1)", DOMAIN)
    args = ["compile", str(tmp_path / "domain.pntc"), str(path), "--emit"]
    assert main(args + ["pddl", "-o", str(tmp_path / "lifted")]) == 2
    err = capsys.readouterr().err
    assert "domain.pntc:12:" in err and "not an integer constant" in err
    assert main(args + ["pddl-ground", "-o", str(tmp_path / "ground")]) == 0
