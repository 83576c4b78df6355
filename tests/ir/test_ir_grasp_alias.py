"""The parallel gripper's grasp is robot-neutral: `manipulation.parallel_grasp` (the Panda's
tcp and the PR2's tool frame both close along y); its old name `panda.grasp` stays an alias
with the same rows, for domains written against it (examples/lab, workshop and field call it)."""
from __future__ import annotations

from pathlib import Path

from gnppdsl.ir import load_domain, load_module

ROOT = Path(__file__).resolve().parents[2]


def test_parallel_grasp_and_its_old_name_have_the_same_rows():
    m = load_module(ROOT / "stdlib" / "manipulation.pntc")
    p = load_module(ROOT / "stdlib" / "panda.pntc")
    new, old = m.templates["manipulation.parallel_grasp"], p.templates["panda.grasp"]
    assert new.body == old.body and new.params == old.params and new.tags == old.tags
    assert len(new.body) == 8


def test_the_mobile_domain_calls_the_robot_neutral_grasp():
    d = load_domain(ROOT / "examples" / "mobile" / "domain.pntc")
    calls = {c.template for r in d.rules for c in r.calls}
    assert "manipulation.parallel_grasp" in calls and "panda.grasp" not in calls
