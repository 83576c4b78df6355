"""Scene YAML loading: poses resolved to the world, shapes, colours, and located errors.

Rotations are checked against rotation matrices built independently here (numpy), not with the
loader's quaternion code.
"""
from __future__ import annotations

import math
import textwrap
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.ir.scene import load_scene, load_scene_file
from gnppdsl.lang.diagnostics import DiagnosticError, Reporter

ROOT = Path(__file__).resolve().parents[2]


def write(tmp_path, text: str, name: str = "s.yaml") -> Path:
    p = tmp_path / name
    p.write_text(textwrap.dedent(text))
    return p


def errors(tmp_path, text: str):
    r = Reporter()
    assert load_scene(write(tmp_path, text), r) is None
    return r.diagnostics


def at(diags, line, col, kind=None):
    hits = [d for d in diags if (d.span.line, d.span.column) == (line, col) and (kind is None or d.kind == kind)]
    assert hits, [f"{d.span} {d.kind} {d.message}" for d in diags]
    return hits[0]


def rot_rpy(r, p, y):
    rx = np.array([[1, 0, 0], [0, math.cos(r), -math.sin(r)], [0, math.sin(r), math.cos(r)]])
    ry = np.array([[math.cos(p), 0, math.sin(p)], [0, 1, 0], [-math.sin(p), 0, math.cos(p)]])
    rz = np.array([[math.cos(y), -math.sin(y), 0], [math.sin(y), math.cos(y), 0], [0, 0, 1]])
    return rz @ ry @ rx


def rot_quat(q):
    x, y, z, w = q
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def test_full_3d_scene(tmp_path):
    (tmp_path / "m.stl").write_text("solid x\nendsolid x\n")
    s = load_scene_file(write(tmp_path, """\
        name: lab
        workspace: [[-1, -1, 0], [1, 1, 1.5]]
        robots:
          left_arm: {model: panda, base: {xyz: [-0.4, -0.3, 0.6], rpy: [0, 0, 1.5708]}, ee: panda_hand_tcp,
                     locked: {panda_finger_joint1: 0.04}, home: [0, -0.5, 0, -2, 0, 1.6, 0.8, 0.04], max_step: 0.3}
        objects:
          table: {shape: box, size: [2.3, 1.24, 0.05], pose: {xyz: [0, 0, 0.575]}, static: true, color: brown}
          b1: {shape: box, size: [0.06, 0.15, 0.09], pose: {xyz: [0.1, 0.2, 0.07], rpy: [0.3, -0.2, 1.0]},
               color: [1, 0, 0], parent: table}
          c: {shape: {cylinder: [0.02, 0.1]}, pose: [0.5, 0, 0.7, 0, 0, 0, 2]}
          mug: {shape: mesh, file: m.stl, scale: [2, 2, 2], pose: [0, 0, 1]}
          f: {pose: {xyz: [1, 2, 3], quat: [0, 0, 1, 1]}, grasp_box: [0.1, 0.2, 0.3]}
        ignore_collisions: [[left_arm, table]]
        """))
    assert s.name == "lab" and s.dimension == 3 and s.workspace == ((-1, -1, 0), (1, 1, 1.5))
    arm = s.robots["left_arm"]
    assert arm.kind == "urdf" and arm.model == "panda" and arm.ee == "panda_hand_tcp"
    assert arm.locked == {"panda_finger_joint1": 0.04} and arm.home == (0, -0.5, 0, -2, 0, 1.6, 0.8, 0.04)
    assert arm.attributes == {"max_step": 0.3}
    np.testing.assert_allclose(rot_quat(arm.base[3:]), rot_rpy(0, 0, 1.5708), atol=1e-9)
    table, b1 = s.objects["table"], s.objects["b1"]
    assert table.static and table.shape.kind == "box" and table.shape.size == (2.3, 1.24, 0.05)
    assert table.color[:3] == (0.55, 0.35, 0.2) and b1.color == (1, 0, 0, 1.0)
    # b1 is relative to the table: world = table * rel
    np.testing.assert_allclose(b1.pose[:3], [0.1, 0.2, 0.575 + 0.07], atol=1e-12)
    np.testing.assert_allclose(rot_quat(b1.pose[3:]), rot_rpy(0.3, -0.2, 1.0), atol=1e-9)
    assert b1.parent == "table"
    c = s.objects["c"]
    assert c.shape.size == (0.02, 0.1)
    np.testing.assert_allclose(c.pose[3:], [0, 0, 0, 1])           # normalised quaternion
    mug = s.objects["mug"]
    assert mug.shape.kind == "mesh" and mug.shape.mesh_file == str((tmp_path / "m.stl").resolve())
    assert mug.shape.size == (2, 2, 2) and mug.pose == (0, 0, 1, 0, 0, 0, 1)
    f = s.objects["f"]
    np.testing.assert_allclose(rot_quat(f.pose[3:]), rot_rpy(0, 0, math.pi / 2), atol=1e-12)
    assert f.shape.kind == "none" and f.attributes == {"grasp_box": (0.1, 0.2, 0.3)}
    assert s.ignore_collisions == {frozenset({"left_arm", "table"})}
    assert s.entity("left_arm") is arm and s.entity("table") is table


def test_parent_chain_rotation_composes(tmp_path):
    s = load_scene_file(write(tmp_path, """\
        objects:
          a: {pose: {xyz: [1, 0, 0], rpy: [0, 0, 1.5707963267948966]}}
          b: {pose: {xyz: [1, 0, 0]}, parent: a}
          c: {pose: {xyz: [0, 1, 0], rpy: [0.5, 0, 0]}, parent: b}
        """))
    # independent: homogeneous matrices
    def H(xyz, R):
        m = np.eye(4)
        m[:3, :3] = R
        m[:3, 3] = xyz
        return m
    A = H([1, 0, 0], rot_rpy(0, 0, math.pi / 2))
    Bw = A @ H([1, 0, 0], np.eye(3))
    Cw = Bw @ H([0, 1, 0], rot_rpy(0.5, 0, 0))
    np.testing.assert_allclose(s.objects["b"].pose[:3], Bw[:3, 3], atol=1e-12)
    np.testing.assert_allclose(s.objects["c"].pose[:3], Cw[:3, 3], atol=1e-12)
    np.testing.assert_allclose(rot_quat(s.objects["c"].pose[3:]), Cw[:3, :3], atol=1e-12)


def test_planar_scene(tmp_path):
    s = load_scene_file(write(tmp_path, """\
        dimension: 2
        workspace: [[-1, -1], [1, 1]]
        robots:
          g: {kind: planar, home: [0.1, 0.2, 0.3], shape: {circle: 0.03}, reach_min: [-1, -1]}
        objects:
          s1: {pose: [0.5, 0.0, 1.0]}
          b1: {shape: {circle: 0.05}, pose: [0.1, 0, 0.5], parent: s1, radius: 0.05}
          r: {shape: box, size: [0.2, 0.4], pose: [0, 0, 0]}
          d: {shape: circle, radius: 0.07, pose: [0, 0, 0]}
        """))
    g = s.robots["g"]
    assert g.kind == "planar" and g.home == (0.1, 0.2, 0.3) and g.shape.size == (0.03,)
    assert g.attributes == {"reach_min": (-1.0, -1.0)}
    b1 = s.objects["b1"]
    # SE2 composition, independently
    x = 0.5 + math.cos(1.0) * 0.1
    y = 0.0 + math.sin(1.0) * 0.1
    np.testing.assert_allclose(b1.pose2, (x, y, 1.5), atol=1e-12)
    # the SE3 pose is valid: z = 0, unit quaternion about z with the same angle
    assert b1.pose[2] == 0.0 and b1.pose[3] == 0.0 and b1.pose[4] == 0.0
    assert abs(math.hypot(b1.pose[5], b1.pose[6]) - 1) < 1e-12
    np.testing.assert_allclose(rot_quat(b1.pose[3:]), rot_rpy(0, 0, 1.5), atol=1e-12)
    assert b1.attributes == {"radius": 0.05}
    assert s.objects["r"].shape.size == (0.2, 0.4, 0.1)
    assert s.objects["d"].shape == type(s.objects["d"].shape)("circle", (0.07,))


def test_example_scenes_load():
    for p in sorted((ROOT / "examples").glob("*/*.yaml")):
        if p.name == "expected.yaml":
            continue
        s = load_scene_file(p)
        assert s.objects or s.robots


# ---------------------------------------------------------------- errors with positions
def test_unknown_top_level_key(tmp_path):
    x = at(errors(tmp_path, "dimention: 2\nobjects: {}\n"), 1, 1, "unknown-key")
    assert x.hint == "did you mean 'dimension'?"


def test_unknown_pose_key_and_bad_lengths(tmp_path):
    d = errors(tmp_path, """\
        objects:
          a: {pose: {xzy: [1, 2, 3]}}
          b: {pose: [1, 2]}
          c: {shape: box, size: [1, 2, -3]}
        """)
    at(d, 2, 14, "unknown-key")
    at(d, 3, 13, "scene")
    at(d, 4, 25, "scene")


def test_bad_colour_and_shape(tmp_path):
    d = errors(tmp_path, """\
        objects:
          a: {shape: bx, size: [1, 1, 1]}
          b: {color: rde}
          c: {color: [2, 0, 0]}
        """)
    assert at(d, 2, 14).hint == "did you mean 'box'?"
    assert at(d, 3, 14).hint == "did you mean 'red'?"
    at(d, 4, 14)


def test_unknown_parent_and_cycle(tmp_path):
    d = errors(tmp_path, """\
        objects:
          a: {pose: [0, 0, 0], parent: tabel}
          table: {pose: [0, 0, 0]}
          x: {parent: y}
          y: {parent: x}
        """)
    assert at(d, 2, 32, "unknown-name").hint == "did you mean 'table'?"
    assert any(x.kind == "cycle" for x in d)


def test_missing_files_at_their_keys(tmp_path):
    d = errors(tmp_path, """\
        robots:
          r: {urdf: robots/nope.urdf}
        objects:
          m: {shape: mesh, file: meshes/nope.stl}
        """)
    at(d, 2, 13, "missing-file")
    at(d, 4, 26, "missing-file")


def test_robot_needs_model_or_urdf(tmp_path):
    at(errors(tmp_path, "robots:\n  r: {ee: tool0}\n"), 2, 3, "scene")


def test_planar_robot_rejects_arm_keys(tmp_path):
    at(errors(tmp_path, "dimension: 2\nrobots:\n  g: {kind: planar, model: panda}\n"), 3, 21, "scene")


def test_bad_base_joint(tmp_path):
    assert at(errors(tmp_path, "robots:\n  r: {model: panda, base_joint: planr}\n"), 2, 33).hint == \
        "did you mean 'planar'?"


def test_duplicate_key(tmp_path):
    at(errors(tmp_path, "objects:\n  a: {pose: [0, 0, 0], pose: [1, 1, 1]}\n"), 2, 24, "duplicate")


def test_non_numeric_extra_key(tmp_path):
    at(errors(tmp_path, "objects:\n  a: {pose: [0, 0, 0], colour: red}\n"), 2, 24, "unknown-key")


def test_ignore_collisions_names(tmp_path):
    at(errors(tmp_path, "objects:\n  a: {}\nignore_collisions: [[a, b]]\n"), 3, 25, "unknown-name")


def test_workspace_dimension(tmp_path):
    at(errors(tmp_path, "dimension: 2\nworkspace: [[0, 0, 0], [1, 1, 1]]\n"), 2, 13)


def test_broken_yaml(tmp_path):
    d = errors(tmp_path, "objects:\n  a: {pose: [0, 0, 0]\n  b: 1\n")
    assert (d[0].kind, d[0].span.line, d[0].span.column) == ("yaml", 3, 3)
    assert "expected ',' or '}'" in d[0].message


def test_not_a_mapping_and_empty(tmp_path):
    at(errors(tmp_path, "- a\n- b\n"), 1, 1)
    assert errors(tmp_path, "# nothing\n")[0].message == "the scene file is empty"


def test_load_scene_file_raises(tmp_path):
    with pytest.raises(DiagnosticError) as exc:
        load_scene_file(write(tmp_path, "objects:\n  a: {pose: [0]}\n"))
    assert "s.yaml:2:13: error:" in str(exc.value)


def test_missing_scene_file(tmp_path):
    r = Reporter()
    assert load_scene(tmp_path / "none.yaml", r) is None
    assert r.diagnostics[0].kind == "missing-file"


def test_held_pose_of_a_robot(tmp_path):
    """`held_pose`: a pose (3-D: {xyz, rpy | quat} or a list; planar: [x, y, theta]), absent ->
    None; a malformed one is a located error at its value."""
    s = load_scene_file(write(tmp_path, """\
        robots:
          a: {model: panda, held_pose: {xyz: [0, 0, 0.01], rpy: [0, 0, 1.0]}}
          b: {model: panda}
        objects: {}
        """))
    held = s.robots["a"].held_pose
    np.testing.assert_allclose(held[:3], [0, 0, 0.01])
    np.testing.assert_allclose(rot_quat(held[3:]), rot_rpy(0, 0, 1.0), atol=1e-12)
    assert s.robots["b"].held_pose is None and "held_pose" not in s.robots["a"].attributes
    p = load_scene_file(write(tmp_path, """\
        dimension: 2
        robots:
          g: {kind: planar, held_pose: [0.01, 0, 0.5]}
        objects: {}
        """, "p.yaml"))
    assert p.robots["g"].held_pose == (0.01, 0.0, 0.5)
    d = errors(tmp_path, """\
        robots:
          a: {model: panda, held_pose: {xyz: [0, 0], rpy: [0, 0, 1]}}
        objects: {}
        """)
    at(d, 2, 38, "scene")
