"""Randomised instance families (`gnppdsl.ir.instances`, paper 002's randomised evaluation):
reproducible per seed, inside the declared ranges, drawn objects apart, located errors; and
`gnpp bench --instances` running a planar family with every solution verified.

Oracles: the ranges and clearances read from the YAML text here (not through the loader's
attributes), plain trigonometry for the yaw, and the solver's own returned world poses for the
benchmark (the block starts where the instance put it)."""
from __future__ import annotations

import csv
import math
import shutil
from pathlib import Path

import numpy as np
import pytest
import yaml

from gnppdsl.cli.main import main
from gnppdsl.errors import UserError
from gnppdsl.ir import load_problem
from gnppdsl.ir.instances import draw_instance, random_objects

ROOT = Path(__file__).resolve().parents[2]
MOBILE = ROOT / "examples" / "mobile"
PLANAR = ROOT / "examples" / "planar"


def _yaw(q) -> float:
    x, y, z, w = q
    return math.atan2(2 * (w * z + x * y), 1 - 2 * (y * y + z * z))


def test_sorting_family_is_reproducible_inside_its_ranges_and_apart():
    problem = load_problem(MOBILE / "sort_random.pntc")
    spec = yaml.safe_load((MOBILE / "sorting_random.yaml").read_text())["objects"]
    names = random_objects(problem.scene)
    assert names == list(spec)                                     # red1, blue1, red2
    seen, yaws = set(), set()
    for k in range(25):
        a, b = draw_instance(problem, k).scene, draw_instance(problem, k).scene
        assert a.objects == b.objects                               # same seed, same instance
        centres = {}
        for n in names:
            lo_x, lo_y, hi_x, hi_y = spec[n]["random_xy"]
            pose = a.objects[n].pose
            assert lo_x <= pose[0] <= hi_x and lo_y <= pose[1] <= hi_y
            assert pose[2] == pytest.approx(spec[n]["pose"]["xyz"][2])   # height as written
            assert np.linalg.norm(pose[3:]) == pytest.approx(1.0)
            lo, hi = spec[n]["random_yaw"]                      # the family draws a yaw too
            assert lo - 1e-9 <= _yaw(pose[3:]) <= hi + 1e-9
            yaws.add(round(_yaw(pose[3:]), 6))
            centres[n] = np.array(pose[:2])
        for i, m in enumerate(names):
            for n in names[i + 1:]:
                half = 0.5 * math.hypot(*spec[m]["size"][:2]) + 0.5 * math.hypot(*spec[n]["size"][:2])
                assert np.linalg.norm(centres[m] - centres[n]) >= half + spec[n]["random_clearance"] - 1e-12
        seen.add(tuple(np.round(centres["red1"], 6)))
        # everything else is the scene as written
        assert {n: o for n, o in a.objects.items() if n not in names} == \
               {n: o for n, o in problem.scene.objects.items() if n not in names}
    assert len(seen) == 25                                          # different seeds differ
    assert len(yaws) == 75 and max(map(abs, yaws)) > 1.0            # turned, each differently
    # the instance changes what the compiled problem starts from
    assert problem.scene.objects["red1"].pose[:2] == (-0.3, -0.25)


def test_a_fixed_scene_has_no_instances():
    with pytest.raises(UserError, match="no `random_xy` range"):
        draw_instance(load_problem(PLANAR / "p1_one_block.pntc"), 0)
    assert main(["solve", str(PLANAR / "p1_one_block.pntc"), "--instance", "0", "--quiet"]) == 2


@pytest.mark.parametrize("attribute, message", [
    ("random_xy: [0.5, 0, -0.5, 0.2]", "random_xy must be"),      # lo > hi
    ("random_xy: 3", "random_xy must be"),                          # a scalar (was a TypeError)
    ("random_xy: [0, 0, 1, 1], random_yaw: [0, 1, 2]", "random_yaw must be"),
    ("random_xy: [0, 0, 1, 1], random_clearance: [1, 2]", "random_clearance must be"),   # (TypeError)
    ("random_xy: [0, 0, 1, 1], random_clearance: -1", "random_clearance must be"),
    ("random_xy: [0, 0, 1, 1], random_clearance: 1e-2", "YAML reads '1e-2' as text"),   # was "unknown key"
])
def test_bad_ranges_are_located_by_gnpp_check(tmp_path, capsys, attribute, message):
    """A malformed `random_*` attribute is an error of the scene at its value, found by `gnpp
    check` (before, only `--instance` found some of them, some as a traceback)."""
    shutil.copy(PLANAR / "domain.pntc", tmp_path)
    shutil.copy(PLANAR / "p1_one_block.pntc", tmp_path)
    text = (PLANAR / "p1_one_block.yaml").read_text()
    bad = text.replace("radius: 0.05, color: red}", f"radius: 0.05, color: red, {attribute}}}")
    assert bad != text
    (tmp_path / "p1_one_block.yaml").write_text(bad)
    line = 1 + bad[:bad.index(attribute)].count("\n")
    assert main(["check", str(tmp_path / "p1_one_block.pntc")]) == 2
    err = capsys.readouterr().err
    assert f"p1_one_block.yaml:{line}:" in err and message in err and "Traceback" not in err
    assert main(["solve", str(tmp_path / "p1_one_block.pntc"), "--instance", "0", "--quiet"]) == 2


def test_bench_runs_a_planar_family_with_every_solution_verified(tmp_path, capsys):
    for f in ("domain.pntc", "p1_one_block.pntc"):
        shutil.copy(PLANAR / f, tmp_path)
    text = (PLANAR / "p1_one_block.yaml").read_text()
    family = text.replace("s1: {pose: [-0.5, 0.0, 0.0]}",
                          "s1: {pose: [-0.5, 0.0, 0.0], random_xy: [-0.7, -0.5, -0.2, 0.5], random_yaw: [-3, 3]}")
    assert family != text
    (tmp_path / "p1_one_block.yaml").write_text(family)
    out = tmp_path / "family.csv"
    assert main(["bench", str(tmp_path / "p1_one_block.pntc"), "--algorithms", "gnpp", "--instances", "3",
                 "--seed", "5", "--time-limit", "30", "--anytime", "10", "--csv", str(out), "--quiet"]) == 0
    rows = list(csv.DictReader(open(out, newline="")))
    assert [r["instance"] for r in rows] == ["5", "6", "7"] and all(r["seed"] == "0" for r in rows)
    assert all(r["solved"] == "True" and r["verified"] == "True" and r["steps"] == "2" for r in rows)
    # with --anytime: two actions, no objective, and no cheaper plan (a plan of one action
    # cannot move the block into the region)
    assert all(r["proved_optimal"] == "True" and float(r["cost"]) == 2.0 for r in rows)
    table = capsys.readouterr().out
    assert "base[m] where all solved" in table and "3/3" in table
    # the spot of instance 6, where its block starts, is the one `gnpp solve --instance 6` reports
    res_json = tmp_path / "six.json"
    assert main(["solve", str(tmp_path / "p1_one_block.pntc"), "--instance", "6", "--quiet",
                 "--json", str(res_json)]) == 0
    import json

    start = json.loads(res_json.read_text())["steps"][0]["world"]["b1"]
    drawn = draw_instance(load_problem(tmp_path / "p1_one_block.pntc"), 6).scene.objects["s1"].pose2
    assert start[:2] == pytest.approx(drawn[:2], abs=1e-9)
    assert -0.7 <= drawn[0] <= -0.2 and -0.5 <= drawn[1] <= 0.5
