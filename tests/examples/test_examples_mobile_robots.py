"""The mobile domain is robot-agnostic (issue 22, deliverable 4): its templates name links by
role (`link(r, "hand")`) and each scene robot's `links:` says which link plays the role, so the
same domain serves the mobile Panda (sorting_setting.yaml) and a PR2 (sorting_pr2_setting.yaml,
example-robot-data `pr2`). Fast: `gnpp check` and the factory's grounding, no solve (the PR2
problems are solved and verified in test_examples_mobile.py, slow)."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import pytest

from gnppdsl.ir.resolve import check_files

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"
PR2_PROBLEMS = ("sort_random_pr2.pntc", "pick_place3_pr2.pntc")


@pytest.mark.parametrize("name", PR2_PROBLEMS)
def test_pr2_problems_check(name):
    rep = check_files([str(MOBILE / name)])
    assert rep.ok, rep.render()


def _ground_links(problem: str | Path, fn: str = "link", arg: int = 1) -> set[str]:
    """The link names of the ground factors of pick(red1) then drop(red1) (`link(r, NAME)`
    as the factory resolved it; `fn="fk", arg=2`: the frames of `fk(r, q, NAME)`)."""
    from gnppdsl import ir
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.ir.expr import Call, Str
    from gnppdsl.solve.compiled import compile_problem

    c = compile_problem(ir.load_problem(MOBILE / problem if isinstance(problem, str) else problem))
    states = plan_states(c.task, parse_plan(c.task, "pick(red1, mm, center); drop(red1, mm, red_tray)"))
    names: set[str] = set()

    def walk(x):
        if isinstance(x, Call) and x.fn == fn and len(x.args) > arg:
            assert isinstance(x.args[arg], Str), x
            names.add(x.args[arg].value)
        if isinstance(x, (tuple, list)):
            for a in x:
                walk(a)
        elif hasattr(x, "__dataclass_fields__"):
            for f in x.__dataclass_fields__:
                if f != "span":
                    walk(getattr(x, f))
    for f in c.factory.factors(states):
        walk(f.body)
    return names


SIDE = ("red_table", "blue_table", "red_tray", "blue_tray")


def test_both_settings_have_the_same_furniture():
    """sorting_pr2_setting.yaml repeats sorting_setting.yaml's furniture (the test families of
    the two robots are the same problems); only the robot differs, and the side tables with
    their trays stand 0.2 m further out (the PR2's base needs the wider gap, below)."""
    import yaml

    a, b = (yaml.safe_load((MOBILE / f).read_text()) for f in ("sorting_setting.yaml", "sorting_pr2_setting.yaml"))
    assert a.pop("robots")["mm"]["model"] == "panda" and b.pop("robots")["mm"]["model"] == "pr2"
    for name in SIDE:
        xa, xb = a["objects"][name]["pose"]["xyz"][0], b["objects"][name]["pose"]["xyz"][0]
        assert abs(xb - xa - math.copysign(0.2, xa)) < 1e-9, name
        a["objects"][name]["pose"]["xyz"][0] = xb
    assert a == b


@pytest.mark.parametrize("setting", ["sorting_setting.yaml", "sorting_pr2_setting.yaml"])
def test_the_robot_drives_between_the_central_and_each_side_table(setting):
    """The near and far halves of the room are joined only by the gaps between the central table
    and the side tables; the robot (home arm, base centred in the gap) must pass there facing
    along the gap and across it with room to spare: 4 cm beyond its base clearance from every
    static object. The PR2 in the Panda's room (0.75 m gaps) does not: its folded left arm is
    inside the central table facing along the gap, 2.5 cm from the side table facing across it,
    and sort_random_pr2 instance 1 (an object reachable only from the far side) failed."""
    from gnppdsl.ir.scene import load_scene_file
    from gnppdsl.reach.graph import ReachabilityGraph
    from gnppdsl.reach.settings import ReachSettings

    scene = load_scene_file(MOBILE / setting)
    spec = scene.robots["mm"]
    graph = ReachabilityGraph.from_scene(scene, ReachSettings(robot="mm", self_collision=False), build=False)
    centre = scene.objects["center"]
    for side in ("red_table", "blue_table"):
        t = scene.objects[side]
        inner = abs(t.pose[0]) - t.shape.size[0] / 2          # the side table's edge facing the centre
        edge = centre.shape.size[0] / 2
        x = math.copysign((inner + edge) / 2, t.pose[0])
        for theta in (0.0, math.pi / 2):
            q = graph.home.copy()
            q[0], q[1], q[2] = x, 0.0, theta
            d, pair = graph.checker.min_distance(q)
            assert d >= spec.attributes["base_clearance"] + 0.04, (setting, side, theta, d, pair)


@pytest.mark.parametrize("problem, links", [
    ("sort_random_pr2.pntc", {"base_link", "r_forearm_link", "r_wrist_flex_link", "r_gripper_palm_link"}),
    ("sort_random.pntc", {"panda_link0", "panda_link5", "panda_link6", "panda_hand"}),
])
def test_roles_ground_to_each_robots_links(problem, links):
    """The factory grounds `link(r, "forearm")` to the scene robot's link (the PR2's
    r_forearm_link, the Panda's panda_link5): the factors name exactly the robot's four links,
    no role and no other robot's link."""
    assert _ground_links(problem) == links


def _copy(tmp_path: Path) -> Path:
    for p in MOBILE.iterdir():
        if p.suffix in (".pntc", ".yaml"):
            shutil.copy(p, tmp_path / p.name)
    return tmp_path


def _at(diags, file: str, line: int, col: int, kind: str):
    hits = [d for d in diags if Path(d.span.file).name == file and d.span.line == line
            and d.span.column == col and d.kind == kind]
    assert hits, "\n".join(f"{d.span}: {d.kind}: {d.message}" for d in diags)
    return hits[0]


def test_unknown_role_in_the_domain_is_located(tmp_path):
    """A misspelt role in a template is an error at its string, with the role as the hint;
    before roles were checked, `gnpp check` passed it and the solve failed in the geometry."""
    d = _copy(tmp_path)
    dom = (d / "domain.pntc").read_text()
    assert dom.count('link(r, "wrist")') == 1
    (d / "domain.pntc").write_text(dom.replace('link(r, "wrist")', 'link(r, "wirst")'))
    line = next(i for i, t in enumerate((d / "domain.pntc").read_text().splitlines(), 1) if '"wirst"' in t)
    col = (d / "domain.pntc").read_text().splitlines()[line - 1].index('"wirst"') + 1
    for problem in ("sort_random_pr2.pntc", "sort2.pntc"):
        rep = check_files([str(d / problem)])
        assert not rep.ok
        x = _at(rep.reporter.diagnostics, "domain.pntc", line, col, "unknown-link")
        assert "wirst" in x.message and "wrist" in (x.hint or "")


def test_a_panda_link_in_the_pr2_scene_is_refused(tmp_path):
    """A literal link of the other robot: fine for the Panda's scene, an error for the PR2's."""
    d = _copy(tmp_path)
    dom = (d / "domain.pntc").read_text()
    (d / "domain.pntc").write_text(dom.replace('link(r, "hand")', 'link(r, "panda_hand")'))
    assert check_files([str(d / "sort2.pntc")]).ok
    rep = check_files([str(d / "sort_random_pr2.pntc")])
    assert not rep.ok
    assert any(x.kind == "unknown-link" and "panda_hand" in x.message for x in rep.reporter.diagnostics)


def test_unknown_link_in_the_scene_is_located(tmp_path):
    """`links:` naming a link the URDF lacks (or one without collision geometry) is an error at
    the value, with the closest link names."""
    d = _copy(tmp_path)
    s = (d / "sorting_pr2_setting.yaml").read_text()
    assert s.count("forearm: r_forearm_link") == 1
    s = s.replace("forearm: r_forearm_link", "forearm: r_forarm_link").replace(
        "hand: r_gripper_palm_link", "hand: r_gripper_tool_frame")
    (d / "sorting_pr2_setting.yaml").write_text(s)
    line = next(i for i, t in enumerate(s.splitlines(), 1) if "r_forarm_link" in t)
    text = s.splitlines()[line - 1]
    rep = check_files([str(d / "sort_random_pr2.pntc")])
    assert not rep.ok
    x = _at(rep.reporter.diagnostics, "sorting_pr2_setting.yaml", line, text.index("r_forarm_link") + 1, "unknown-link")
    assert "'r_forearm_link'" in (x.hint or "")
    y = _at(rep.reporter.diagnostics, "sorting_pr2_setting.yaml", line, text.index("r_gripper_tool_frame") + 1,
            "unknown-link")
    assert "collision geometry" in y.message          # a frame, not a link with a shape


def test_unknown_locked_joint_is_located(tmp_path):
    """`locked:` naming a joint the URDF lacks, or one that does not move (fixed), is an error
    of `gnpp check` at the key, with the closest joint names; until 27 Nov it passed the check
    and `gnpp solve` ended with an unlocated "cannot lock unknown joint"."""
    d = _copy(tmp_path)
    s = (d / "sorting_pr2_setting.yaml").read_text()
    assert s.count("l_wrist_roll_joint: -0.09}") == 1
    s = s.replace("l_wrist_roll_joint: -0.09}", "l_wrist_roll_joint: -0.09, l_wrist_rol_joint: 1.0, base_footprint_joint: 0}")
    (d / "sorting_pr2_setting.yaml").write_text(s)
    line = next(i for i, t in enumerate(s.splitlines(), 1) if "l_wrist_rol_joint" in t)
    text = s.splitlines()[line - 1]
    rep = check_files([str(d / "sort_random_pr2.pntc")])
    assert not rep.ok
    x = _at(rep.reporter.diagnostics, "sorting_pr2_setting.yaml", line, text.index("l_wrist_rol_joint") + 1,
            "unknown-joint")
    assert "'l_wrist_roll_joint'" in (x.hint or "")
    _at(rep.reporter.diagnostics, "sorting_pr2_setting.yaml", line, text.index("base_footprint_joint") + 1,
        "unknown-joint")
    assert len(rep.reporter.errors) == 2


def test_a_scene_attribute_of_the_wrong_shape_is_a_located_error(tmp_path):
    """The domain declares `scene base_clearance(r: object) : R`; a list in the scene was used
    as a vector (rows of another length, a solve that sometimes ended solved): now the factor
    that reads it is refused at the call, naming the value and the declared space."""
    from gnppdsl import ir
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.errors import UserError
    from gnppdsl.solve.compiled import compile_problem

    d = _copy(tmp_path)
    s = (d / "sorting_setting.yaml").read_text()
    assert s.count("base_clearance: 0.15") == 1
    (d / "sorting_setting.yaml").write_text(s.replace("base_clearance: 0.15", "base_clearance: [0.1, 0.2]"))
    c = compile_problem(ir.load_problem(d / "sort2.pntc"))
    states = plan_states(c.task, parse_plan(c.task, "pick(red1, mm, center); drop(red1, mm, red_tray)"))
    with pytest.raises(UserError) as e:
        c.factory.factors(states)
    text = str(e.value)
    assert "domain.pntc:" in text and "base_clearance of 'mm' is [0.1, 0.2]" in text and "declares it R" in text


def test_a_continuous_joint_is_locked_at_its_angle():
    """The PR2's left wrist roll (continuous: cos, sin in pinocchio) locked at -0.09 rad: the
    reduced model places its link as the full model does at that angle."""
    import numpy as np
    import pinocchio as pin

    from gnppdsl.geometry.robots import load_robot
    from gnppdsl.ir.scene import load_scene_file

    spec = load_scene_file(MOBILE / "sorting_random_pr2.yaml").robots["mm"]
    r = load_robot(spec)
    assert r.nc == 10 and [c.name for c in r.coords][0] == "root_joint"
    full = pin.buildModelFromUrdf(r.urdf, pin.JointModelPlanar())
    q = pin.neutral(full)
    for j, v in spec.locked.items():
        jm = full.joints[full.getJointId(j)]
        q[jm.idx_q:jm.idx_q + jm.nq] = (math.cos(v), math.sin(v)) if jm.nq == 2 else (v,)
    df, dr = full.createData(), r.model.createData()
    pin.framesForwardKinematics(full, df, q)
    pin.framesForwardKinematics(r.model, dr, r.to_pin_q(np.zeros(r.nc)))
    for ln in ("l_wrist_roll_link", "l_gripper_l_finger_tip_link", "r_gripper_l_finger_tip_link"):
        a, b = df.oMf[full.getFrameId(ln)], dr.oMf[r.model.getFrameId(ln)]
        assert np.allclose(a.homogeneous, b.homogeneous, atol=1e-9), ln
    assert abs(spec.locked["l_wrist_roll_joint"] + 0.09) < 1e-12


def test_links_of_a_robot_whose_urdf_is_a_fifo_are_not_read(tmp_path):
    """`links:` are checked against the robot's URDF text (`urdf_collision_links`), read
    through `gnppdsl.inputs` like every file a user names: a URDF that is a FIFO is refused,
    never opened for reading (that blocks until a writer appears; ElementTree's own parse did).
    In a subprocess with a timeout, so a regression fails instead of hanging the suite; and
    `gnpp check` of a scene naming it ends located, exit 2."""
    import os
    import subprocess
    import sys

    d = tmp_path / "mobile"
    shutil.copytree(MOBILE, d)
    os.mkfifo(d / "pipe.urdf")
    env = {**os.environ, "PYTHONPATH": str(MOBILE.parents[1])}
    code = f"from gnppdsl.ir.scene import urdf_collision_links; print(urdf_collision_links(None, {str(d / 'pipe.urdf')!r}))"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60, env=env)
    assert out.returncode == 0 and out.stdout.strip() == "None", out.stdout + out.stderr
    setting = d / "sorting_setting.yaml"
    text = setting.read_text()
    assert "    model: panda\n" in text
    setting.write_text(text.replace("    model: panda\n", "    urdf: pipe.urdf\n", 1))
    out = subprocess.run([sys.executable, "-m", "gnppdsl.cli.main", "check", str(d / "sort2.pntc")],
                         capture_output=True, text=True, timeout=120, env=env, cwd=MOBILE.parents[1])
    assert out.returncode == 2, out.stdout + out.stderr
    assert "Traceback" not in out.stderr and "FIFO" in out.stdout + out.stderr, out.stdout + out.stderr


def _scene_robots():
    """Every URDF robot of every bundled scene (Lab, Field, Workshop, mobile, scalability)."""
    from gnppdsl.ir.scene import load_scene_file

    ex = MOBILE.parent
    out = {}
    for y in sorted(ex.glob("*/*.yaml")):
        if y.name == "expected.yaml":
            continue
        try:
            sc = load_scene_file(y)
        except Exception:          # not a scene (a settings file): nothing to count
            continue
        for r in sc.robots.values():
            if r.kind == "urdf":
                out[(r.model, r.urdf, r.attributes.get("base_joint"), tuple(sorted(r.locked.items())))] = r
    return list(out.values())


def test_configuration_size_from_the_urdf_text_equals_pinocchios_reduced_model():
    """`configuration_size` counts a robot's coordinates from the URDF's XML (no pinocchio, for
    `gnpp check`); the oracle is the geometry layer's pinocchio model after locking. Over every
    distinct robot of the bundled scenes (Panda fixed and on a planar base, the PR2 with 23
    locked joints and two continuous ones), plus the PR2 with its left arm moving too."""
    import dataclasses

    from gnppdsl.geometry.robots import load_robot
    from gnppdsl.ir.scene import configuration_size

    robots = _scene_robots()
    assert {r.model for r in robots} >= {"panda", "pr2"} and len(robots) >= 3
    pr2 = next(r for r in robots if r.model == "pr2")
    arm_free = {k: v for k, v in pr2.locked.items() if not k.startswith("l_") or "gripper" in k}
    robots.append(dataclasses.replace(pr2, locked=arm_free, home=()))
    for r in robots:
        size = configuration_size(r.model, r.urdf, r.attributes.get("base_joint"), r.locked)
        assert size is not None and size[0] == load_robot(r).nc, (r.model, r.locked, size)
    assert size[0] == 17                              # 3 base + 7 right arm + 7 left arm


def test_a_home_of_the_wrong_length_is_a_located_error(tmp_path):
    """A home one value short (the Panda on a planar base: 3 + 7 numbers) or long (the PR2) is an
    error of `gnpp check` at the value, saying how many the configuration has; before, the check
    passed and the solve stopped with an unlocated "constraint sides have lengths 10 and 9"."""
    d = _copy(tmp_path)
    for scene, old, new, problem in (
            ("sorting_setting.yaml", "home: [0, -1.1, 1.5708, 0, -0.5, 0, -2.0, 0, 1.6, 0.8]",
             "home: [0, -1.1, 1.5708, 0, -0.5, 0, -2.0, 0, 1.6]", "sort2.pntc"),
            ("sorting_pr2_setting.yaml", "home: [0, -1.15, 1.5708, -0.4, 0.2, -0.2, -1.7, 0, -0.9, 0]",
             "home: [0, -1.15, 1.5708, -0.4, 0.2, -0.2, -1.7, 0, -0.9, 0, 0]", "pick_place3_pr2.pntc")):
        s = (d / scene).read_text()
        assert s.count(old) == 1
        (d / scene).write_text(s.replace(old, new))
        line = next(i for i, t in enumerate(s.splitlines(), 1) if old in t)
        rep = check_files([str(d / problem)])
        assert not rep.ok
        x = _at(rep.reporter.diagnostics, scene, line, s.splitlines()[line - 1].index("[") + 1, "scene")
        assert "its configuration has 10 (planar base 3, 7 joints that move" in x.message, x.message
        assert len(rep.reporter.errors) == 1
        (d / scene).write_text(s)
        assert check_files([str(d / problem)]).ok


def test_a_joint_named_only_in_a_transmission_cannot_be_locked(tmp_path):
    """The PR2's URDF names its caster wheel joints in <transmission> blocks only; pinocchio's
    model has no such joint, so locking one is an unknown-joint error (it passed the check and
    failed the solve while the check read every <joint> element of the file)."""
    d = _copy(tmp_path)
    s = (d / "sorting_pr2_setting.yaml").read_text()
    s = s.replace("l_wrist_roll_joint: -0.09}", "l_wrist_roll_joint: -0.09, fl_caster_rotation_joint: 0}")
    (d / "sorting_pr2_setting.yaml").write_text(s)
    rep = check_files([str(d / "sort_random_pr2.pntc")])
    assert [e.kind for e in rep.reporter.errors] == ["unknown-joint"]
    assert "fl_caster_rotation_joint" in rep.reporter.errors[0].message


def _with_wrist_height(d: Path, role: str) -> None:
    """The mobile domain plus a template on `fk(r, q(r), ROLE)` (the wrist above the floor)."""
    dom = (d / "domain.pntc").read_text()
    old = "template base_clear(r: object, t: object) tags collision {\n"
    assert dom.count(old) == 1
    dom = dom.replace(old, old + f'  pos(fk(r, q(r), "{role}"))[2] >= 0.0\n')
    (d / "domain.pntc").write_text(dom)


@pytest.mark.parametrize("problem, links, ee", [
    ("sort_random_pr2.pntc", {"base_link", "r_forearm_link", "r_wrist_flex_link", "r_gripper_palm_link"},
     "r_gripper_tool_frame"),
    ("sort_random.pntc", {"panda_link0", "panda_link5", "panda_link6", "panda_hand"}, "panda_hand_tcp"),
])
def test_fk_takes_a_role_as_link_does(tmp_path, problem, links, ee):
    """`fk(r, q, "wrist")` grounds to the scene robot's link for the role, as `link(r, "wrist")`
    does (before, the role "wrist" went to pinocchio as a frame name and the solve failed): the
    ground fk frames are the robot's links (of link(), posed by fk) and its `ee` (the two-argument
    fk), and no role."""
    d = _copy(tmp_path)
    _with_wrist_height(d, "wrist")
    assert check_files([str(d / problem)]).ok
    assert _ground_links(d / problem, "fk", 2) == links | {ee}


def test_an_unknown_fk_frame_is_located(tmp_path):
    """A misspelt frame or role in `fk(r, q, NAME)` is an error of `gnpp check` at the string;
    a URDF joint name is a frame (pinocchio makes one per joint) and passes."""
    d = _copy(tmp_path)
    _with_wrist_height(d, "wirst")
    text = (d / "domain.pntc").read_text().splitlines()
    line = next(i for i, t in enumerate(text, 1) if '"wirst"' in t)
    rep = check_files([str(d / "sort_random_pr2.pntc")])
    x = _at(rep.reporter.diagnostics, "domain.pntc", line, text[line - 1].index('"wirst"') + 1, "unknown-link")
    assert "frame 'wirst'" in x.message and "'wrist'" in (x.hint or "")
    d2 = tmp_path / "joint"
    d2.mkdir()
    _copy(d2)
    _with_wrist_height(d2, "r_wrist_flex_joint")
    assert check_files([str(d2 / "sort_random_pr2.pntc")]).ok


def test_a_missing_scene_attribute_is_found_by_check(tmp_path):
    """`base_clearance(r)` read by rule arm_table (`always`, every robot) of a robot whose scene
    entry lacks it: an error of `gnpp check` at the read, naming the entry; before, the check
    passed and the solve stopped at the first grounding, after loading and planning."""
    d = _copy(tmp_path)
    s = (d / "sorting_setting.yaml").read_text()
    assert s.count("    base_clearance: 0.15\n") == 1
    (d / "sorting_setting.yaml").write_text(s.replace("    base_clearance: 0.15\n", ""))
    text = (d / "domain.pntc").read_text().splitlines()
    line = next(i for i, t in enumerate(text, 1) if "sdist(link(r, \"base\"), t) >= base_clearance(r)" in t)
    rep = check_files([str(d / "sort2.pntc")])
    x = _at(rep.reporter.diagnostics, "domain.pntc", line, text[line - 1].index("base_clearance") + 1,
            "scene-missing")
    assert x.severity == "error" and "'mm'" in x.message and "'base_clearance'" in x.message
    assert check_files([str(MOBILE / "sort2.pntc")]).ok


def test_a_scene_attribute_a_conditional_rule_reads_is_a_warning(tmp_path):
    """planar.inside reads `half_extent(r)` for rule placed (`parent(o) = r`): a region without it
    is a warning (the rule may never hold for it), a gripper without `reach_min` (rule reach,
    `always`) an error."""
    planar = MOBILE.parent / "planar"
    for f in ("domain.pntc", "p1_one_block.pntc", "p1_one_block.yaml"):
        shutil.copy(planar / f, tmp_path / f)
    y = (tmp_path / "p1_one_block.yaml").read_text()
    assert y.count(", half_extent: [0.15, 0.15]") == 1
    (tmp_path / "p1_one_block.yaml").write_text(y.replace(", half_extent: [0.15, 0.15]", ""))
    rep = check_files([str(tmp_path / "p1_one_block.pntc")])
    assert rep.ok
    [w] = [d for d in rep.reporter.diagnostics if d.kind == "scene-missing"]
    assert w.severity == "warning" and "'r1'" in w.message and "'half_extent'" in w.message
    (tmp_path / "p1_one_block.yaml").write_text(y.replace(", reach_min: [-1, -1]", ""))
    rep = check_files([str(tmp_path / "p1_one_block.pntc")])
    assert [(d.severity, d.kind) for d in rep.reporter.errors] == [("error", "scene-missing")]
    assert "'reach_min'" in rep.reporter.errors[0].message
