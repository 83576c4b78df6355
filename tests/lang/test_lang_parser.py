"""The parser: every grammar construct, the AST it produces, and syntax diagnostics.

`test_every_grammar_rule_is_exercised` parses the snippets below and the blocks of
docs/reference.md with the raw lark parser and checks that every rule / alias of
grammar/pntc.lark occurs in some tree: a construct added to the grammar without a test fails it.
"""
from __future__ import annotations

import re
from pathlib import Path

import pytest

from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter
from gnppdsl.lang.parser import _lark, parse_file, parse_text

ROOT = Path(__file__).resolve().parents[2]


def parse(text: str) -> ast.FileAst:
    r = Reporter()
    f = parse_text(text, "t.pntc", r)
    assert f is not None and not r.diagnostics, r.render()
    return f


def items(text: str, header: str = "domain d\n"):
    return parse(header + text).items


# ---------------------------------------------------------------- one test per construct
SNIPPETS: dict[str, str] = {
    "headers": "module m\n",
    "problem_header": "problem p for d\n",
    "use": "domain d\nuse planar, manipulation\n",
    "types": "domain d\ntype a\ntype b, c < a\n;\n",
    "const": "domain d\nconst k = 2 * pi / 3\nconst v = [1, -2, 3]\n",
    "constants": "domain d\nconstants { table : place  floor, wall : place; }\n",
    "state": "domain d\nstate parent(o: block) : place | gripper\nstate free(g: gripper) : bool\nstate frozen : bool\n",
    "derived": "domain d\nderived clear(x: place) := not exists o: block, p: place . parent(o) = x or (free(x) and not d2(x))\n",
    "action": """domain d
action pick(o: block, g: gripper) {
  pre parent(o) = g, holding(g) != none, a < b, clear(o) not free(g)
  eff parent(o) := g, free(g), not busy(g), when free(g) and not x(g) { holding(g) := o }
  cost 2
}
action noop() { }
""",
    "continuous": "domain d\ncontinuous pose(o: block) : SE2 tags object\ncontinuous t : R[3]\n"
                  "traj path(r: arm) : joints(r) waypoints 20 tags traj, robot\ntraj s(g: g) : SE2\n",
    "frame": "domain d\nframe o: block = world(parent(o)) * pose(o)\n",
    "template": """domain d
template t(a: R[3], p: SE3, q: joints, s: string, v: value, o: block) tags x y, z {
  a == [1, 2, 3]; 0 <= a[0] <= 1
  forall k in 0 .. waypoints(path(o)) - 2 { norm(path(o)[k+1] - path(o)[k]) <= 0.1 };
  (world(o) with q(o) = path(o)[k], p(o) = 2) >= -a[0:2] / 2 ^ 3
  planar.c * world(o)' >= fk(o, q(o), "tcp")
}
""",
    "scene_attr": "module m\nscene radius(o: object) : R\nprimitive fk(r: object, q: joints, f: string) : SE3\n",
    "rules": """domain d
rule a(o: block, P: place | gripper) : parent(o) = P -> parent(o) = P => m.same(pose(o), pose(o)') tags time
rule b(o, g) where o != g, o < g : parent(o) = g, not free(g) => grasp(o, g), grasp(g, o)
rule c(a: block) : always => n(a)
rule e(a: block) : initial => n(a) tags robot, traj
rule f : always => n()
""",
    "relaxations": "domain d\nrelaxations {\n  a : drop robot, collision\n  b : drop time;\n}\n",
    "solver": "domain d\nsolver { algorithm = gnpp, switches = \"trn\"; tolerance = 1e-6  seed = -1  w = [1, [2, 3]] }\n",
    "reachability": """domain d
reachability left {
  robot = left_arm  frame = "panda_hand_tcp"
  heuristic pick(o, r, from) : travel(r, o)
  heuristic noop() : travel()
  warmstart path(r);
}
""",
    "problem": """problem p for d
scene "p.yaml"
objects { b1, b2 : block  g : gripper }
init { parent(b1) = s1, parent(b2) = s2  free(g)  not busy(g) }
goal { parent(b1) = g }
""",
}


@pytest.mark.parametrize("name", sorted(SNIPPETS))
def test_snippet_parses(name):
    parse(SNIPPETS[name])


def test_header_kinds():
    assert parse("module m\n").header == ast.Header("module", ast.Name("m"))
    h = parse("problem p for dom\n").header
    assert (h.kind, h.name.value, h.domain.value) == ("problem", "p", "dom")


def test_type_declarations():
    a, b = items("type a\ntype b, c < a\n")
    assert [n.value for n in b.names] == ["b", "c"] and b.parent.value == "a" and a.parent is None


def test_state_declarations():
    p, f, z = items("state parent(o: block) : place | gripper\nstate free(g: gripper) : bool\nstate z : bool\n")
    assert [n.value for n in p.domain] == ["place", "gripper"]
    assert [x.value for x in p.params[0].types] == ["block"]
    assert [n.value for n in f.domain] == ["bool"] and z.params == ()


def test_formula_precedence_and_exists_scope():
    (d,) = items("derived x(a: t) := p(a) or q(a) and not r(a) or exists z: t . s(z) and u(z)\n")
    body = d.body
    assert isinstance(body, ast.FOr) and len(body.items) == 3
    assert isinstance(body.items[1], ast.FAnd)
    assert isinstance(body.items[1].items[1], ast.FNot)
    ex = body.items[2]
    assert isinstance(ex, ast.FExists) and isinstance(ex.body, ast.FAnd)   # body extends right


def test_action_parts():
    (a,) = items(SNIPPETS["action"].split("\n", 1)[1].rsplit("action noop", 1)[0])
    assert [l.kind for l in a.pre] == ["cmp", "cmp", "cmp", "atom", "not"]
    assert [l.op for l in a.pre[:3]] == ["=", "!=", "<"]
    kinds = [type(e).__name__ for e in a.effects]
    assert kinds == ["EffAssign", "EffBool", "EffBool", "EffWhen"]
    assert a.effects[2].value is False and a.cost.value == 2


def test_continuous_and_traj():
    c, t = items("continuous pose(o: block) : SE2 tags object\n"
                 "traj path(r: arm) : joints(r) waypoints 20 tags traj robot\n")
    assert not c.traj and c.space.name.value == "SE2" and [x.value for x in c.tags] == ["object"]
    assert t.traj and t.waypoints.value == 20 and t.space.arg.value == "r"
    assert [x.value for x in t.tags] == ["traj", "robot"]


def test_expression_precedence():
    (t,) = items("template t(a: R) { -a ^ 2 * 3 + 4 / a - 1 == a'[0] }\n")
    (c,) = t.body
    lhs = c.operands[0]
    # ((((-(a^2)) * 3) + (4 / a)) - 1)
    assert isinstance(lhs, ast.EBin) and lhs.op == "-"
    plus = lhs.lhs
    assert plus.op == "+" and plus.rhs.op == "/"
    times = plus.lhs
    assert times.op == "*" and isinstance(times.lhs, ast.ENeg) and times.lhs.arg.op == "^"
    rhs = c.operands[1]
    assert isinstance(rhs, ast.EIndex) and isinstance(rhs.base, ast.EPrime)


def test_chained_constraint_and_with():
    (t,) = items("template t(a: R) { 0 <= a <= 1\n (f(a) with q(r) = p(r)[k]) >= 0 }\n")
    c1, c2 = t.body
    assert [o.value for o in c1.ops] == ["<=", "<="] and len(c1.operands) == 3
    w = c2.operands[0]
    assert isinstance(w, ast.EWith) and len(w.substs) == 1


def test_statements_without_separator_juxtapose():
    """`a == b` followed by `(c) ...` reads as a call `b(c)`: documented, needs `;`."""
    (t,) = items("template t(a: R) { a == b; (a) <= 1 }\n")
    assert len(t.body) == 2
    (t,) = items("template t(a: R) { a == b (a) <= 1 }\n")
    assert len(t.body) == 1 and isinstance(t.body[0].operands[1], ast.ECall)


def test_rule_forms():
    rs = items(SNIPPETS["rules"].split("\n", 1)[1])
    assert [r.kind for r in rs] == ["transition", "state", "always", "initial", "always"]
    a, b = rs[0], rs[1]
    assert a.calls[0].text == "m.same" and [t.value for t in a.tags] == ["time"]
    assert [p.types for p in b.params] == [(), ()] and len(b.where) == 2 and len(b.calls) == 2
    assert [l.kind for l in b.pre] == ["cmp", "not"]


def test_settings_values():
    (s,) = items('solver { a = gnpp  b = "x"  c = 1e-6  d = -2  e = [1, [2, 3]] }\n')
    vals = {x.key.value: x.value.plain() for x in s.settings}
    assert vals == {"a": "gnpp", "b": "x", "c": 1e-6, "d": -2, "e": [1, [2, 3]]}


def test_reachability_block():
    (r,) = items(SNIPPETS["reachability"].split("\n", 1)[1])
    assert {s.key.value for s in r.settings} == {"robot", "frame"}      # `frame` is a plain key here
    h = r.heuristics[0]
    assert (h.action.value, [p.value for p in h.params], h.measure.value, [a.value for a in h.args]) == \
        ("pick", ["o", "r", "from"], "travel", ["r", "o"])
    assert r.warmstarts[0].traj.value == "path"


def test_problem_sections():
    f = parse(SNIPPETS["problem"])
    scene, objs, init, goal = f.items
    assert scene.path == "p.yaml"
    assert [([n.value for n in g.names], g.type.value) for g in objs.groups] == [(["b1", "b2"], "block"), (["g"], "gripper")]
    assert [l.kind for l in init.lits] == ["cmp", "cmp", "atom", "not"]
    assert len(goal.lits) == 1


def test_spans_point_at_the_text():
    f = parse("domain d\n\ntemplate t(a: R) {\n  a   ==  nrm(a)\n}\n")
    (t,) = f.items
    call = t.body[0].operands[1]
    assert (call.span.line, call.span.column, call.span.end_column) == (4, 11, 17)
    assert (t.name.span.line, t.name.span.column) == (3, 10)


def test_keyword_is_a_name_where_no_declaration_can_start():
    # `waypoints` is the traj keyword and also a function; `frame` a key in reachability
    (t,) = items("template t(r: object) { waypoints(path(r)) >= 2 }\n")
    assert t.body[0].operands[0].text == "waypoints"


# ---------------------------------------------------------------- syntax diagnostics
def syntax_errors(text: str):
    r = Reporter()
    assert parse_text(text, "t.pntc", r) is None
    return r.diagnostics


def test_unexpected_token_position_and_hint():
    (d,) = syntax_errors("domain d\ntype a b\n")
    assert (d.kind, d.span.line, d.span.column) == ("syntax", 2, 8)
    assert d.message == "unexpected 'b'" and "a declaration" in d.hint


def test_unexpected_character():
    (d,) = syntax_errors("domain d\nstate s(x: a) : a $\n")
    assert (d.span.line, d.span.column, d.message) == (2, 19, "unexpected character '$'")


def test_unterminated_string():
    (d,) = syntax_errors('domain d\nreachability r { frame = "abc\n}\n')
    assert (d.span.line, d.span.column) == (2, 26) and "double quotes" in d.hint


def test_unexpected_end_of_file():
    (d,) = syntax_errors("domain d\ntemplate t(a: R) {\n  a == 1\n")
    assert d.message == "unexpected end of file" and (d.span.line, d.span.column) == (3, 9)


def test_reserved_word_where_no_declaration_can_start_is_a_name():
    (s,) = items("state traj(o: object) : bool\n")
    assert s.name.value == "traj"


def test_keyword_in_space_separated_tags_hint():
    ds = syntax_errors("domain d\ncontinuous p(o: block) : SE2 tags robot traj\nframe o: block = p(o)\n")
    d = ds[0]
    assert (d.span.line, d.span.column) == (3, 7)
    assert "tags robot, traj" in d.hint


def test_or_and_in_a_list_of_facts_hint():
    (d,) = syntax_errors("domain d\naction a(g: g) {\n  pre free(g) or full(g)\n}\n")
    assert (d.span.line, d.span.column) == (3, 15) and "derived NAME(...) := a or b" in d.hint
    (d,) = syntax_errors("domain d\nrule r(g: g) : free(g) and full(g) => t(g)\n")
    assert (d.span.line, d.span.column) == (2, 24) and "separated by `,`" in d.hint


def test_goal_facts_combine_with_or_and_parentheses():
    (f,) = items("goal { a(x) = y or (b(x) and not c(x)), d(x) }\n", header="problem p for d\n")
    first, second = f.lits
    assert type(first).__name__ == "FOr" and type(first.items[1]).__name__ == "FAnd"
    assert type(second).__name__ == "Lit"


def test_missing_header():
    (d,) = syntax_errors("type a\n")
    assert (d.span.line, d.span.column) == (1, 1)


def test_several_syntax_errors_in_one_run():
    text = "domain d\ntype a b\nstate s(x: a) : a\naction p(x: a) { pre s(x) = = }\nrule r : always => \n"
    ds = syntax_errors(text)
    assert [(d.span.line, d.span.column) for d in ds] == [(2, 8), (4, 29), (5, 20)]


def test_missing_file_is_a_diagnostic(tmp_path):
    r = Reporter()
    assert parse_file(tmp_path / "nope.pntc", r) is None
    assert r.diagnostics[0].kind == "missing-file"


def test_diagnostic_rendering():
    (d,) = syntax_errors("domain d\ntype a b\n")
    r = Reporter()
    parse_text("domain d\ntype a b\n", "t.pntc", r)
    text = r.render()
    assert text.splitlines()[:3] == ["t.pntc:2:8: error: unexpected 'b'", " 2 | type a b",
                                     "   |        ^"]
    assert text.splitlines()[3].startswith("hint: ")


# ---------------------------------------------------------------- grammar coverage
def _tree_names(tree, out: set) -> None:
    from lark import Tree

    if isinstance(tree, Tree):
        out.add(tree.data)
        for c in tree.children:
            _tree_names(c, out)


def test_every_grammar_rule_is_exercised():
    parser = _lark()
    expected = set()
    for rule in parser.rules:
        name = rule.alias or rule.origin.name
        name = getattr(name, "name", name)
        if rule.alias is None and (rule.options.expand1 or str(name).startswith("_")):
            continue
        expected.add(str(name))
    corpus = list(SNIPPETS.values())
    doc = (ROOT / "docs" / "reference.md").read_text()
    for block in re.findall(r"^```pntc\n(.*?)^```", doc, re.M | re.S):
        first = next((l for l in block.splitlines() if l.split("#")[0].strip()), "")
        corpus.append(block if re.match(r"(domain|problem|module)\b", first) else "domain d\n" + block)
    seen: set = set()
    for text in corpus:
        _tree_names(parser.parse(text, start="file"), seen)
    _tree_names(parser.parse("type a", start="items"), seen)
    missing = expected - {str(s) for s in seen}
    assert not missing, f"grammar rules never exercised: {sorted(missing)}"


def test_examples_and_stdlib_parse():
    files = sorted((ROOT / "stdlib").glob("*.pntc")) + sorted((ROOT / "examples").glob("*/*.pntc"))
    assert files
    for f in files:
        r = Reporter()
        assert parse_file(f, r) is not None, r.render()
