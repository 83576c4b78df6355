"""Objectives (`minimize`): the optimisation phase moves the solution where the objective says,
keeps it feasible, reports the cost, and never changes what the loop decides.

Oracles: the scene YAML and the returned relative poses (world positions recomputed here with
plain trigonometry), the numpy re-check of the solution, and the same problem solved with the
phase switched off."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest
import yaml

from gnppdsl.cli.main import main
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
TARGET = (0.6, 0.1)      # a corner of p1's region r1 where the disc b1 still fits inside
OBJECTIVE = f"""
template near(o: object, t: R[2]) tags cost {{
  minimize dot(pos(world(o)) - t, pos(world(o)) - t)
}}
rule placed_near(o: block, r: region) : parent(o) = r => near(o, [{TARGET[0]}, {TARGET[1]}])
"""


def _domain_with(tmp: Path, extra: str, problem: str) -> Path:
    (tmp / "domain.pntc").write_text((PLANAR / "domain.pntc").read_text() + extra)
    shutil.copy(PLANAR / f"{problem}.pntc", tmp)
    shutil.copy(PLANAR / f"{problem}.yaml", tmp)
    return tmp / f"{problem}.pntc"


def _solve(path: Path, **kw):
    c = load_and_compile([str(path)])
    return c, solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=60, **kw))


def _world_xy(path: Path, result, obj: str, region: str) -> tuple[float, float]:
    """obj's world position at the last step: the region's scene pose composed with obj's pose
    relative to it (SE2), computed from the YAML and the returned numbers."""
    scene = yaml.safe_load(path.with_suffix(".yaml").read_text())
    rx, ry, rt = scene["objects"][region]["pose"]
    x, y, _ = result.steps[-1].values[f"pose({obj})"]
    return rx + math.cos(rt) * x - math.sin(rt) * y, ry + math.sin(rt) * x + math.cos(rt) * y


def test_the_objective_moves_the_block_to_the_predicted_point(tmp_path):
    path = _domain_with(tmp_path, OBJECTIVE, "p1_one_block")
    _, res = _solve(path)
    assert res.solved, res.message
    wx, wy = _world_xy(path, res, "b1", "r1")
    assert math.hypot(wx - TARGET[0], wy - TARGET[1]) < 1e-3
    assert res.stats.optimised and res.stats.max_violation <= 1e-6
    # the cost reported is the objective at the returned numbers
    assert res.stats.cost == pytest.approx((wx - TARGET[0]) ** 2 + (wy - TARGET[1]) ** 2, abs=1e-9)
    assert res.stats.cost_feasible > res.stats.cost
    # without the phase the loop's feasible solution stays, elsewhere in the region
    _, plain = _solve(path, optimise=False)
    px, py = _world_xy(path, plain, "b1", "r1")
    assert math.hypot(px - TARGET[0], py - TARGET[1]) > 0.05
    assert plain.stats.cost == pytest.approx((px - TARGET[0]) ** 2 + (py - TARGET[1]) ** 2, abs=1e-9)
    assert not plain.stats.optimised


def test_objectives_do_not_change_what_the_loop_decides(tmp_path):
    path = _domain_with(tmp_path, OBJECTIVE, "p3_occupied")
    _, with_obj = _solve(path)
    _, without = _solve(PLANAR / "p3_occupied.pntc")
    for r in (with_obj, without):
        assert r.solved, r.message
    assert with_obj.plan == without.plan
    s, t = with_obj.stats, without.stats
    assert (s.nlp_solves, s.plans, s.conflicts, s.N0, s.N) == (t.nlp_solves, t.plans, t.conflicts, t.N0, t.N)
    assert without.stats.cost is None and with_obj.stats.cost is not None


def test_a_vector_objective_is_a_located_error(tmp_path, capsys):
    bad = OBJECTIVE.replace("minimize dot(pos(world(o)) - t, pos(world(o)) - t)", "minimize pos(world(o)) - t")
    path = _domain_with(tmp_path, bad, "p1_one_block")
    assert main(["check", str(path)]) == 2
    err = capsys.readouterr().err
    assert "minimize takes a scalar (R)" in err
    line = next(i for i, ln in enumerate((tmp_path / "domain.pntc").read_text().splitlines(), 1)
                if "minimize pos" in ln)
    assert f"domain.pntc:{line}:" in err


def test_json_carries_cost_and_path_lengths(tmp_path):
    import json

    path = _domain_with(tmp_path, OBJECTIVE, "p1_one_block")
    out = tmp_path / "r.json"
    assert main(["solve", str(path), "--json", str(out), "--quiet"]) == 0
    data = json.loads(out.read_text())
    assert data["cost"] == pytest.approx(data["stats"]["cost"]) and data["cost"] < 1e-6
    assert data["path_length"] == {}         # a planar gripper has no joint configuration
