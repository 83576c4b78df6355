"""Every diagnostic kind of the resolver / type checker, with its exact line and column.

Each case appends a few lines to a small valid domain (BASE, 14 lines) or problem, so the
offending text is on line 15 or later; the expected positions are counted by hand from the
snippets below (columns are 1-based).
"""
from __future__ import annotations

import textwrap

import pytest

from gnppdsl.ir.resolve import check_files

BASE = """\
domain d
type place
type block
type gripper
state parent(o: block) : place | gripper
state holding(g: gripper) : block | none
state free(g: gripper) : bool
continuous pose(o: block) : SE2 tags object
continuous q(g: gripper) : SE2 tags robot
frame o: block = world(parent(o)) * pose(o)
frame g: gripper = q(g)
template same(a: value, b: value) tags time {
  a == b
}
"""
assert BASE.count("\n") == 14

PROBLEM = """\
problem p for d
objects { b1, b2 : block  s1 : place  g : gripper }
init { parent(b1) = s1  parent(b2) = s1  holding(g) = none }
goal { parent(b1) = g }
"""


def check(tmp_path, domain_extra: str = "", problem: str | None = None, files: dict | None = None):
    (tmp_path / "domain.pntc").write_text(BASE + textwrap.dedent(domain_extra))
    paths = [tmp_path / "domain.pntc"]
    if problem is not None:
        (tmp_path / "p.pntc").write_text(textwrap.dedent(problem))
        paths.append(tmp_path / "p.pntc")
    for name, text in (files or {}).items():
        (tmp_path / name).write_text(textwrap.dedent(text))
    return check_files([str(p) for p in paths]).reporter.diagnostics


def at(diags, line: int, col: int, kind: str | None = None, file: str | None = None):
    hits = [d for d in diags if d.span is not None and (d.span.line, d.span.column) == (line, col)
            and (kind is None or d.kind == kind) and (file is None or d.span.file.endswith(file))]
    assert hits, "no diagnostic at %d:%d (%s); got:\n%s" % (
        line, col, kind, "\n".join(f"{d.span} {d.kind}: {d.message}" for d in diags))
    return hits[0]


def test_base_is_clean(tmp_path):
    assert check(tmp_path, problem=PROBLEM) == []


# ---------------------------------------------------------------- names and types
def test_unknown_type_with_hint(tmp_path):
    d = check(tmp_path, "state on(o: blok) : place\n")
    x = at(d, 15, 13, "unknown-type")
    assert "blok" in x.message and x.hint == "did you mean 'block'?"


def test_unknown_supertype(tmp_path):
    at(check(tmp_path, "type spot < plase\n"), 15, 13, "unknown-type")


def test_duplicate_type(tmp_path):
    at(check(tmp_path, "type block\n"), 15, 6, "duplicate")


def test_type_cycle(tmp_path):
    d = check(tmp_path, "type a < b\ntype b < a\n")
    assert any(x.kind == "cycle" for x in d)


def test_reserved_type_name(tmp_path):
    at(check(tmp_path, "type SE2\n"), 15, 6, "reserved")


@pytest.mark.parametrize("decl, col", [("state final : bool\n", 7), ("action initial() { }\n", 8),
                                       ("derived final() := free(g)\n", 9)])
def test_names_of_the_compiled_rule_markers_are_reserved(tmp_path, decl, col):
    """`initial` and `final` are the state variable and step the compiler adds for `: initial`
    and `: final` rules: declaring one passed check and failed at compile without a location."""
    x = at(check(tmp_path, decl, problem=PROBLEM), 15, col, "reserved")
    assert "reserved" in x.message


def test_unknown_state_variable_in_action(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          pre parnt(o) = g
        }
        """)
    x = at(d, 16, 7, "unknown-name")
    assert x.hint == "did you mean 'parent'?"


def test_state_arity(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          pre parent(o, g) = g
        }
        """)
    at(d, 16, 7, "arity")


def test_argument_type(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          pre parent(g) = g
        }
        """)
    x = at(d, 16, 14, "type")
    assert "gripper" in x.message


def test_value_outside_domain(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          eff holding(g) := g
        }
        """)
    at(d, 16, 21, "type")


def test_none_not_allowed(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          eff parent(o) := none
        }
        """)
    x = at(d, 16, 20, "type")
    assert "| none" in x.hint


def test_non_boolean_used_as_condition(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          pre holding(g)
        }
        """)
    at(d, 16, 7, "logic")


def test_boolean_assigned_object(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          eff free(g) := o
        }
        """)
    at(d, 16, 18, "type")


def test_derived_cannot_be_assigned(tmp_path):
    d = check(tmp_path, """\
        derived busy(g: gripper) := not free(g)
        action pick(o: block, g: gripper) {
          eff busy(g)
        }
        """)
    at(d, 17, 7, "logic")


def test_duplicate_action_keyword(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) {
          pre free(g)
          pre holding(g) = none
        }
        """)
    at(d, 17, 3, "duplicate")


def test_untyped_action_parameter(tmp_path):
    d = check(tmp_path, "action pick(o) { pre free(o) }\n")
    at(d, 15, 13, "missing-type")


def test_misplaced_declaration(tmp_path):
    d = check(tmp_path, "objects { b : block }\n")
    x = at(d, 15, 1, "misplaced")
    assert "problem" in x.hint


# ---------------------------------------------------------------- continuous side and templates
def test_unknown_space(tmp_path):
    x = at(check(tmp_path, "continuous v(o: block) : SE4\n"), 15, 26, "unknown-space")
    assert "'SE2'" in x.hint and "'SE3'" in x.hint


def test_joints_needs_parameter(tmp_path):
    at(check(tmp_path, "continuous j(g: gripper) : joints(r)\n"), 15, 35, "unknown-name")


def test_dimension_mismatch_in_constraint(tmp_path):
    d = check(tmp_path, """\
        template t(a: R[3], b: R[2]) {
          a == b
        }
        """)
    x = at(d, 16, 5, "dimension")
    assert "R[3]" in x.message and "R[2]" in x.message


def test_dimension_mismatch_in_addition(tmp_path):
    d = check(tmp_path, """\
        template t(a: R[3], b: R[2]) {
          a + b == a
        }
        """)
    at(d, 16, 3, "dimension")


def test_dimension_mismatch_in_builtin_call(tmp_path):
    d = check(tmp_path, """\
        template t(a: R[3], b: R[2]) {
          dot(a, b) == 0
        }
        """)
    at(d, 16, 3, "dimension")


def test_pose_composition_mismatch(tmp_path):
    d = check(tmp_path, """\
        template t(a: SE2, b: SE3) {
          pos(a * b) == [0, 0]
        }
        """)
    at(d, 16, 7, "dimension")


def test_unknown_name_in_template(tmp_path):
    d = check(tmp_path, """\
        template t(a: R, b: R) {
          a == bb
        }
        """)
    x = at(d, 16, 8, "unknown-name")
    assert x.hint == "did you mean 'b'?"


def test_unknown_function_in_template(tmp_path):
    d = check(tmp_path, """\
        template t(a: R[2]) {
          nrom(a) == 1
        }
        """)
    x = at(d, 16, 3, "unknown-name")
    assert x.hint.startswith("did you mean 'norm'")


def test_overload_needs_a_space(tmp_path):
    d = check(tmp_path, """\
        template t(a: value) {
          pos(a) == [0, 0]
        }
        """)
    at(d, 16, 3, "type")


def test_index_out_of_range(tmp_path):
    d = check(tmp_path, """\
        template t(a: R[2]) {
          a[2] == 0
        }
        """)
    at(d, 16, 5, "dimension")


def test_object_where_value_expected(tmp_path):
    d = check(tmp_path, """\
        template t(o: block) {
          o == 0
        }
        """)
    x = at(d, 16, 3, "type")
    assert "world" in x.hint


def test_forall_bounds_must_be_integers(tmp_path):
    d = check(tmp_path, """\
        template t(a: R[3]) {
          forall k in 0 .. 1.5 { a[k] >= 0 }
        }
        """)
    at(d, 16, 20, "type")


def test_with_needs_a_variable(tmp_path):
    d = check(tmp_path, """\
        template t(o: block, g: gripper) {
          (norm(pos(world(o))) with free(g) = 1) >= 0
        }
        """)
    at(d, 16, 29, "type")


def test_const_must_be_numeric(tmp_path):
    at(check(tmp_path, 'const c = "x"\n'), 15, 11, "const")


def test_frame_must_be_a_pose(tmp_path):
    d = check(tmp_path, "type stone\ncontinuous at(s: stone) : R[2]\nframe s: stone = at(s)\n")
    at(d, 17, 18, "frame")


def test_duplicate_frame(tmp_path):
    at(check(tmp_path, "frame b: block = pose(b)\n"), 15, 10, "duplicate")


# ---------------------------------------------------------------- primes
def test_prime_in_frame(tmp_path):
    d = check(tmp_path, "type stone\ncontinuous at(s: stone) : SE2\nframe s: stone = at(s)'\n")
    at(d, 17, 18, "prime")


def test_double_prime(tmp_path):
    d = check(tmp_path, """\
        template t(o: block) {
          world(o)'' == world(o)
        }
        """)
    at(d, 16, 3, "prime")


def test_prime_without_effect(tmp_path):
    d = check(tmp_path, """\
        template t(a: R) {
          a' == 1
        }
        """)
    at(d, 16, 3, "prime")


def test_prime_in_single_state_rule(tmp_path):
    d = check(tmp_path, "rule r(o: block, g: gripper) : parent(o) = g => same(pose(o), pose(o)')\n")
    x = at(d, 15, 63, "prime")
    assert "p -> p'" in x.message


def test_two_step_template_in_single_state_rule(tmp_path):
    d = check(tmp_path, """\
        template keep(o: block) { world(o)' == world(o) }
        rule r(o: block) : always => keep(o)
        """)
    at(d, 16, 30, "prime")


# ---------------------------------------------------------------- rules
def test_unknown_template(tmp_path):
    x = at(check(tmp_path, "rule r(o: block) : always => sam(pose(o), pose(o))\n"), 15, 30,
           "unknown-template")
    assert x.hint.startswith("did you mean 'same'")


def test_unknown_qualified_template(tmp_path):
    d = check(tmp_path, "rule r(o: block) : always => d.sme(pose(o), pose(o))\n")
    x = at(d, 15, 32, "unknown-template")
    # the suggestion is written as the call must be: with its module, not the bare name
    assert x.hint == "did you mean 'd.same'?", x.hint


def test_unknown_module_in_call(tmp_path):
    d = check(tmp_path, "rule r(o: block) : always => planr.same(pose(o), pose(o))\n")
    at(d, 15, 30, "unknown-module")


def test_unknown_module_in_use(tmp_path):
    (tmp_path / "domain.pntc").write_text("domain d\nuse planr\n")
    d = check_files([str(tmp_path / "domain.pntc")]).reporter.diagnostics
    x = at(d, 2, 5, "unknown-module")
    assert x.hint.startswith("did you mean 'planar'")


def test_ambiguous_template(tmp_path):
    mods = {"m1.pntc": "module m1\ntemplate z(a: R) { a == 0 }\n",
            "m2.pntc": "module m2\ntemplate z(a: R) { a == 1 }\n"}
    (tmp_path / "domain.pntc").write_text(
        "domain d\nuse m1, m2\ntype block\ncontinuous v(o: block) : R\n"
        "rule r(o: block) : always => z(v(o))\n")
    for k, v in mods.items():
        (tmp_path / k).write_text(v)
    d = check_files([str(tmp_path / "domain.pntc")]).reporter.diagnostics
    x = at(d, 5, 30, "ambiguous")
    assert "m1.z" in x.hint and "m2.z" in x.hint


def test_template_arity(tmp_path):
    d = check(tmp_path, "rule r(o: block) : always => same(pose(o))\n")
    x = at(d, 15, 30, "arity")
    assert "takes 2 arguments, got 1" in x.message


def test_template_value_arguments_must_agree(tmp_path):
    d = check(tmp_path, "rule r(o: block) : always => same(pose(o), [1, 2])\n")
    at(d, 15, 44, "dimension")


def test_template_object_argument(tmp_path):
    d = check(tmp_path, """\
        template near(o: block, g: gripper) { norm(pos(world(o)) - pos(world(g))) <= 1 }
        rule r(o: block, g: gripper) : always => near(g, o)
        """)
    at(d, 16, 47, "type")


def test_value_argument_given_an_object(tmp_path):
    d = check(tmp_path, "rule r(o: block) : always => same(o, pose(o))\n")
    x = at(d, 15, 35, "type")
    assert "world" in x.hint


def test_untyped_rule_parameter_is_inferred(tmp_path):
    assert check(tmp_path, "rule r(o: block, P) : parent(o) = P -> parent(o) = P => same(pose(o), pose(o)')\n") == []


def test_untyped_rule_parameter_not_in_pattern(tmp_path):
    at(check(tmp_path, "rule r(o: block, X) : always => same(pose(o), pose(o))\n"), 15, 18, "missing-type")


def test_not_equal_in_pattern(tmp_path):
    d = check(tmp_path, "rule r(o: block, g: gripper) : parent(o) != g => same(pose(o), pose(o))\n")
    at(d, 15, 32, "pattern")


def test_comparison_in_pattern(tmp_path):
    d = check(tmp_path, "rule r(a: block, b: block) : a < b => same(pose(a), pose(b))\n")
    x = at(d, 15, 30, "pattern")
    assert "where" in x.hint


def test_state_fact_in_where(tmp_path):
    d = check(tmp_path, "rule r(o: block, g: gripper) where free(g) : always => same(pose(o), pose(o))\n")
    at(d, 15, 36, "where")


# ---------------------------------------------------------------- settings
def test_unknown_solver_setting(tmp_path):
    x = at(check(tmp_path, "solver { time_limt = 3 }\n"), 15, 10, "unknown-setting")
    assert x.hint == "did you mean 'time_limit'?"


def test_bad_solver_value(tmp_path):
    d = check(tmp_path, "solver { algorithm = gnp  switches = \"trx\"  seed = 1.5 }\n")
    at(d, 15, 22, "setting")
    at(d, 15, 38, "setting")
    at(d, 15, 52, "setting")


def test_unknown_tag_in_relaxation(tmp_path):
    x = at(check(tmp_path, "relaxations {\n  loose : drop robt, time\n}\n"), 16, 16, "unknown-tag")
    assert x.hint.startswith("did you mean 'robot'")


def test_reachability_checks(tmp_path):
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) { pre free(g) }
        reachability left {
          robot = g  samplez = 3
          heuristic pick(o, g) : travel(g, o)
          heuristic pik(o, g) : travel(g, o)
          warmstart pose(o)
        }
        """)
    at(d, 17, 14, "unknown-setting")
    at(d, 19, 13, "unknown-name")
    at(d, 20, 13, "unknown-name")


def test_reachability_needs_robot(tmp_path):
    at(check(tmp_path, "reachability left { samples = 3 }\n"), 15, 14, "setting")


# ---------------------------------------------------------------- problems
def test_problem_unknown_type_and_object(tmp_path):
    d = check(tmp_path, problem="""\
        problem p for d
        objects { b1 : blok  g : gripper }
        init { parent(b9) = g  holding(g) = none }
        goal { free(g) }
        """)
    at(d, 2, 16, "unknown-type", "p.pntc")
    x = at(d, 3, 15, "unknown-name", "p.pntc")
    assert x.hint is None or "b9" not in x.hint


def test_problem_missing_initial_value(tmp_path):
    d = check(tmp_path, problem="""\
        problem p for d
        objects { b1, b2 : block  s : place  g : gripper }
        init { parent(b1) = s }
        goal { free(g) }
        """)
    x = at(d, 3, 1, "init", "p.pntc")
    assert "parent(b2)" in x.message and "holding" not in x.message


def test_problem_duplicate_initial_value(tmp_path):
    d = check(tmp_path, problem="""\
        problem p for d
        objects { b1 : block  s : place  g : gripper }
        init { parent(b1) = s  parent(b1) = g }
        goal { free(g) }
        """)
    at(d, 3, 24, "duplicate", "p.pntc")


def test_problem_goal_not_equal(tmp_path):
    d = check(tmp_path, problem="""\
        problem p for d
        objects { b1 : block  s : place  g : gripper }
        init { parent(b1) = s }
        goal { parent(b1) != s }
        """)
    at(d, 4, 8, "goal", "p.pntc")


def test_problem_without_goal(tmp_path):
    d = check(tmp_path, problem="problem p for d\nobjects { g : gripper }\n")
    at(d, 1, 1, "goal", "p.pntc")


def test_problem_duplicate_object(tmp_path):
    d = check(tmp_path, problem="problem p for d\nobjects { g : gripper  g : block }\ngoal { free(g) }\n")
    at(d, 2, 24, "duplicate", "p.pntc")


def test_missing_domain(tmp_path):
    (tmp_path / "p.pntc").write_text("problem p for nowhere\ngoal { }\n")
    d = check_files([str(tmp_path / "p.pntc")]).reporter.diagnostics
    at(d, 1, 15, "missing-domain")


def test_domain_found_by_name_in_directory(tmp_path):
    (tmp_path / "blocks.pntc").write_text(BASE)
    (tmp_path / "p.pntc").write_text(PROBLEM)
    assert check_files([str(tmp_path / "p.pntc")]).reporter.diagnostics == []


def test_missing_scene_file(tmp_path):
    d = check(tmp_path, problem=PROBLEM + 'scene "nothere.yaml"\n')
    x = at(d, 5, 7, "missing-file", "p.pntc")
    assert "nothere.yaml" in x.message


def test_undeclared_scene_attribute_near_miss(tmp_path):
    scene = "dimension: 2\nobjects:\n  b1: {pose: [0, 0, 0], radios: 0.1}\n"
    d = check(tmp_path, problem=PROBLEM + 'scene "s.yaml"\n', files={"s.yaml": scene})
    x = at(d, 3, 25, "unknown-key", "s.yaml")
    assert x.hint == "did you mean 'radius'?"


# ---------------------------------------------------------------- remaining kinds
def test_type_union_in_action_parameter(tmp_path):
    at(check(tmp_path, "action a(x: block | place) { pre free(x) }\n"), 15, 21, "type-union")


def test_bool_combined_with_types(tmp_path):
    at(check(tmp_path, "state s(o: block) : bool | place\n"), 15, 21, "state-domain")


def test_negative_cost(tmp_path):
    at(check(tmp_path, "action a(g: gripper) { cost -1.5 }\n"), 15, 29, "cost")


def test_bad_waypoints(tmp_path):
    at(check(tmp_path, "traj w(g: gripper) : SE2 waypoints 1\n"), 15, 36, "waypoints")


def test_space_takes_no_argument(tmp_path):
    at(check(tmp_path, "continuous v(o: block) : SE2[3]\n"), 15, 26, "space")


def test_parameter_is_not_callable(tmp_path):
    d = check(tmp_path, """\
        template t(a: R) {
          a(1) == 1
        }
        """)
    at(d, 16, 3, "not-callable")


def test_with_substitutes_only_variables(tmp_path):
    d = check(tmp_path, """\
        template t(o: block, g: gripper) {
          (norm(pos(world(o))) with world(g) = [1, 2, 3]) >= 0
        }
        """)
    at(d, 16, 29, "with")


def test_type_cycle_position(tmp_path):
    d = check(tmp_path, "type a < b\ntype b < a\n")
    at(d, 15, 1, "cycle")


def test_module_name_must_match_file(tmp_path):
    (tmp_path / "m.pntc").write_text("module other\n")
    (tmp_path / "domain.pntc").write_text("domain d\nuse m\n")
    d = check_files([str(tmp_path / "domain.pntc")]).reporter.diagnostics
    at(d, 1, 8, "module-name", "m.pntc")


def test_use_of_a_domain_file(tmp_path):
    (tmp_path / "m.pntc").write_text("domain other\n")
    (tmp_path / "domain.pntc").write_text("domain d\nuse m\n")
    d = check_files([str(tmp_path / "domain.pntc")]).reporter.diagnostics
    at(d, 2, 5, "not-a-module")


def test_problem_given_as_domain(tmp_path):
    from gnppdsl.ir.resolve import Workspace

    (tmp_path / "p.pntc").write_text("problem p for d\n")
    ws = Workspace()
    assert ws.domain(tmp_path / "p.pntc") is None
    at(ws.reporter.diagnostics, 1, 1, "not-a-domain")
    ws2 = Workspace()
    (tmp_path / "domain.pntc").write_text(BASE)
    assert ws2.problem(tmp_path / "domain.pntc") is None
    at(ws2.reporter.diagnostics, 1, 1, "not-a-problem")


def test_wrong_domain(tmp_path):
    from gnppdsl.ir.resolve import Workspace

    (tmp_path / "domain.pntc").write_text(BASE)
    (tmp_path / "p.pntc").write_text("problem p for other\ngoal { }\n")
    ws = Workspace()
    assert ws.problem(tmp_path / "p.pntc", tmp_path / "domain.pntc") is None
    at(ws.reporter.diagnostics, 1, 15, "wrong-domain")


def test_file_kinds(tmp_path):
    (tmp_path / "notes.txt").write_text("hello")
    (tmp_path / "bad.pntc").write_bytes(b"domain d\ntype \xff\n")
    ds = check_files([str(tmp_path / "notes.txt"), str(tmp_path / "bad.pntc")]).reporter.diagnostics
    assert [d.kind for d in ds] == ["file-kind", "unreadable-file"]


def test_objects_missing_from_the_scene(tmp_path):
    scene = "dimension: 2\nobjects:\n  b1: {pose: [0, 0, 0]}\n  s1: {pose: [0, 0, 0]}\n"
    d = check(tmp_path, "type arm\ncontinuous j(r: arm) : joints(r)\n",
              problem=PROBLEM.replace("g : gripper }", "g : gripper  a : arm }") + 'scene "s.yaml"\n',
              files={"s.yaml": scene})
    msgs = sorted(x.message for x in d if x.kind == "scene-missing")
    assert [(x.span.line, x.span.column) for x in d if x.kind == "scene-missing"] == [(5, 7)] * 3
    assert msgs == ["object 'a' needs a robot in scene s.yaml (joints of 'j')",
                    "object 'b2' has no entry in scene s.yaml (it has a continuous variable 'pose')",
                    "object 'g' has no entry in scene s.yaml (it has a continuous variable 'q')"]


def test_given_domain_next_to_the_problem_wins(tmp_path):
    (tmp_path / "a").mkdir()
    (tmp_path / "b").mkdir()
    (tmp_path / "a" / "domain.pntc").write_text(BASE.replace("type gripper\n", "type gripper\ntype extra\n"))
    (tmp_path / "b" / "domain.pntc").write_text(BASE)
    (tmp_path / "b" / "p.pntc").write_text(PROBLEM.replace("goal { parent(b1) = g }", "goal { parent(b1) = g }\nobjects { e : extra }"))
    rep = check_files([str(tmp_path / "a" / "domain.pntc"), str(tmp_path / "b" / "domain.pntc"),
                       str(tmp_path / "b" / "p.pntc")])
    # b's domain has no type `extra`: the problem was checked against it, not against a's
    at(rep.reporter.diagnostics, 5, 15, "unknown-type", "p.pntc")


def test_module_exists_but_is_not_used(tmp_path):
    x = at(check(tmp_path, "rule r(o: block) : always => planar.same(pose(o), pose(o))\n"), 15, 30,
           "unknown-module")
    assert x.hint == "add `use planar`"


def test_unused_rule_parameter_is_a_warning(tmp_path):
    (tmp_path / "domain.pntc").write_text(BASE + "rule r(o: block, g: gripper) : always => same(pose(o), pose(o))\n")
    rep = check_files([str(tmp_path / "domain.pntc")])
    (w,) = rep.reporter.diagnostics
    assert (w.severity, w.kind, w.span.line, w.span.column) == ("warning", "unused", 15, 18)
    assert rep.ok and rep.summary() == "ok: 1 domain checked, 1 warning"
    assert "warning: parameter 'g' of rule 'r' is not used" in rep.render()


@pytest.mark.parametrize("cost, col, word", [
    ("norm(q(g))", 34, "continuous variable 'q'"),
    ("norm(pos(world(g)))", 38, "world pose"),
    ("[1, 2]", 29, "R[2]"),
    ("norm(pos(pose0(g)) - pos(pose0(g))) - 1", None, None),   # not constant: checked when compiled
])
def test_cost_expressions(tmp_path, cost, col, word):
    diags = check(tmp_path, f"action a(g: gripper) {{ cost {cost} }}\n")
    if col is None:
        assert not [d for d in diags if d.severity == "error"]
        return
    assert word in at(diags, 15, col, "cost").message


def test_disjunctive_goal_and_its_misuses(tmp_path):
    ok = check(tmp_path, problem="""\
        problem p for d
        objects { b1, b2 : block  s1 : place  g : gripper }
        init { parent(b1) = s1  parent(b2) = s1 }
        goal { parent(b1) = g or (parent(b2) = g and not free(g)), free(g) }
        """)
    assert [d for d in ok if d.severity == "error"] == []
    d = check(tmp_path, problem="""\
        problem p for d
        objects { b1, b2 : block  s1 : place  g : gripper }
        init { parent(b1) = s1 or parent(b1) = g  parent(b2) = s1 }
        goal { parent(b1) = g or parent(b2) != g }
        """)
    assert "no `or`" in at(d, 3, 8, "init", "p.pntc").message
    at(d, 4, 26, "goal", "p.pntc")
    assert not [x for x in d if "no value" in x.message]      # no follow-up error for parent(b1)


def test_travel_on_a_planar_scene(tmp_path):
    scene = """\
        name: s
        dimension: 2
        workspace: [[-1, -1], [1, 1]]
        robots:
          g: {kind: planar, home: [0, 0, 0], shape: {circle: 0.03}}
        objects:
          s1: {pose: [0.0, 0.0, 0.0]}
          b1: {shape: {circle: 0.05}, pose: [0.0, 0.0, 0.0]}
          b2: {shape: {circle: 0.05}, pose: [0.0, 0.0, 0.0]}
        """
    d = check(tmp_path, """\
        action pick(o: block, g: gripper) { pre holding(g) = none  eff holding(g) := o }
        reachability left {
          robot = g
          heuristic pick(o, g) : travel(g, o)
        }
        """, problem=PROBLEM.replace("problem p for d\n", 'problem p for d\nscene "s.yaml"\n'),
        files={"s.yaml": scene})
    x = at(d, 18, 3, "scene", "domain.pntc")
    assert "travel" in x.message and "planar" in x.message
