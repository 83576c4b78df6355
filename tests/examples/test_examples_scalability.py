"""examples/scalability: the committed files are what generate.py writes, and the geometric
claims behind their expected N hold, checked with pinocchio IK directly (not gnppdsl.geometry):
every block the family means one arm to handle (stack: both blocks of a column, clutter: block
and pad of a column) is within that arm's reach with a top grasp.
"""
from __future__ import annotations

import importlib.util
import sys
from pathlib import Path

import numpy as np
import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_reference import EXAMPLES  # noqa: E402

FAMILY = EXAMPLES / "scalability"


def _generator():
    spec = importlib.util.spec_from_file_location("scalability_generate", FAMILY / "generate.py")
    mod = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = mod              # dataclasses look their module up
    spec.loader.exec_module(mod)
    return mod


def test_committed_files_are_generated(tmp_path):
    gen = _generator()
    assert gen.main(["--out", str(tmp_path)]) == 0
    written = sorted(p.name for p in tmp_path.iterdir() if p.name != "domain.pntc")
    committed = sorted(p.name for p in FAMILY.iterdir() if p.suffix in (".pntc", ".yaml") and p.name != "domain.pntc")
    assert written == committed
    for name in written:
        assert (tmp_path / name).read_text() == (FAMILY / name).read_text(), name
    assert (FAMILY / "domain.pntc").resolve() == (EXAMPLES / "lab" / "domain.pntc").resolve()


def test_generator_rejects_bad_parameters(capsys):
    gen = _generator()
    assert gen.main(["--out", "/nonexistent-never", "--stack", "5"]) == 2
    assert "even number" in capsys.readouterr().err


def _arm_for(x: float) -> str:
    return "left_arm" if x < 0 else "right_arm"


def _claims():
    """(problem, arm, point) for every grasp the family's N relies on."""
    expected = yaml.safe_load((FAMILY / "expected.yaml").read_text())["problems"]
    for name in expected:
        if not name.startswith(("stack_", "clutter_")):
            continue
        scene = yaml.safe_load((FAMILY / f"{name}.yaml").read_text())["objects"]
        for obj, spec in scene.items():
            if obj == "table" or obj.startswith("o"):
                continue
            x, y, z = spec["pose"]["xyz"]
            top = z + 0.045 if obj.startswith("pad") else z + 0.03     # tcp near the top face
            yield name, _arm_for(x), obj, (x, y, top)


@pytest.mark.parametrize("name,arm,obj,point", [c for c in _claims() if c[0] in ("stack_32", "clutter_6")])
def test_family_grasps_are_reachable(name, arm, obj, point):
    import test_examples_lab_reach as reach       # a test module beside this one: never a skip
    R = np.column_stack([[0, 1, 0], [1, 0, 0], [0, 0, -1]]).astype(float)
    assert reach._ik(arm, point, R) < 1e-4, f"{name}: {arm} cannot grasp {obj} at {point}"
    # a stacked block: the top of the pair (stack) is reachable too
    if name.startswith("stack_"):
        assert reach._ik(arm, (point[0], point[1], point[2] + 0.09), R) < 1e-4
