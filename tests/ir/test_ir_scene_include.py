"""Scene includes (`include:` in a scene YAML) and scene objects a problem does not declare.

Oracles: a merged scene is compared with the same scene written in one file (the Lab scenes
against their single-file originals kept in tests/ir/data/lab_inline); every misuse is checked
for its file:line:col, kind and hint.
"""
from __future__ import annotations

import textwrap
from dataclasses import replace
from pathlib import Path

import pytest

from gnppdsl.ir import load_problem
from gnppdsl.ir.scene import load_scene, load_scene_file
from gnppdsl.lang.diagnostics import Reporter

ROOT = Path(__file__).resolve().parents[2]


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(textwrap.dedent(text))
    return path


def errors(path: Path):
    r = Reporter()
    assert load_scene(path, r) is None
    return r.diagnostics


def at(diags, file: str, line: int, col: int, kind: str):
    hits = [d for d in diags if d.span is not None and d.span.file.endswith(file)
            and (d.span.line, d.span.column) == (line, col) and d.kind == kind]
    assert hits, [f"{d.span} {d.kind} {d.message}" for d in diags]
    return hits[0]


def content(scene):
    """What a scene says, without where it was written (paths and source positions)."""
    return (scene.name, scene.dimension, scene.workspace, scene.ignore_collisions,
            {k: replace(v, source="") for k, v in scene.robots.items()},
            {k: replace(v, source="") for k, v in scene.objects.items()})


@pytest.mark.parametrize("name", ["lab.yaml", "lab4.yaml", "lab_obstacles.yaml"])
def test_lab_scenes_with_include_equal_their_single_file_originals(name):
    new = load_scene_file(ROOT / "examples/lab" / name)
    old = load_scene_file(ROOT / "tests/ir/data/lab_inline" / name)
    assert "include:" in (ROOT / "examples/lab" / name).read_text()
    assert content(new) == content(old)
    assert list(new.objects) == list(old.objects)


def test_include_merges_nested_files_relative_to_the_including_file(tmp_path):
    (tmp_path / "common" / "meshes").mkdir(parents=True)
    (tmp_path / "common" / "meshes" / "m.stl").write_text("solid x\nendsolid x\n")
    write(tmp_path / "common" / "table.yaml", """\
        dimension: 2
        workspace: [[-1, -1], [1, 1]]
        objects:
          table: {shape: box, size: [1, 1], pose: [0.5, 0, 0], static: true}
          cup: {shape: mesh, file: meshes/m.stl, pose: [0, 0, 0]}
        """)
    write(tmp_path / "common" / "robots.yaml", """\
        include: table.yaml
        robots:
          g: {kind: planar, home: [0, 0, 0], shape: {circle: 0.03}}
        ignore_collisions: [[g, table]]
        """)
    s = load_scene_file(write(tmp_path / "scene.yaml", """\
        include: [common/robots.yaml]
        objects:
          b1: {shape: {circle: 0.05}, pose: [0.1, 0.2, 0.0], parent: table}
        """))
    assert s.dimension == 2 and s.workspace == ((-1, -1), (1, 1)) and s.name == "scene"
    assert list(s.robots) == ["g"] and list(s.objects) == ["table", "cup", "b1"]
    assert s.objects["b1"].pose2 == pytest.approx((0.6, 0.2, 0.0))    # parent from another file
    assert s.objects["cup"].shape.mesh_file == str((tmp_path / "common/meshes/m.stl").resolve())
    assert s.ignore_collisions == {frozenset({"g", "table"})}


def test_include_cycle_is_located_at_the_include_that_closes_it(tmp_path):
    write(tmp_path / "b.yaml", """\
        objects:
          x: {pose: [0, 0, 0]}
        include: a.yaml
        """)
    d = errors(write(tmp_path / "a.yaml", "include: b.yaml\n"))
    hit = at(d, "b.yaml", 3, 10, "cycle")
    assert "a.yaml -> b.yaml -> a.yaml" in hit.message and "itself" in hit.hint


def test_scene_including_itself(tmp_path):
    d = errors(write(tmp_path / "a.yaml", "include: [a.yaml]\n"))
    assert "a.yaml -> a.yaml" in at(d, "a.yaml", 1, 11, "cycle").message


def test_missing_include(tmp_path):
    d = errors(write(tmp_path / "a.yaml", "objects: {}\ninclude: [robots.yaml]\n"))
    hit = at(d, "a.yaml", 2, 11, "missing-file")
    assert "robots.yaml" in hit.message and str(tmp_path) in hit.hint


def test_name_defined_twice_across_files(tmp_path):
    write(tmp_path / "r.yaml", """\
        robots:
          g: {kind: planar}
        """)
    d = errors(write(tmp_path / "a.yaml", """\
        include: r.yaml
        objects:
          g: {pose: [0, 0, 0]}
        """))
    hit = at(d, "a.yaml", 3, 3, "duplicate")
    assert "already a robot" in hit.message and "r.yaml:2:3" in hit.hint


def test_two_includes_defining_one_name(tmp_path):
    write(tmp_path / "r1.yaml", "objects:\n  t: {pose: [0, 0, 0]}\n")
    write(tmp_path / "r2.yaml", "objects:\n  t: {pose: [1, 0, 0]}\n")
    d = errors(write(tmp_path / "a.yaml", "include: [r1.yaml, r2.yaml]\n"))
    assert "both in r2.yaml" in at(d, "a.yaml", 1, 20, "duplicate").message


def test_dimension_mismatch_with_an_include(tmp_path):
    write(tmp_path / "r.yaml", "dimension: 2\n")
    d = errors(write(tmp_path / "a.yaml", "include: r.yaml\ndimension: 3\n"))
    assert "differs" in at(d, "a.yaml", 2, 12, "include").message


def test_errors_inside_an_included_file_point_into_it(tmp_path):
    write(tmp_path / "r.yaml", """\
        objects:
          t: {pose: [0, 0, 0], parent: tabel}
          u: {pose: [0, 0, 0], colour: red}
        """)
    write(tmp_path / "table.yaml", "objects:\n  table: {pose: [0, 0, 0]}\n")
    d = errors(write(tmp_path / "a.yaml", "include: [table.yaml, r.yaml]\n"))
    assert "did you mean 'table'" in at(d, "r.yaml", 2, 32, "unknown-name").hint
    assert at(d, "r.yaml", 3, 24, "unknown-key")


def test_include_must_name_files(tmp_path):
    d = errors(write(tmp_path / "a.yaml", "include: [{x: 1}]\n"))
    assert "path" in at(d, "a.yaml", 1, 11, "scene").message


# ---- scene objects the problem does not declare ---------------------------------------------
def test_undeclared_scene_objects_are_static_obstacles():
    """lab1 declares b1, b2 (and the table constant); b3, b4, b5 and the pads of lab.yaml stay
    in the scene as static obstacles, with the static table."""
    p = load_problem(ROOT / "examples/lab/lab1.pntc")
    assert p.undeclared_scene_objects == ("pad_c", "pad_l", "b3", "b4", "b5")
    assert list(p.static_obstacles) == ["table", "pad_c", "pad_l", "b3", "b4", "b5"]
    assert p.static_obstacles["b3"] is p.scene.objects["b3"]
    assert not p.scene.objects["b3"].static        # movable in the scene file, fixed here
    p5 = load_problem(ROOT / "examples/lab/lab5.pntc")
    assert "b3" not in p5.static_obstacles and "o1" not in p5.static_obstacles
    assert set(p5.static_obstacles) == {"table", "pad_c", "pad_l"}


def test_shapeless_frames_are_no_obstacles():
    p = load_problem(ROOT / "examples/planar/p1_one_block.pntc")
    for name, o in p.scene.objects.items():
        assert (name in p.static_obstacles) == (o.shape.kind != "none" and
                                                (o.static or name not in p.objects))
