"""The `planner` setting (logic modes) in the solve: settings and command line, user errors, and
the GNPP loop in every mode on planar problems whose N > N0 (conflicts must be learned): each
mode solves them, the solution is re-checked by `solve_checks.check_solution` (a valid plan that
contains none of the learned conflicts; every factor re-evaluated, independent of the solver),
and the exact modes give expected.yaml's N0 and N.
"""
from __future__ import annotations

import sys
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "logic"))
from logic_fd import require_fd  # noqa: E402
from solve_checks import check_solution  # noqa: E402

from gnppdsl.errors import UserError  # noqa: E402
from gnppdsl.solve.compiled import load_and_compile  # noqa: E402
from gnppdsl.solve.loop import solve_compiled  # noqa: E402
from gnppdsl.solve.options import SolveOptions  # noqa: E402

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
EXPECTED = yaml.safe_load((PLANAR / "expected.yaml").read_text())["problems"]


def _problem(tmp_path: Path, solver_line: str) -> Path:
    (tmp_path / "domain.pntc").write_text((PLANAR / "domain.pntc").read_text())
    (tmp_path / "p1_one_block.pntc").write_text((PLANAR / "p1_one_block.pntc").read_text() + "\n" + solver_line + "\n")
    for extra in PLANAR.glob("*.yaml"):
        (tmp_path / extra.name).write_text(extra.read_text())
    return tmp_path / "p1_one_block.pntc"


def test_planner_setting_reaches_the_options_and_the_command_line_wins(tmp_path):
    c = load_and_compile(str(_problem(tmp_path, "solver { planner = fd }")))
    assert c.problem.settings.planner == "fd"
    assert SolveOptions.from_settings(c.problem.settings).planner == "fd"
    assert SolveOptions.from_settings(c.problem.settings, planner="sequential").planner == "sequential"
    assert SolveOptions().planner == "auto"


def test_unknown_planner_is_a_located_error(tmp_path):
    path = _problem(tmp_path, "solver { planner = fastdownward }")
    with pytest.raises(UserError) as e:
        load_and_compile(str(path))
    text = str(e.value)
    assert "unknown planner 'fastdownward'" in text and "fd" in text
    assert f"p1_one_block.pntc:{len(path.read_text().splitlines())}:" in text


@pytest.mark.parametrize("algorithm", ["oneway", "rlgp"])
def test_fd_cannot_serve_enumeration_or_costs(algorithm):
    with pytest.raises(UserError, match="planner fd cannot serve"):
        SolveOptions(algorithm=algorithm, planner="fd").validated()
    with pytest.raises(UserError, match="planner 'x' is not available"):
        SolveOptions(planner="x").validated()


def test_cli_planner_option(capsys):
    from gnppdsl.cli.main import main

    with pytest.raises(SystemExit) as e:
        main(["solve", str(PLANAR / "p1_one_block.pntc"), "--planner", "nope"])
    assert e.value.code == 2
    assert "--planner" in capsys.readouterr().err
    assert main(["solve", str(PLANAR / "p3_occupied.pntc"), "--planner", "fd", "--quiet"]) == 0
    assert "solved, N = 4" in capsys.readouterr().out


@pytest.mark.parametrize("mode", ["sequential", "fd", "auto"])
@pytest.mark.parametrize("name", ["p3_occupied", "t1_swap"])
def test_gnpp_loop_in_every_mode(mode, name):
    if mode != "sequential":
        require_fd()
    e = EXPECTED[name]
    comp = load_and_compile(str(PLANAR / e["file"]))
    opts = SolveOptions.from_settings(comp.problem.settings, planner=mode, time_limit=120)
    r = solve_compiled(comp, opts)
    assert r.solved, r.message
    check_solution(comp, r)         # valid plan avoiding every learned conflict; factors hold
    if mode != "fd":                # exact: shortest logical plan first, shortest feasible plan
        assert r.stats.N0 == e["n0"] and r.stats.N0_shortest
        assert r.stats.N == e["n"]
    else:
        assert r.stats.N0 >= e["n0"] and r.stats.N >= e["n"]
        # proven shortest only by a bounded search's "no plan" below it (FastDownwardPlanner._tighten)
        assert r.stats.N0_shortest is False or r.stats.N0 == e["n0"]
    assert r.stats.first_plan_time is not None and r.stats.conflicts >= 1
