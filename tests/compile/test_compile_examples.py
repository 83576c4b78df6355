"""End to end on the shipped examples: .pntc -> SAS+ -> Fast Downward finds the expected
optimal plan length n0 (examples/*/expected.yaml); the graph-NLP of FD's plan is well formed.
(The PDDL and ASP that `gnpp compile --emit` writes are solved by FD's translator and by clingo
in test_compile_emit_solved.py.)"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from fd_oracle import run_fd_on_sas, translate_pddl
from sas_semantics import run_plan

ROOT = Path(__file__).resolve().parents[2]


def _cases():
    out = []
    for sub in ("planar", "lab", "mobile", "field", "workshop"):
        exp = ROOT / "examples" / sub / "expected.yaml"
        if not exp.is_file():
            continue
        data = yaml.safe_load(exp.read_text())
        for name, info in data["problems"].items():
            out.append(pytest.param(ROOT / "examples" / sub / info["file"], info["n0"], id=f"{sub}-{name}"))
    return out


def _load(path):
    from gnppdsl.ir import load_problem
    return load_problem(str(path))


@pytest.mark.parametrize("path,n0", _cases())
def test_sas_solved_by_fd_with_expected_length(path, n0):
    from gnppdsl.compile.sas_writer import write_sas
    from gnppdsl.compile.task import build_task

    problem = _load(path)
    task = build_task(problem)
    res = run_fd_on_sas(write_sas(task))
    assert res.solved
    assert all(op.cost == 1 for op in task.operators)
    assert res.length == res.cost == n0
    assert task.goal.holds_in(run_plan(task, res.plan)[-1])


@pytest.mark.parametrize("path,n0", _cases())
def test_graph_nlp_of_fd_plan_is_well_formed(path, n0):
    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.sas_writer import write_sas
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.compile.task import build_task

    problem = _load(path)
    task = build_task(problem)
    res = run_fd_on_sas(write_sas(task))
    states = plan_states(task, parse_plan(task, "; ".join(res.plan)))
    fac = GraphNLPFactory(problem, task, robot_dims=_robot_dims(problem))
    factors = fac.factors(states)
    variables = fac.variables(states, factors)
    assert factors and variables
    n = len(states) - 1
    for f in factors:
        assert f.generator[0].holds_in(states[f.step])
        if f.span == 2:
            assert f.generator[1].holds_in(states[f.step + 1])
        assert all(f.step <= v.step <= f.step + f.span - 1 for v in f.variables), f.label
        assert all(v.step <= n - 1 for v in f.variables if v.waypoints), f.label
    # the factory is deterministic
    assert fac.factors(states) == factors


def _robot_dims(problem):
    """Joint dimensions from the robot model when a URDF robot is in the scene."""
    scene = problem.scene
    if scene is None or all(r.kind == "planar" for r in scene.robots.values()):
        return None
    from gnppdsl.geometry.context import GeometryContext
    ctx = GeometryContext(scene)
    return ctx.robot_dims


def test_cli_conflict_lengthens_optimal_plan(tmp_path, capsys):
    """p3: forbidding `b1 in target while b2 still on s2` (the geometric conflict of the paper's
    loop) turns the 2-step optimum into 4 steps; the emitted .sas is checked by FD."""
    path = ROOT / "examples" / "planar" / "p3_occupied.pntc"
    _load(path)
    from gnppdsl.cli.main import main

    conflicts = tmp_path / "c.txt"
    conflicts.write_text("<{parent(b1) = target, parent(b2) = s2}>\n")
    assert main(["compile", str(path), "--emit", "sas"]) == 0
    assert run_fd_on_sas(capsys.readouterr().out).length == 2
    assert main(["compile", str(path), "--emit", "sas", "--conflicts", str(conflicts)]) == 0
    res = run_fd_on_sas(capsys.readouterr().out)
    assert res.solved and res.length == 4
    assert main(["compile", str(path), "--emit", "pddl", "--conflicts", str(conflicts), "-o", str(tmp_path / "pd")]) == 0
    pd = tmp_path / "pd"
    res = run_fd_on_sas(translate_pddl((pd / "domain.pddl").read_text(), (pd / "p3_occupied.pddl").read_text()))
    assert res.solved and res.cost == 4


def test_cli_bad_problem_file_exits_2(tmp_path, capsys):
    _load(ROOT / "examples" / "planar" / "p1_one_block.pntc")
    from gnppdsl.cli.main import main

    bad = tmp_path / "bad.pntc"
    bad.write_text("problem bad for no_such_domain\nobjects { b1 : block }\n")
    assert main(["compile", str(bad), "--emit", "sas"]) == 2
    err = capsys.readouterr().err
    assert "bad.pntc" in err and "Traceback" not in err


def _planar_cases():
    return [c for c in _cases() if "planar-" in c.id]


@pytest.mark.parametrize("path,n0", _planar_cases())
def test_scene_initial_configuration_satisfies_the_graph_of_s0(path, n0):
    """The scene is a geometric solution of s_0: evaluating every factor of G(<s_0>) at the
    factory's warm start (scene poses made relative to their parents) violates nothing."""
    from body_eval import violation

    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.semantics import initial_state
    from gnppdsl.compile.task import build_task

    problem = _load(path)
    task = build_task(problem)
    fac = GraphNLPFactory(problem, task)
    factors = fac.factors([initial_state(task)])
    assert factors
    for f in factors:
        values = [fac.initial_guess(v) for v in f.variables]
        assert all(v is not None for v in values), f.label
        worst = max(violation(c, values) for c in f.body)
        assert worst < 1e-9, (f.label, worst)


@pytest.mark.parametrize("path", [ROOT / "examples" / "lab" / "lab1.pntc",
                                  ROOT / "examples" / "mobile" / "pick_place.pntc"])
def test_3d_scene_initial_configuration_satisfies_the_graph_of_s0(path):
    """As for the planar examples, in 3-D (fk with robot bases, SE3 chains, sdist): checked by
    the nlp layer's independent numpy interpreter with the pinocchio/coal geometry."""
    from gnppdsl.geometry import context
    from gnppdsl.nlp import evaluate
    import numpy as np

    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.semantics import initial_state
    from gnppdsl.compile.task import build_task

    problem = _load(path)
    task = build_task(problem)
    geo = context.GeometryContext(problem.scene)
    fac = GraphNLPFactory(problem, task, robot_dims=geo.robot_dims)
    factors = fac.factors([initial_state(task)])
    assert {f.rule for f in factors} >= {"home", "start", "on"}
    values = {}
    for f in factors:
        for v in f.variables:
            guess = fac.initial_guess(v)
            assert guess is not None, v.name
            values[v] = np.asarray(guess)
    for f in factors:
        assert evaluate.factor_violation(f, values, geo) < 1e-9, f.label


def test_a_held_block_starts_at_the_scenes_held_pose_and_holds_the_grasp_there():
    """lab3 (`held_pose` in lab.yaml): along the plan pick(b5, right_arm) - handover - put, the
    factory's initial guess of b5's pose is the held pose at the steps an arm holds it, and its
    s_0 pose relative to the table otherwise; and at that start, the grasp rows of those steps
    hold (evaluated by the independent numpy interpreter), which the table-relative start
    violates by the block's distance from the tcp."""
    from gnppdsl.geometry import context
    from gnppdsl.nlp import evaluate
    import numpy as np

    from gnppdsl.compile.factory import GraphNLPFactory
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.compile.task import build_task

    problem = _load(ROOT / "examples" / "lab" / "lab3.pntc")
    task = build_task(problem)
    geo = context.GeometryContext(problem.scene)
    fac = GraphNLPFactory(problem, task, robot_dims=geo.robot_dims)
    states = plan_states(task, parse_plan(task, "pick(b5, right_arm, table); "
                                                "handover(b5, right_arm, left_arm); put(b5, left_arm, pad_l)"))
    held = problem.scene.robots["left_arm"].held_pose
    np.testing.assert_allclose(held, [0, 0, 0, 0, 0, np.sqrt(0.5), np.sqrt(0.5)], atol=1e-12)
    poses = {v.step: v for v in fac.variables(states) if v.kind == "pose" and v.args == ("b5",)}
    assert set(poses) == {0, 1, 2, 3}
    for i in (1, 2):                                # held by right_arm, then by left_arm
        assert fac.initial_guess(poses[i], states) == list(held)
    for i in (0, 3):                                # on the table, on pad_l: as without states
        assert fac.initial_guess(poses[i], states) == fac.initial_guess(poses[i])
    grasps = [f for f in fac.factors(states) if f.rule == "held"]
    assert {f.step for f in grasps} == {1, 2}
    for with_states, bound in ((True, 1e-9), (False, None)):
        values = {v: np.asarray(fac.initial_guess(v, states) if with_states else fac.initial_guess(v))
                  for f in grasps for v in f.variables}
        worst = max(evaluate.factor_violation(f, values, geo) for f in grasps)
        assert worst < 1e-9 if with_states else worst > 0.1, worst
