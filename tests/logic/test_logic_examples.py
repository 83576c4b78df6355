"""Cross-check on the example problems (examples/*/*.pntc): clingo's shortest plan under
conflicts has the length of Fast Downward's optimal plan on the Appendix-B-compiled `.sas`,
for random conflict sets and for conflicts learned GNPP-style from the plans themselves."""
from __future__ import annotations

import os
import random
import subprocess
import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).parent))
from logic_fd import require_fd, run_fd  # noqa: E402

from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.logic.generators import random_conflicts  # noqa: E402
from gnppdsl.logic.planner import IncrementalPlanner  # noqa: E402
from gnppdsl.logic.reformulation import forbid_sequences  # noqa: E402
from gnppdsl.logic.validate import validate_plan  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]
# the scalability families (examples/scalability) beyond their smallest members only with
# GNPP_SLOW=1: proving their horizons empty takes clingo 10 s to minutes (that is their point)
SMALL_FAMILY = {"stack_4", "lab4_paper"}
PROBLEMS = sorted(p for p in ROOT.glob("examples/*/*.pntc") if p.name != "domain.pntc"
                  and (p.parent.name != "scalability" or p.stem in SMALL_FAMILY or os.environ.get("GNPP_SLOW") == "1"))
H = 16
_tasks: dict[Path, object] = {}


def load_task(path: Path):
    if path not in _tasks:
        from gnppdsl.compile.task import build_task
        from gnppdsl.ir import load_problem
        _tasks[path] = build_task(load_problem(path))
    return _tasks[path]


def agree(task, conflicts):
    """Both planners, both plans validated; returns the common length (None: no plan <= H)."""
    compiled = forbid_sequences(task, conflicts)
    fd = run_fd(compiled)
    planner = IncrementalPlanner(task)
    planner.add_conflicts(conflicts)
    res = planner.shortest_plan(max_horizon=H)
    if fd.solved:
        assert validate_plan(task, fd.operators, conflicts).valid
        assert validate_plan(compiled, fd.operators).valid
    if res.found:
        r = validate_plan(task, res.plan, conflicts)
        assert r.valid, r.error
        assert list(res.plan.states) == r.states
    fd_len = len(fd.operators) if fd.solved and len(fd.operators) <= H else None
    got = len(res.plan) if res.found else None
    assert got == fd_len
    return res


def transition_conflict(task, plan, rng):
    """A GNPP-like conflict: the facts that change in one step of the plan (before, after)."""
    i = rng.randrange(len(plan.states) - 1)
    a, b = plan.states[i], plan.states[i + 1]
    changed = [v for v in range(len(a)) if a[v] != b[v] and not task.variables[v].is_derived]
    return (PartialState(tuple((v, a[v]) for v in changed)),
            PartialState(tuple((v, b[v]) for v in changed)))


@pytest.mark.parametrize("path", PROBLEMS, ids=lambda p: f"{p.parent.name}/{p.stem}")
def test_examples_agree_with_fast_downward(path):
    require_fd()
    task = load_task(path)
    rng = random.Random(path.stem)
    for k in range(2):                            # random conflict sets from random walks
        agree(task, random_conflicts(task, rng, rng.randint(1, 4), walk_length=10))
    conflicts = []                                # conflicts learned from the plans, 3 rounds
    for _ in range(3):
        res = agree(task, conflicts)
        if not res.found or len(res.plan) == 0:
            break
        conflicts.append(transition_conflict(task, res.plan, rng))


def test_cli_emits_the_compiled_task(tmp_path):
    """`gnpp compile P --conflicts FILE --emit sas` is the Appendix-B task: FD plans around it."""
    binary = require_fd()
    path = next(p for p in PROBLEMS if p.stem == "p2_two_blocks")
    task = load_task(path)
    plan = IncrementalPlanner(task).shortest_plan().plan
    rng = random.Random(1)
    for _ in range(20):           # a conflict that leaves a (longer) plan
        conflict = transition_conflict(task, plan, rng)
        planner = IncrementalPlanner(task)
        planner.add_conflict(conflict)
        if planner.shortest_plan(max_horizon=10).found:
            break
    from gnppdsl.logic.conflict_io import write_conflicts

    (tmp_path / "c.txt").write_text(write_conflicts(task, [conflict]))
    gnpp = Path(sys.executable).parent / "gnpp"
    out = subprocess.run([str(gnpp), "compile", str(path), "--emit", "sas", "--conflicts",
                          str(tmp_path / "c.txt")], capture_output=True, text=True, timeout=60)
    assert out.returncode == 0, out.stderr
    fd = subprocess.run([str(binary), "--search", "astar(blind(), cost_type=one)"],
                        input=out.stdout, capture_output=True, text=True, cwd=tmp_path, timeout=60)
    assert fd.returncode == 0
    names = [l.strip()[1:-1] for l in (tmp_path / "sas_plan").read_text().splitlines()
             if not l.startswith(";")]
    by_name = {" ".join(op.name.split()): i for i, op in enumerate(task.operators)}
    ops = [by_name[n] for n in names]
    assert validate_plan(task, ops, [conflict]).valid
    planner = IncrementalPlanner(task)
    planner.add_conflict(conflict)
    assert len(planner.shortest_plan().plan) == len(ops) >= len(plan)
    assert not validate_plan(task, plan, [conflict]).valid      # the old plan is forbidden
    (tmp_path / "bad.txt").write_text("<{nonsense = 1}>\n")
    bad = subprocess.run([str(gnpp), "compile", str(path), "--emit", "sas", "--conflicts",
                          str(tmp_path / "bad.txt")], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "bad.txt:1:3" in bad.stderr and "Traceback" not in bad.stderr
