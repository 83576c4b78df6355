"""`gnpp compile`: every --emit, -o, --plan, --conflicts and the error paths (exit 2)."""
from __future__ import annotations

import pytest

import planar_ir
from asp_oracle import solve_incremental
from fd_oracle import run_fd_on_sas, translate_pddl
from pddl.parser.domain import DomainParser
from pddl.parser.problem import ProblemParser

from gnppdsl.compile.task import build_task

import gnppdsl.ir
from gnppdsl.cli.main import main


@pytest.fixture
def p1(monkeypatch, tmp_path):
    """A problem file whose loading is replaced by the IR built in Python (parser-independent)."""
    path = tmp_path / "p1.pntc"
    path.write_text("# loaded through the monkeypatched loader\n")
    monkeypatch.setattr(gnppdsl.ir, "load_problem", lambda *paths: planar_ir.problem("p1"), raising=False)
    return str(path)


def test_emit_sas_to_stdout_is_solved_by_fd(p1, capsys):
    assert main(["compile", p1, "--emit", "sas"]) == 0
    out = capsys.readouterr().out
    res = run_fd_on_sas(out)
    assert res.solved and res.plan == ["pick(b1, g, s1)", "place(b1, g, r1)"]


def test_emit_pddl_into_directory(p1, tmp_path, capsys):
    out_dir = tmp_path / "out"
    assert main(["compile", p1, "--emit", "pddl", "-o", str(out_dir)]) == 0
    assert sorted(p.name for p in out_dir.iterdir()) == ["domain.pddl", "p1.pddl"]
    domain, problem = (out_dir / "domain.pddl").read_text(), (out_dir / "p1.pddl").read_text()
    DomainParser()(domain)
    ProblemParser()(problem)
    res = run_fd_on_sas(translate_pddl(domain, problem))
    assert res.solved and res.length == 2
    assert "(:action pick\n    :parameters (?o - block ?g - gripper ?from - place_type)" in domain
    assert main(["compile", p1, "--emit", "pddl-ground", "-o", str(tmp_path / "g")]) == 0
    assert "(:action pick_b1_g_s1" in (tmp_path / "g" / "domain.pddl").read_text()
    assert main(["compile", p1, "--emit", "sas", "--inline-derived"]) == 2


def test_emit_factors_with_plan(p1, capsys, tmp_path):
    assert main(["compile", p1, "--emit", "factors", "--plan", "pick(b1, g, s1); place(b1, g, r1)"]) == 0
    out = capsys.readouterr().out
    assert "3 states" in out and "held(o=b1, g=g) -> planar.grasp @1" in out
    assert "generator: @1 {parent(b1) = g}" in out
    plan_file = tmp_path / "plan.txt"
    plan_file.write_text("(pick(b1, g, s1))\n(place(b1, g, r1))\n; cost = 2 (unit cost)\n")
    assert main(["compile", p1, "--emit", "factors", "--plan", str(plan_file)]) == 0
    assert capsys.readouterr().out == out
    # default: only s_0
    assert main(["compile", p1, "--emit", "factors"]) == 0
    assert "1 states" in capsys.readouterr().out


def test_emit_asp(p1, capsys):
    """The emitted program, run by clingo in incremental mode, finds FD's 2-step plan."""
    assert main(["compile", p1, "--emit", "asp"]) == 0
    plan = solve_incremental(capsys.readouterr().out, max_steps=6)
    assert plan.length == 2 and len(plan.operators) == 2
    task = build_task(planar_ir.problem("p1"))
    assert [task.operators[o].name for o in plan.operators] == ["pick(b1, g, s1)", "place(b1, g, r1)"]


def test_conflicts_are_forbidden_in_emitted_sas(p1, tmp_path, capsys):
    conflicts = tmp_path / "c.txt"
    conflicts.write_text("<{parent(b1) = g}, {parent(b1) = r1}>\n")
    assert main(["compile", p1, "--emit", "sas", "--conflicts", str(conflicts)]) == 0
    res = run_fd_on_sas(capsys.readouterr().out)
    # placing b1 into r1 right after holding it is forbidden: the goal is now unreachable
    assert not res.solved


@pytest.mark.parametrize("argv,message", [
    (["--emit", "factors", "--plan", "place(b1, g, r1)"], "is not applicable"),
    (["--emit", "factors", "--plan", "jump(b1)"], "unknown or statically inapplicable action 'jump(b1)'"),
    (["--emit", "sas", "--plan", "pick(b1, g, s1)"], "--plan only applies to --emit factors"),
    (["--emit", "factors", "--plan", "missing_plan.txt"], "no such file"),
])
def test_user_errors_exit_2(p1, capsys, argv, message):
    assert main(["compile", p1, *argv]) == 2
    err = capsys.readouterr().err
    assert message in err and "Traceback" not in err


def test_missing_problem_file_exits_2(capsys):
    assert main(["compile", "/nonexistent/p.pntc"]) == 2
    assert "no such file" in capsys.readouterr().err


def test_help_lists_every_option(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["compile", "--help"])
    assert exc.value.code == 0
    out = capsys.readouterr().out
    for opt in ("--emit", "--output", "--plan", "--conflicts", "examples:"):
        assert opt in out
