"""Object ranges and quantified init/goal facts (gnppdsl.ir.families): what they expand to, and
a located diagnostic for every misuse.

The expansions are checked against facts written out by hand (the oracle is the explicit list),
and the rewritten Lab 5 against its hand-written original: both compile to the same SAS+ task
text (Fast Downward's format, `write_sas`), so the rewrite changed nothing a planner sees.
"""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.task import build_task
from gnppdsl.ir import load_problem
from gnppdsl.ir.resolve import check_files
from tests.ir.test_ir_diagnostics import BASE, at

ROOT = Path(__file__).resolve().parents[2]


def problem(tmp_path, text: str):
    (tmp_path / "domain.pntc").write_text(BASE)
    (tmp_path / "p.pntc").write_text(textwrap.dedent(text))
    return tmp_path / "p.pntc", tmp_path / "domain.pntc"


def diags(tmp_path, text: str):
    p, d = problem(tmp_path, text)
    return check_files([str(d), str(p)]).reporter.diagnostics


def facts(tmp_path, text: str):
    p, d = problem(tmp_path, text)
    prob = load_problem(p, d)
    init = {(a.var, tuple(x.name for x in a.args)): a.value.name for a in prob.init}
    goal = {(g.var, tuple(x.name for x in g.args)): g.value.name for g in prob.goal}
    return prob, init, goal


def test_ranges_and_foralls_expand_to_the_written_out_facts(tmp_path):
    prob, init, goal = facts(tmp_path, """\
        problem p for d
        objects { b1..b6, x : block  s01..s03 : place  g : gripper }
        init { forall b: block . parent(b) = s01   holding(g) = none }
        goal { forall i in 1..3 { parent(b{2*i}) = s0{i} }  holding(g) = b{7-2*3} }
        """)
    assert list(prob.objects) == ["b1", "b2", "b3", "b4", "b5", "b6", "x", "s01", "s02", "s03", "g"]
    assert all(init[("parent", (b,))] == "s01" for b in ("b1", "b2", "b3", "b4", "b5", "b6", "x"))
    assert init[("holding", ("g",))] == "none"
    assert goal == {("parent", ("b2",)): "s01", ("parent", ("b4",)): "s02", ("parent", ("b6",)): "s03",
                    ("holding", ("g",)): "b1"}


def test_forall_over_several_types_and_nested(tmp_path):
    _, init, goal = facts(tmp_path, """\
        problem p for d
        objects { b1..b2 : block  s1..s2 : place  g, h : gripper }
        init { forall i in 1..2 . parent(b{i}) = s{i}  forall k: gripper . holding(k) = none }
        goal { forall k: gripper { forall i in 1..1 . holding(k) = b{i} } }
        """)
    assert init[("parent", ("b1",))] == "s1" and init[("parent", ("b2",))] == "s2"
    assert goal == {("holding", ("g",)): "b1", ("holding", ("h",)): "b1"}


def test_expanded_facts_keep_every_later_check(tmp_path):
    # b{i} with i = 3 names no object: reported at the fact inside the forall
    d = diags(tmp_path, """\
        problem p for d
        objects { b1..b2 : block  s1 : place  g : gripper }
        init { forall b: block . parent(b) = s1  holding(g) = none }
        goal { forall i in 2..3 . parent(b{i}) = g }
        """)
    assert "b3" in at(d, 4, 34, "unknown-name").message


@pytest.mark.parametrize("objects, line_col, kind, needle", [
    ("b1..c3 : block", (2, 11), "range", "different prefixes"),
    ("b..b3 : block", (2, 11), "range", "does not end in a number"),
    ("b5..b2 : block", (2, 11), "range", "empty range"),
    ("b1..b999999 : block", (2, 11), "range", "at most"),
    ("b1..b2 : blok", (2, 20), "unknown-type", "unknown type"),
])
def test_bad_ranges_are_located(tmp_path, objects, line_col, kind, needle):
    d = diags(tmp_path, f"""\
        problem p for d
        objects {{ {objects}  s1 : place  g : gripper }}
        init {{ holding(g) = none }}
        goal {{ holding(g) = none }}
        """)
    hit = at(d, *line_col, kind)
    assert needle in hit.message
    assert hit.hint is not None or kind == "range" and needle == "at most"


@pytest.mark.parametrize("goal, line_col, needle, hint", [
    ("forall b: blok . parent(b) = s1", (4, 18), "unknown type 'blok'", "did you mean 'block'?"),
    ("forall b1: block . parent(b1) = s1", (4, 15), "shadows an object", "rename"),
    ("forall parent: block . holding(g) = parent", (4, 15), "shadows a state variable", "rename"),
    ("forall i in 1..2 { forall i in 1..2 . parent(b{i}) = s1 }", (4, 34), "already bound", "own name"),
    ("forall i in 1..2 . parent(i) = s1", (4, 34), "integer index, not an object", "b{i}"),
    ("forall b: block . parent(s{b}) = s1", (4, 35), "object, not an integer index", "forall i in"),
    ("forall i in 1..2 . parent(b{j}) = s1", (4, 36), "unknown index 'j'", "forall i in LO..HI"),
    ("forall i in 1..2 . parent(b{i/2}) = s1", (4, 36), "1 / 2 is not an integer", None),
    ("forall i in 1..2 . parent(b{i-5}) = s1", (4, 36), "non-negative", None),
    ("forall i in 3..2 . parent(b{i}) = s1", (4, 15), "empty index range", None),
    ("forall i in 1..2 . parent(b{i*[1]}) = s1", (4, 38), "integer expression", "b{2*i-1}"),
    ("forall i in 1.5..2 . parent(b{i}) = s1", (4, 15), "integer bounds", "forall i in 1..8"),
])
def test_bad_foralls_are_located(tmp_path, goal, line_col, needle, hint):
    d = diags(tmp_path, f"""\
        problem p for d
        objects {{ b1..b2 : block  s1 : place  g : gripper }}
        init {{ forall b: block . parent(b) = s1  holding(g) = none }}
        goal {{ {goal} }}
        """)
    hit = at(d, *line_col)
    assert needle in hit.message, hit.message
    if hint is not None:
        assert hint in (hit.hint or ""), hit.hint


def test_indexed_name_outside_init_and_goal_is_a_syntax_error(tmp_path):
    (tmp_path / "domain.pntc").write_text(BASE + "action a(o: block) { pre parent(b{1}) = o }\n")
    d = check_files([str(tmp_path / "domain.pntc")]).reporter.diagnostics
    hit = at(d, 15, 34, "syntax")
    assert "'{'" in hit.message


def test_forall_expansion_limit(tmp_path):
    d = diags(tmp_path, """\
        problem p for d
        objects { b1..b2 : block  s1 : place  g : gripper }
        init { holding(g) = none  forall b: block . parent(b) = s1 }
        goal { forall i in 1..500, j in 1..500 . holding(g) = b{1} }
        """)
    assert "more than" in at(d, 4, 8, "forall").message


def _sas(problem_path: Path, domain_path: Path) -> str:
    return write_sas(build_task(load_problem(problem_path, domain_path)))


def test_rewritten_lab5_compiles_to_the_same_sas_task():
    """examples/lab/lab5.pntc uses a range and quantified facts; its hand-written original (kept
    in tests/ir/data/lab_inline) compiles to the same SAS+ text."""
    dom = ROOT / "examples/lab/domain.pntc"
    new = _sas(ROOT / "examples/lab/lab5.pntc", dom)
    old = _sas(ROOT / "tests/ir/data/lab_inline/lab5.pntc", dom)
    assert "forall" in (ROOT / "examples/lab/lab5.pntc").read_text()
    assert new == old
    assert "parent(b4)" in new
