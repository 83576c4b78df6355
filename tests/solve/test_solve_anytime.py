"""Anytime mode (`gnppdsl.solve.anytime`): cheaper logical plans under a cost bound after the
first solution, a proof of optimality when the bound leaves no plan.

Problem: the planar domain with one more rule, the travel of every gripper as the objective
(sum over transitions of the squared displacement of its position); one block to move from a
spot into a region, two grippers, one near the block and one far. Every plan that does it with
one gripper costs 2 (actions) + that gripper's travel; plans with a handover cost >= 3.

Oracles: (1) the optimal travel of each one-gripper plan computed here from the scene numbers
alone by a grid search over the grasp offset (the held disc's centre lies within grasp_tol of
the gripper, its offset is fixed in the gripper frame while held; the gripper may turn freely):
no code of gnppdsl; (2) the objective re-evaluated from the returned gripper poses; (3) the
proof's claim checked by arithmetic: every other plan's lower bound (its action costs) is at
least the returned cost.
"""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from gnppdsl.cli.main import main
from gnppdsl.ir.expr import Call, Num, Slot
from gnppdsl.solve.anytime import nonnegative
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
TRAVEL = """
template travel(g: object) tags cost {
  minimize dot(pos(q(g)') - pos(q(g)), pos(q(g)') - pos(q(g)))
}
rule move(g: gripper) : always -> always => travel(g)
"""
PROBLEM = """problem two for planar_blocks
scene "two.yaml"
objects { b1 : block  s1 : spot  r1 : region  g1, g2 : gripper }
init { parent(b1) = s1  holding(g1) = none  holding(g2) = none }
goal { parent(b1) = r1 }
"""
NEAR, FAR = (-0.3, 0.3), (0.3, -0.6)
BLOCK, REGION, HALF, RADIUS, GRASP_TOL = (-0.3, 0.0), (0.3, 0.0), 0.15, 0.05, 0.01


def _scene(g1_home, g2_home, g1_reach_x=1.0) -> str:
    return f"""name: two
dimension: 2
workspace: [[-1, -1], [1, 1]]
robots:
  g1: {{kind: planar, home: [{g1_home[0]}, {g1_home[1]}, 0], shape: {{circle: 0.03}}, reach_min: [-1, -1], reach_max: [{g1_reach_x}, 1]}}
  g2: {{kind: planar, home: [{g2_home[0]}, {g2_home[1]}, 0], shape: {{circle: 0.03}}, reach_min: [-1, -1], reach_max: [1, 1]}}
objects:
  s1: {{pose: [{BLOCK[0]}, {BLOCK[1]}, 0.0]}}
  r1: {{shape: box, size: [{2 * HALF}, {2 * HALF}, 0.01], pose: [{REGION[0]}, {REGION[1]}, 0.0], half_extent: [{HALF}, {HALF}], static: true, color: yellow}}
  b1: {{shape: {{circle: {RADIUS}}}, pose: [{BLOCK[0]}, {BLOCK[1]}, 0.0], radius: {RADIUS}, color: red}}
"""


def _problem(tmp: Path, g1_home, g2_home, g1_reach_x=1.0) -> Path:
    (tmp / "domain.pntc").write_text((PLANAR / "domain.pntc").read_text() + TRAVEL)
    (tmp / "two.pntc").write_text(PROBLEM)
    (tmp / "two.yaml").write_text(_scene(g1_home, g2_home, g1_reach_x))
    return tmp / "two.pntc"


def optimal_travel(home) -> float:
    """The least travel of one gripper from `home` that picks the block and places it in the
    region: min over the grasp offset u (|u| = r <= tol, any direction) of
    |block - u - home|^2 + (dist(block - u, placeable box) - r)_+^2 (the gripper may turn at
    the place, so the offset's direction there is free)."""
    h, b = np.asarray(home, float), np.asarray(BLOCK, float)
    lo = np.asarray(REGION) - HALF + RADIUS
    hi = np.asarray(REGION) + HALF - RADIUS
    phi = np.linspace(0.0, 2 * np.pi, 2880, endpoint=False)
    best = np.inf
    for r in np.linspace(0.0, GRASP_TOL, 21):
        u = r * np.stack([np.cos(phi), np.sin(phi)], axis=1)
        target = b - u
        place = np.maximum(np.linalg.norm(np.clip(target, lo, hi) - target, axis=1) - r, 0.0) ** 2
        best = min(best, float(np.min(np.sum((target - h) ** 2, axis=1) + place)))
    return best


def _travel_of(result) -> float:
    """The objective re-evaluated from the returned gripper poses."""
    total = 0.0
    for a, b in zip(result.steps, result.steps[1:]):
        for g in ("g1", "g2"):
            p, q = np.asarray(a.values[f"q({g})"][:2]), np.asarray(b.values[f"q({g})"][:2])
            total += float(np.sum((q - p) ** 2))
    return total


def _solve(path: Path, **kw):
    c = load_and_compile([str(path)])
    return solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=60, **kw))


@pytest.mark.parametrize("homes", [(NEAR, FAR), (FAR, NEAR)], ids=["g1_near", "g2_near"])
def test_anytime_returns_the_brute_force_optimum_with_a_proof(tmp_path, homes):
    res = _solve(_problem(tmp_path, *homes), anytime=30)
    assert res.solved, res.message
    a = res.anytime
    near = "g1" if homes[0] == NEAR else "g2"
    assert all(near in step for step in res.plan)               # the near gripper does it
    expected = 2 + optimal_travel(NEAR)
    assert a["cost"] == pytest.approx(expected, abs=1e-4)
    assert res.stats.cost == pytest.approx(_travel_of(res), abs=1e-9)
    assert a["plan_cost"] + a["objective"] == pytest.approx(a["cost"])
    # proved over every plan: the far gripper's plan costs more, every handover plan >= 3
    assert a["proved_optimal"] and a["scope"] == "all plans", a["stopped"]
    assert 2 + optimal_travel(FAR) > a["cost"] and 3 > a["cost"]
    costs = [h["cost"] for h in a["history"]]
    assert costs == sorted(costs, reverse=True) and costs[-1] == a["cost"]
    if len(costs) == 2:                      # the first solution was the far gripper's
        assert costs[0] == pytest.approx(2 + optimal_travel(FAR), abs=1e-4)
    assert len(costs) <= 2 and res.stats.plans == 2
    assert res.verification["ok"]


def test_an_infeasible_cheap_plan_is_excluded_by_its_conflict(tmp_path):
    """The near gripper cannot reach the region (reach_max x = 0): its plan's conflict leaves
    the far gripper's plan, optimal since any handover costs >= 3."""
    res = _solve(_problem(tmp_path, NEAR, FAR, g1_reach_x=0.0), anytime=30)
    assert res.solved, res.message
    assert all("g2" in step for step in res.plan) and res.conflicts
    assert res.anytime["cost"] == pytest.approx(2 + optimal_travel(FAR), abs=1e-4)
    assert res.anytime["proved_optimal"] and res.anytime["cost"] < 3


def test_anytime_is_off_by_default_and_the_option_is_checked(tmp_path, capsys):
    path = _problem(tmp_path, NEAR, FAR)
    assert _solve(path).anytime is None
    assert main(["solve", str(path), "--anytime", "-1", "--quiet"]) == 2
    assert "--anytime -1" in capsys.readouterr().err


def test_nonnegative_recognises_sums_of_squares_only():
    x, y = Slot(0), Slot(1)
    d = Call("sub", (x, y))
    assert nonnegative(Call("dot", (d, d))) and nonnegative(Call("norm", (x,)))
    assert nonnegative(Call("add", (Call("sqnorm", (x,)), Call("mul", (Num(2.0), Call("abs", (y,)))))))
    assert nonnegative(Call("mul", (d, d)))
    assert not nonnegative(Call("dot", (x, y))) and not nonnegative(d)
    assert not nonnegative(Call("mul", (Num(-1.0), Call("norm", (x,)))))
