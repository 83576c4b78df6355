"""Consistency of the example files: expected.yaml vs problem comments, scenes vs objects.

These checks need no front end: they read the files as text / YAML. The front-end checks
(`gnpp check`, compilation) are in test_examples_frontend.py.
"""
from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_reference import EXAMPLES, expected_comment, raw_scene  # noqa: E402

DIRS = ["planar", "lab", "mobile", "field", "workshop", "scalability"]
STDLIB = EXAMPLES.parent / "stdlib"


def _expected(d: str) -> dict:
    return yaml.safe_load((EXAMPLES / d / "expected.yaml").read_text())


def _problems():
    for d in DIRS:
        for name, e in _expected(d)["problems"].items():
            yield d, name, e


def _strip(text: str) -> str:
    return re.sub(r"#[^\n]*", "", text)


def _section(text: str, name: str) -> str:
    m = re.search(rf"\b{name}\s*\{{([^}}]*)\}}", _strip(text))
    return m.group(1) if m else ""


def _declared_objects(text: str) -> dict[str, str]:
    out = {}
    for names, ty in re.findall(r"([\w\s,.]+?)\s*:\s*(\w+)", _section(text, "objects")):
        for n in names.replace(",", " ").split():
            rng = re.fullmatch(r"([A-Za-z_]+)(\d+)\.\.\1(\d+)", n)       # b1..b4: b1, b2, b3, b4
            for k in range(int(rng.group(2)), int(rng.group(3)) + 1) if rng else ():
                out[f"{rng.group(1)}{k}"] = ty
            if not rng:
                out[n] = ty
    return out


@pytest.mark.parametrize("d", DIRS)
def test_every_problem_is_listed(d):
    listed = {e["file"] for e in _expected(d)["problems"].values()}
    on_disk = {p.name for p in (EXAMPLES / d).glob("*.pntc") if p.name != "domain.pntc"}
    assert listed == on_disk
    assert (EXAMPLES / d / _expected(d)["domain"]).is_file()


@pytest.mark.parametrize("d,name,e", list(_problems()))
def test_problem_matches_expected_yaml(d, name, e):
    path = EXAMPLES / d / e["file"]
    text = path.read_text()
    assert re.search(rf"^problem\s+{name}\s+for\s+\w+", _strip(text), re.M), "problem name = key"
    n0, n = expected_comment(path)
    assert (n0, n) == (e["n0"], e["n"])
    assert e["n"] is None or e["n"] >= e["n0"]


@pytest.mark.parametrize("d,name,e", list(_problems()))
def test_scene_has_every_object(d, name, e):
    """Each problem object is a robot or object of the scene (domain constants too)."""
    text = (EXAMPLES / d / e["file"]).read_text()
    scene_file = re.search(r'\bscene\s+"([^"]+)"', text).group(1)
    scene = raw_scene(EXAMPLES / d / scene_file)
    names = set(scene.get("robots", {})) | set(scene.get("objects", {}))
    declared = _declared_objects(text)
    domain = (EXAMPLES / d / "domain.pntc").read_text()
    constants = _declared_objects(domain.replace("constants", "objects", 1)) if "constants" in domain else {}
    missing = (set(declared) | set(constants)) - names
    assert not missing, f"{scene_file} lacks {sorted(missing)}"
    assert scene["dimension"] == (2 if d == "planar" else 3)
    for ob in declared:
        if ob in scene.get("robots", {}):
            assert "home" in scene["robots"][ob]


def test_planar_scene_attributes():
    """Planar blocks have radius, regions half extents, grippers reach boxes (used by templates)."""
    for y in (EXAMPLES / "planar").glob("*.yaml"):
        if y.name == "expected.yaml":
            continue
        sc = yaml.safe_load(y.read_text())
        for name, ob in sc["objects"].items():
            if name.startswith("b"):
                assert ob["radius"] == ob["shape"]["circle"]
            if "half_extent" in ob:
                assert [2 * h for h in ob["half_extent"]] == ob["size"][:2]
        for r in sc["robots"].values():
            assert len(r["home"]) == 3 and len(r["reach_min"]) == 2 and len(r["reach_max"]) == 2


def test_lab_scene_matches_paper():
    """The paper's Lab geometry (Sec. VIII-A, robotics issue): table, bases, block size."""
    for f in ("lab.yaml", "lab_obstacles.yaml", "lab4.yaml"):
        sc = raw_scene(EXAMPLES / "lab" / f)
        t = sc["objects"]["table"]
        assert t["size"][:2] == [2.3, 1.24]
        assert abs(t["pose"]["xyz"][2] + t["size"][2] / 2 - 0.6) < 1e-9
        xs = sorted(r["base"]["xyz"][0] for r in sc["robots"].values())
        assert xs == [-0.4, 0.4]
        for r in sc["robots"].values():
            assert r["model"] == "panda" and r["ee"] == "panda_hand_tcp"
            assert r["base"]["xyz"][1] == -0.3 and r["base"]["rpy"] == [0, 0, 1.5708]
            assert len(r["home"]) == 7
        for name, ob in sc["objects"].items():
            if name[0] in "bo" and name[1:].isdigit():
                assert ob["size"] == [0.06, 0.15, 0.09]
                # resting on the table top
                assert abs(ob["pose"]["xyz"][2] - (0.6 + 0.045)) < 1e-9


def test_lab_relaxations_are_appendix_c():
    text = _strip((EXAMPLES / "lab" / "domain.pntc").read_text())
    body = re.search(r"relaxations\s*\{([^}]*)\}", text).group(1)
    drops = [frozenset(x.strip() for x in m.split(",")) for m in re.findall(r"drop\s+([\w ,]+)", body)]
    assert drops == [frozenset(s) for s in (
        {"robot", "collision", "traj"}, {"collision", "traj"}, {"robot", "time", "traj"},
        {"time", "traj"}, {"traj"})]


def test_stdlib_modules_present():
    for m in ("prelude", "planar", "manipulation", "panda", "tools"):
        text = (STDLIB / f"{m}.pntc").read_text()
        assert re.search(rf"^module\s+{m}\b", _strip(text), re.M)
