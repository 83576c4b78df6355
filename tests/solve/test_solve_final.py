"""`rule back(g: gripper) : final => ref(q(g), home(g))`: "the gripper ends at home", solved on a
planar problem that needs a conflict. Oracles: `solve_checks.check_solution` (a valid plan free
of the learned conflicts; every factor of the graph-NLP rebuilt from the plan's states and
re-evaluated by numpy) and the home position read from the scene YAML here."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve_checks import check_solution  # noqa: E402

from gnppdsl.solve.compiled import load_and_compile  # noqa: E402
from gnppdsl.solve.loop import solve_compiled  # noqa: E402
from gnppdsl.solve.options import SolveOptions  # noqa: E402

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
EXPECTED = yaml.safe_load((PLANAR / "expected.yaml").read_text())["problems"]


def test_gripper_ends_at_home_after_the_last_action(tmp_path):
    # a domain of its own name: the planar reference model of solve_checks knows no `final`
    domain = (PLANAR / "domain.pntc").read_text().replace("domain planar_blocks", "domain planar_final")
    (tmp_path / "domain.pntc").write_text(
        domain + "\nrule back(g: gripper) : final => planar.ref(q(g), home(g)) tags robot\n")
    (tmp_path / "p3_occupied.pntc").write_text(
        (PLANAR / "p3_occupied.pntc").read_text().replace("for planar_blocks", "for planar_final"))
    (tmp_path / "p3_occupied.yaml").write_text((PLANAR / "p3_occupied.yaml").read_text())
    home = yaml.safe_load((PLANAR / "p3_occupied.yaml").read_text())["robots"]["g"]["home"]

    comp = load_and_compile(str(tmp_path / "p3_occupied.pntc"))
    r = solve_compiled(comp, SolveOptions.from_settings(comp.problem.settings, time_limit=120))
    assert r.solved, r.message
    check_solution(comp, r)
    assert r.plan[-1] == "final()" and r.stats.N == EXPECTED["p3_occupied"]["n"] + 1
    last, before = r.steps[-1].values["q(g)"], r.steps[-2].values["q(g)"]
    assert np.allclose(last, home, atol=1e-5)
    assert not np.allclose(before, home, atol=1e-2)     # the place left it elsewhere: it moved
