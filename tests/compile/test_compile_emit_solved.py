"""What `gnpp compile --emit` writes is solved by tools that share no code with gnppdsl, to the
optimum Fast Downward finds on the emitted `.sas` (examples/*: planar, Lab, mobile):
- `--emit asp`: clingo (incremental mode, tests/compile/asp_oracle.py) finds a plan of the same
  length; the plan, replayed by the SAS+ semantics written in the tests (sas_semantics.py),
  reaches the goal;
- `--emit pddl -o DIR`: the `pddl` package parses both files, Fast Downward's own translator
  and search solve them to the same optimal length (whether the export is grounded or lifted).
"""
from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from asp_oracle import solve_incremental
from fd_oracle import run_fd_on_sas, translate_pddl
from sas_semantics import run_plan

from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]


def _examples():
    out = []
    for sub in ("planar", "lab", "mobile"):
        data = yaml.safe_load((ROOT / "examples" / sub / "expected.yaml").read_text())
        for name, info in data["problems"].items():
            out.append(pytest.param(ROOT / "examples" / sub / info["file"], id=f"{sub}-{name}"))
    return out


def _emit(capsys, path, kind, *extra) -> str:
    assert main(["compile", str(path), "--emit", kind, *extra]) == 0
    return capsys.readouterr().out


@pytest.mark.parametrize("path", _examples())
def test_emitted_asp_solved_by_clingo_to_fd_length(path, capsys):
    from gnppdsl.compile.task import build_task
    from gnppdsl.ir import load_problem

    fd = run_fd_on_sas(_emit(capsys, path, "sas"))
    asp = solve_incremental(_emit(capsys, path, "asp"), max_steps=20)
    if not fd.solved:
        assert asp.length is None
        return
    assert asp.length == fd.length, (asp.length, fd.plan)
    task = build_task(load_problem(str(path)))
    names = [task.operators[o].name for o in asp.operators]
    assert len(names) == asp.length
    assert task.goal.holds_in(run_plan(task, names)[-1])


@pytest.mark.parametrize("path", _examples())
def test_emitted_pddl_parsed_and_solved_by_fd_to_the_same_length(path, capsys, tmp_path):
    from pddl.parser.domain import DomainParser
    from pddl.parser.problem import ProblemParser

    fd = run_fd_on_sas(_emit(capsys, path, "sas"))
    out = tmp_path / "pddl"
    assert main(["compile", str(path), "--emit", "pddl", "-o", str(out)]) == 0
    capsys.readouterr()
    domain = (out / "domain.pddl").read_text()
    problems = [p for p in out.iterdir() if p.name != "domain.pddl"]
    assert len(problems) == 1, sorted(p.name for p in out.iterdir())
    problem = problems[0].read_text()
    DomainParser()(domain)
    ProblemParser()(problem)
    res = run_fd_on_sas(translate_pddl(domain, problem))
    assert res.solved == fd.solved
    if fd.solved:
        assert res.length == fd.length and res.cost == fd.cost, (res.plan, fd.plan)
