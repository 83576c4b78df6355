"""Every example passes `gnpp check`, loads, and compiles (SAS+ task and graph-NLP factors).

N0 of every example is checked against Fast Downward by tests/compile/test_compile_examples.py;
here: the front end accepts the files, the relaxation tags name real tags, and the graph-NLP
factory instantiates the expected plan of each problem (the plan in its `# plan:` comment when
it is fully specified) with the factors the domain promises.
"""
from __future__ import annotations

import re
import sys
from collections import Counter
from pathlib import Path

import pytest
import yaml

sys.path.insert(0, str(Path(__file__).resolve().parent))
from planar_reference import EXAMPLES  # noqa: E402

import gnppdsl.ir as ir  # noqa: E402  (a missing front end is a failure, never a skip)

DIRS = ["planar", "lab", "mobile", "field", "workshop"]
STDLIB = EXAMPLES.parent / "stdlib"


def _problems():
    for d in DIRS:
        exp = yaml.safe_load((EXAMPLES / d / "expected.yaml").read_text())["problems"]
        for name, e in exp.items():
            yield d, name, e


def _plan_comment(path: Path) -> str | None:
    """The `# plan:` comment (possibly continued on `#` lines), if fully specified (no `_`)."""
    lines = path.read_text().splitlines()
    for i, line in enumerate(lines):
        if line.startswith("# plan:"):
            text = line[len("# plan:"):]
            for more in lines[i + 1:]:
                if more.startswith("#       "):
                    text += more[1:]
                else:
                    break
            text = re.sub(r"\(or .*?\)\s*$", "", text.strip()).strip()
            if "_" in re.sub(r"\w+_\w+", "", text) or not text:
                return None
            return "; ".join(a.strip() for a in re.findall(r"\w+\([^)]*\)", text))
    return None


@pytest.mark.parametrize("d", DIRS)
def test_gnpp_check_accepts_examples(d, capsys):
    from gnppdsl.cli.main import main

    files = sorted(str(p) for p in (EXAMPLES / d).glob("*.pntc"))
    assert main(["check", *files]) == 0, capsys.readouterr().err


def test_gnpp_check_accepts_stdlib(capsys):
    from gnppdsl.cli.main import main

    assert main(["check", *sorted(str(p) for p in STDLIB.glob("*.pntc"))]) == 0, capsys.readouterr().err


def test_gnpp_check_rejects_a_broken_example(tmp_path, capsys):
    """The check above can fail: a misspelt template in a copy of the planar domain."""
    from gnppdsl.cli.main import main

    src = (EXAMPLES / "planar" / "domain.pntc").read_text()
    assert "planar.no_overlap(a, b)" in src
    (tmp_path / "domain.pntc").write_text(src.replace("planar.no_overlap(a, b)", "planar.no_overlpa(a, b)"))
    for f in ("p1_one_block.pntc", "p1_one_block.yaml"):
        (tmp_path / f).write_text((EXAMPLES / "planar" / f).read_text())
    assert main(["check", str(tmp_path / "domain.pntc"), str(tmp_path / "p1_one_block.pntc")]) != 0
    assert "no_overlap" in capsys.readouterr().err        # did-you-mean hint


@pytest.mark.parametrize("d,name,e", list(_problems()))
def test_problem_loads(d, name, e):
    prob = ir.load_problem(EXAMPLES / d / e["file"])
    assert prob.name == name
    assert prob.domain.world_space.kind == ("SE2" if d == "planar" else "SE3")
    assert prob.scene is not None and prob.scene.dimension == (2 if d == "planar" else 3)
    # relaxations drop tags that exist in the domain (a typo would silently drop nothing)
    dom = prob.domain
    tags = set()
    for t in dom.templates.values():
        tags |= set(t.tags)
    for r in dom.rules:
        tags |= set(r.tags)
        for c in r.calls:
            tags |= set(c.tags)
    for c in dom.continuous.values():
        tags |= set(c.tags)
    for rel in prob.relaxations or dom.relaxations:
        assert rel.drop <= tags, f"{rel.name} drops unknown tags {sorted(rel.drop - tags)}"


def _factors(path: Path, plan: str):
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.solve.compiled import compile_problem

    c = compile_problem(ir.load_problem(path))
    states = plan_states(c.task, parse_plan(c.task, plan))
    return c, states, c.factory.factors(states)


PLANS = [(d, n, e) for d, n, e in _problems() if _plan_comment(EXAMPLES / d / e["file"])]


def test_plan_comments_found():
    names = {n for _, n, _ in PLANS}
    assert {"p1_one_block", "p3_occupied", "p5_handover", "t1_swap", "lab3"} <= names


@pytest.mark.parametrize("d,name,e", PLANS)
def test_expected_plan_compiles(d, name, e):
    plan = _plan_comment(EXAMPLES / d / e["file"])
    c, states, factors = _factors(EXAMPLES / d / e["file"], plan)
    assert len(states) == e["n"] + 1
    n = len(states) - 1
    assert all(0 <= f.step <= n for f in factors)
    by_template = Counter(f.template.split(".")[-1] for f in factors)
    if d == "planar":
        blocks = c.problem.objects_of("block")
        grippers = c.problem.objects_of("gripper")
        # one kinematic switch per action (each action changes exactly one block's parent)
        assert by_template["kin_switch"] == n
        # no_overlap between every pair of blocks at every step
        assert by_template["no_overlap"] == len(blocks) * (len(blocks) - 1) // 2 * (n + 1)
        assert by_template["within"] == len(grippers) * (n + 1)
        # time consistency for every block whose parent does not change, at every transition
        assert by_template["same"] == len(blocks) * n - n
    else:
        # one kinematic switch per action that moves an object (the Field's start_move and
        # end_move move only the base), trajectories for every robot and phase
        drives = sum(a.strip().startswith(("start_move(", "end_move(")) for a in plan.split(";"))
        assert by_template["kin_switch_rel"] == n - drives
        arms = list(c.problem.objects_of("arm")) + (list(c.problem.objects_of("mobile")) if d == "field" else [])
        assert by_template["boundary"] == len(arms) * n
        assert by_template["grasp"] >= 1 and by_template["on"] >= 1
        if d == "workshop":
            # four arms: arm-arm pairs left to the active set; a pushed block rides on the
            # stick's end for one step per push (`take` follows at once in these plans), and
            # the motion out of that step is a push
            pushes = sum(a.strip().startswith("push(") for a in plan.split(";"))
            assert pushes >= 1 and by_template["clear_arms"] == 0
            assert by_template["tip_contact"] == by_template["push_motion"] == pushes
            assert by_template["push_path"] == pushes
        else:
            assert by_template["clear_arms"] == n + 1
        tags = set().union(*(f.tags for f in factors))
        assert {"traj", "collision", "robot", "grasp", "place", "kin"} <= tags


def test_planar_goal_placement_factor():
    """p3: in the final state b1 is inside `target` and b2 inside `side` (factor bindings)."""
    _, states, factors = _factors(EXAMPLES / "planar" / "p3_occupied.pntc",
                                  "pick(b2, g, s2); place(b2, g, side); pick(b1, g, s1); place(b1, g, target)")
    inside = {tuple(sorted(dict(f.bindings).items())) for f in factors
              if f.template == "planar.inside" and f.step == 4}
    assert inside == {(("o", "b1"), ("r", "target")), (("o", "b2"), ("r", "side"))}


@pytest.mark.parametrize("f", sorted(str(p.relative_to(EXAMPLES.parent)) for p in
                                     list(EXAMPLES.glob("*/*.pntc")) + list(STDLIB.glob("*.pntc"))))
def test_no_statement_continues_the_previous_line(f):
    """Statements need no separator, so a line starting with '(', '-' or '[' would continue the
    previous statement's expression (`x == 0` + `-d <= y` parses as `x == 0 - d <= y`). Such a
    line must follow a line ending with ';', '{' or '}' (or a comment / blank line after one)."""
    prev = "{"
    for i, line in enumerate((EXAMPLES.parent / f).read_text().splitlines(), 1):
        code = line.split("#", 1)[0].rstrip()
        if not code:
            continue
        if re.match(r"\s*[-(\[]", code) and not re.search(r"(=>|,|->|with|:=|=|\()\s*$", prev):
            assert prev.endswith((";", "{", "}")), f"{f}:{i}: starts with '{code.strip()[0]}' after '{prev.strip()}'"
        prev = code
