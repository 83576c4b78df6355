"""lab5_paper's N: 12 + 2 + 2 = 16, no handover (examples/scalability/generate.py).

The generator said N = 17 "by construction": b1, the bottom block of the left tower, starts
right of the middle (x = 0.3) and was taken to need a handover to reach pad_l. Solves returned
verified 16-step plans in which the left arm picks b1 where it stands. Here, independently of
the solver: the left arm grasps b1 at its start from above (inverse kinematics on the Lab's
Panda, as the family's grasp claims are checked), and with both pads covered (each obstacle
must be picked and set down before a block goes onto its pad: the conflicts every solve learns)
the shortest logical plan has 16 steps, exactly expected.yaml's N. lab4_paper's handover stays:
the left arm cannot grasp its b1 at x = 0.45."""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[2]
FAMILY = ROOT / "examples" / "scalability"
DOWN = np.column_stack([[0, 1, 0], [1, 0, 0], [0, 0, -1]]).astype(float)   # the family's grasp


def _grasp_error(problem: str, block: str, arm: str) -> float:
    sys.path.insert(0, str(Path(__file__).resolve().parent))
    import test_examples_lab_reach as reach       # a test module beside this one: never a skip
    x, y, z = yaml.safe_load((FAMILY / f"{problem}.yaml").read_text())["objects"][block]["pose"]["xyz"]
    return reach._ik(arm, (x, y, z + 0.03), DOWN)


def test_lab5_paper_needs_no_handover_and_n_is_16():
    sys.path.insert(0, str(ROOT / "tests" / "logic"))
    from test_logic_raised_bound import _lab5

    from gnppdsl.logic.planner import IncrementalPlanner
    from gnppdsl.logic.validate import validate_plan

    assert _grasp_error("lab5_paper", "b1", "left_arm") < 1e-4      # b1 where it stands
    task, covered = _lab5()
    planner = IncrementalPlanner(task)
    planner.add_lifted(covered("pad_l", "o1") + covered("pad_r", "o2"))
    res = planner.shortest_plan(max_horizon=22)
    assert res.found and res.plan.shortest and len(res.plan) == 16
    assert validate_plan(task, res.plan.operators, planner.conflicts).valid
    expected = yaml.safe_load((FAMILY / "expected.yaml").read_text())["problems"]["lab5_paper"]
    assert (expected["n0"], expected["n"]) == (12, len(res.plan))


def test_lab4_paper_keeps_its_handover():
    assert _grasp_error("lab4_paper", "b1", "left_arm") > 1e-2
    assert _grasp_error("lab4_paper", "b1", "right_arm") < 1e-4
