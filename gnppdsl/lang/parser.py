"""Parse .pntc text into `gnppdsl.lang.ast` with spans; syntax errors become diagnostics.

Why these choices:
- lark's LALR parser with a cached table (`cache=True`): building the table takes ~0.1 s, loading
  it from the cache a few ms, and parsing is linear -- `gnpp check` must finish in well under 1 s.
- Error recovery: after a syntax error the parser resumes at the next line that starts with a
  declaration keyword (start symbol `items`, text before it blanked so line numbers stay
  right), so one run reports the syntax errors of several declarations.
"""
from __future__ import annotations

import re
from contextlib import contextmanager
from functools import lru_cache
from pathlib import Path
from typing import Iterator

from gnppdsl.lang.span import Span
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter

MAX_SYNTAX_ERRORS = 20
#: deepest parse tree accepted (brackets, parentheses, prefix operators, chains of `+`, `and`,
#: `[i]` each add a level). The bundled files reach 14; the transformer, the resolvers, the
#: type checker and the casadi lowering recurse once or a few times per level, so a bound far
#: below Python's recursion limit turns 1,000 nested `[` into a located message, not a
#: RecursionError (tests/lang/test_lang_limits.py checks every stage at this depth).
MAX_NESTING = 100
#: largest `R[n]`
MAX_VECTOR_DIMENSION = 10_000

# words that start a declaration (used for error recovery and keyword hints)
DECL_KEYWORDS = (
    "domain", "problem", "module", "use", "type", "const", "constants", "state", "derived",
    "action", "continuous", "traj", "frame", "template", "rule", "relaxations", "solver", "avoid",
    "reachability", "scene", "primitive", "objects", "init", "goal",
)
_DECL_LINE = re.compile(r"^\s*(%s)\b" % "|".join(DECL_KEYWORDS))

_TERMINAL_NAMES = {
    "NAME": "a name", "NUMBER": "a number", "STRING": "a string", "$END": "end of file",
}


@lru_cache(maxsize=1)
def _lark():
    """The LALR parser (built once per process; tables cached on disk by lark)."""
    from lark import Lark

    from gnppdsl.resources import grammar_dir

    path = grammar_dir() / "pntc.lark"
    text = path.read_text(encoding="utf-8")
    try:
        return Lark(text, parser="lalr", start=["file", "items"], propagate_positions=True,
                    maybe_placeholders=True, cache=True)
    except (OSError, PermissionError):  # read-only temp dir: build without the cache
        return Lark(text, parser="lalr", start=["file", "items"], propagate_positions=True,
                    maybe_placeholders=True)


@lru_cache(maxsize=1)
def keywords() -> frozenset[str]:
    """Reserved words of the grammar (string terminals that look like names)."""
    words = set()
    for term in _lark().terminals:
        pat = term.pattern
        if pat.type == "str" and re.fullmatch(r"[A-Za-z_]\w*", pat.value):
            words.add(pat.value)
    return frozenset(words)


def _terminal_text(name: str) -> str:
    if name in _TERMINAL_NAMES:
        return _TERMINAL_NAMES[name]
    try:
        term = _lark().get_terminal(name)
    except KeyError:
        return name
    return f"'{term.pattern.value}'" if term.pattern.type == "str" else name


# ----------------------------------------------------------------------------------------
# Tree -> AST
# ----------------------------------------------------------------------------------------
class _Params(tuple):
    pass


class _Sig(tuple):
    pass


class _Tags(tuple):
    pass


class _Where(tuple):
    pass


class _Calls(tuple):
    pass


class _NameList(tuple):
    pass


class _Supertype(ast.Name):
    pass


def _make_transformer(path: str, problems: list):
    """The lark Transformer to the AST. Values a token cannot hold (a number that overflows
    a float, `R[1e400]`) are appended to `problems` as (span, message, hint) and replaced by
    a harmless value, so a file gets one located diagnostic per bad literal."""
    from lark import Token, Transformer, v_args

    def sp(meta) -> Span | None:
        if getattr(meta, "empty", True):
            return None
        return Span(path, meta.line, meta.column, meta.end_line, meta.end_column)

    def tok_span(t: Token) -> Span:
        return Span(path, t.line, t.column, t.end_line, t.end_column)

    def name(t: Token) -> ast.Name:
        return ast.Name(str(t), tok_span(t))

    def _lname(x) -> ast.Name | ast.IndexedName:
        return x if isinstance(x, ast.IndexedName) else name(x)

    def real(children):
        return [c for c in children if c is not None]

    def finite(t: Token) -> float:
        v = float(t)
        if v != v or v in (float("inf"), float("-inf")):
            problems.append((tok_span(t), f"number {_short(str(t))} is out of range",
                             "numbers must fit a 64-bit float (at most about 1.8e308)"))
            return 0.0
        return v

    def num(t: Token) -> ast.ENum:
        return ast.ENum(finite(t), str(t), tok_span(t))

    def setting_number(t: Token) -> int | float:
        text = str(t)
        if re.fullmatch(r"[0-9]+", text) and len(text) <= 18:
            return int(text)
        return finite(t)

    @v_args(meta=True)
    class ToAst(Transformer):
        # ---- files
        def file(self, m, c):
            return (c[0], tuple(real(c[1:])))

        def items(self, m, c):
            return (None, tuple(real(c)))

        def domain_header(self, m, c):
            return ast.Header("domain", name(c[0]), None, sp(m))

        def problem_header(self, m, c):
            return ast.Header("problem", name(c[0]), name(c[1]), sp(m))

        def module_header(self, m, c):
            return ast.Header("module", name(c[0]), None, sp(m))

        def empty(self, m, c):
            return None

        # ---- modules and types
        def use_decl(self, m, c):
            return ast.UseDecl(tuple(name(t) for t in c), sp(m))

        def supertype(self, m, c):
            return _Supertype(str(c[0]), tok_span(c[0]))

        def type_decl(self, m, c):
            parent = c[-1] if isinstance(c[-1], _Supertype) else None
            names = [name(t) for t in c if isinstance(t, Token)]
            return ast.TypeDecl(tuple(names), ast.Name(parent.value, parent.span) if parent else None, sp(m))

        def const_decl(self, m, c):
            return ast.ConstDecl(name(c[0]), c[1], sp(m))

        def obj_range(self, m, c):
            return ast.ObjRange(name(c[0]), name(c[1]), sp(m))

        def obj_group(self, m, c):
            return ast.ObjGroup(tuple(x if isinstance(x, ast.ObjRange) else name(x) for x in c[:-1]),
                                name(c[-1]), sp(m))

        def constants_decl(self, m, c):
            return ast.ConstantsDecl(tuple(c), sp(m))

        def objects_decl(self, m, c):
            return ast.ObjectsDecl(tuple(c), sp(m))

        # ---- logic
        def params(self, m, c):
            return _Params(real(c))

        def param(self, m, c):
            return ast.Param(name(c[0]), tuple(name(t) for t in c[1:]), sp(m))

        def state_decl(self, m, c):
            params = c[1] if len(c) > 1 and isinstance(c[1], _Params) else _Params()
            rest = [t for t in c[1:] if isinstance(t, Token)]
            return ast.StateDecl(name(c[0]), tuple(params), tuple(name(t) for t in rest), sp(m))

        def derived_decl(self, m, c):
            params = c[1] if isinstance(c[1], _Params) else _Params()
            return ast.DerivedDecl(name(c[0]), tuple(params), c[-1], sp(m))

        def pre(self, m, c):
            return ("pre", c[0], sp(m))

        def eff(self, m, c):
            return ("eff", c[0], sp(m))

        def cost(self, m, c):
            return ("cost", c[0], sp(m))

        def action_decl(self, m, c):
            params = c[1] if len(c) > 1 and isinstance(c[1], _Params) else _Params()
            parts = [p for p in c[1:] if isinstance(p, tuple) and not isinstance(p, _Params)]
            pre: list = []
            effs: list = []
            cost = None
            seen: set[str] = set()
            dups = []
            for kind, val, span in parts:
                if kind in seen:
                    dups.append(ast.Name(kind, span))
                seen.add(kind)
                if kind == "pre":
                    pre.extend(val)
                elif kind == "eff":
                    effs.extend(val)
                else:
                    cost = val
            return ast.ActionDecl(name(c[0]), tuple(params), tuple(pre), tuple(effs), cost,
                                  tuple(dups), sp(m))

        def lname(self, m, c):
            return ast.LTerm(_lname(c[0]), None, sp(m))

        def lapp(self, m, c):
            return ast.LTerm(_lname(c[0]), tuple(real(c[1:])), sp(m))

        def indexed_name(self, m, c):
            return ast.IndexedName(name(c[0]), c[1], sp(m))

        # ---- init / goal facts
        def fact_list(self, m, c):
            return tuple(c)

        def type_binder(self, m, c):
            return ast.TypeBinder(name(c[0]), tuple(name(t) for t in c[1:]), sp(m))

        def index_binder(self, m, c):
            return ast.IndexBinder(name(c[0]), num(c[1]), num(c[2]), sp(m))

        def fact_forall(self, m, c):
            return ast.FactForall(tuple(c[:-1]), (c[-1],), sp(m))

        def fact_forall_block(self, m, c):
            return ast.FactForall(tuple(c[:-1]), tuple(c[-1]), sp(m))

        def lop(self, m, c):
            return name(c[0])

        def lit_atom(self, m, c):
            return ast.Lit("atom", c[0], None, None, sp(m))

        def lit_not(self, m, c):
            return ast.Lit("not", c[0], None, None, sp(m))

        def lit_cmp(self, m, c):
            return ast.Lit("cmp", c[0], c[1].value, c[2], sp(m))

        def lit_list(self, m, c):
            return tuple(c)

        def effect_list(self, m, c):
            return tuple(c)

        def eff_assign(self, m, c):
            return ast.EffAssign(c[0], c[1], sp(m))

        def eff_true(self, m, c):
            return ast.EffBool(c[0], True, sp(m))

        def eff_false(self, m, c):
            return ast.EffBool(c[0], False, sp(m))

        def eff_when(self, m, c):
            return ast.EffWhen(c[0], tuple(c[1]), sp(m))

        def f_or(self, m, c):
            items = []
            for x in c:
                items.extend(x.items if isinstance(x, ast.FOr) else (x,))
            return ast.FOr(tuple(items), sp(m))

        def f_and(self, m, c):
            items = []
            for x in c:
                items.extend(x.items if isinstance(x, ast.FAnd) else (x,))
            return ast.FAnd(tuple(items), sp(m))

        fact_or = f_or          # `or` / `and` between goal facts: the same AST as in formulas
        fact_and = f_and

        def f_not(self, m, c):
            return ast.FNot(c[0], sp(m))

        def f_exists(self, m, c):
            return ast.FExists(tuple(c[:-1]), c[-1], sp(m))

        # ---- continuous
        def space_name(self, m, c):
            return ast.SpaceAst(name(c[0]), None, None, sp(m))

        def space_vec(self, m, c):
            before = len(problems)
            v = finite(c[1])
            if len(problems) > before:           # one diagnostic per literal
                v = 1
            elif v != int(v) or not 1 <= v <= MAX_VECTOR_DIMENSION:
                problems.append((tok_span(c[1]), f"vector dimension {_short(str(c[1]))} is not a "
                                 f"whole number from 1 to {MAX_VECTOR_DIMENSION:,}", None))
                v = 1
            return ast.SpaceAst(name(c[0]), int(v), None, sp(m))

        def space_app(self, m, c):
            return ast.SpaceAst(name(c[0]), None, name(c[1]), sp(m))

        def tags(self, m, c):
            return _Tags(name(t) for t in c)

        def waypoints(self, m, c):
            return num(c[0])

        def _cont(self, m, c, traj):
            params = _Params()
            tags = _Tags()
            space = None
            wp = None
            for x in c[1:]:
                if isinstance(x, _Params):
                    params = x
                elif isinstance(x, _Tags):
                    tags = x
                elif isinstance(x, ast.SpaceAst):
                    space = x
                elif isinstance(x, ast.ENum):
                    wp = x
            return ast.ContinuousDecl(name(c[0]), tuple(params), space, tuple(tags), traj, wp, sp(m))

        def continuous_decl(self, m, c):
            return self._cont(m, c, False)

        def traj_decl(self, m, c):
            return self._cont(m, c, True)

        def frame_decl(self, m, c):
            return ast.FrameDecl(name(c[0]), name(c[1]), c[2], sp(m))

        # ---- templates
        def sig_params(self, m, c):
            return _Sig(real(c))

        def sig_param(self, m, c):
            return ast.SigParam(name(c[0]), c[1], sp(m))

        def template_decl(self, m, c):
            tags = _Tags()
            body = []
            for x in c[2:]:
                if isinstance(x, _Tags):
                    tags = x
                else:
                    body.append(x)
            return ast.TemplateDecl(name(c[0]), tuple(c[1]), tuple(tags), tuple(body), sp(m))

        def scene_attr_decl(self, m, c):
            return ast.SceneAttrDecl(name(c[0]), tuple(c[1]), c[2], sp(m))

        def primitive_decl(self, m, c):
            return ast.PrimitiveDecl(name(c[0]), tuple(c[1]), c[2], sp(m))

        def cop(self, m, c):
            return name(c[0])

        def constraint(self, m, c):
            operands = tuple(x for x in c if not isinstance(x, ast.Name))
            ops = tuple(x for x in c if isinstance(x, ast.Name))
            return ast.ConstraintAst(operands, ops, sp(m))

        def minimize(self, m, c):
            return ast.MinimizeAst(c[0], sp(m))

        def forall(self, m, c):
            return ast.ForallAst(name(c[0]), c[1], c[2], tuple(c[3:]), sp(m))

        def with_expr(self, m, c):
            return ast.EWith(c[0], tuple(c[1:]), sp(m))

        def subst(self, m, c):
            return (c[0], c[1])

        def _bin(op):
            def f(self, m, c):
                return ast.EBin(op, c[0], c[1], sp(m))
            return f

        add = _bin("+")
        sub = _bin("-")
        mul = _bin("*")
        div = _bin("/")
        pow = _bin("^")

        def neg(self, m, c):
            return ast.ENeg(c[0], sp(m))

        def prime(self, m, c):
            return ast.EPrime(c[0], sp(m))

        def index(self, m, c):
            return ast.EIndex(c[0], c[1], None, sp(m))

        def slice(self, m, c):
            return ast.EIndex(c[0], c[1], c[2], sp(m))

        def number(self, m, c):
            return num(c[0])

        def string(self, m, c):
            return ast.EStr(str(c[0])[1:-1], tok_span(c[0]))

        def qname(self, m, c):
            return tuple(name(t) for t in c)

        def ref(self, m, c):
            return ast.ERef(c[0], sp(m))

        def call(self, m, c):
            return ast.ECall(c[0], tuple(real(c[1:])), sp(m))

        def vector(self, m, c):
            return ast.EVec(tuple(real(c)), sp(m))

        # ---- rules
        def where(self, m, c):
            return _Where(c)

        def pat_always(self, m, c):
            return ("always", (), (), sp(m))

        def pat_always_transition(self, m, c):
            # every transition i -> i+1: a transition rule with empty partial states
            return ("transition", (), (), sp(m))

        def pat_initial(self, m, c):
            return ("initial", (), (), sp(m))

        def pat_final(self, m, c):
            # the last state of the plan (compiled to a derived variable: the goal holds)
            return ("final", (), (), sp(m))

        def pat_state(self, m, c):
            return ("state", c[0], (), sp(m))

        def pat_transition(self, m, c):
            return ("transition", c[0], c[1], sp(m))

        def pat_lits(self, m, c):
            return tuple(c)

        def call_list(self, m, c):
            return _Calls(c)

        def tcall(self, m, c):
            return ast.TCall(c[0], tuple(real(c[1:])), sp(m))

        def rule_decl(self, m, c):
            params, where, tags, calls, pattern = _Params(), _Where(), _Tags(), _Calls(), None
            for x in c[1:]:
                if isinstance(x, _Params):
                    params = x
                elif isinstance(x, _Where):
                    where = x
                elif isinstance(x, _Tags):
                    tags = x
                elif isinstance(x, _Calls):
                    calls = x
                else:
                    pattern = x
            kind, pre, post, pspan = pattern
            return ast.RuleDecl(name(c[0]), tuple(params), tuple(where), kind, tuple(pre),
                                tuple(post), tuple(calls), tuple(tags), pspan, sp(m))

        # ---- settings
        def relaxation(self, m, c):
            return ast.RelaxationAst(name(c[0]), tuple(name(t) for t in c[1:]), sp(m))

        def relaxations_decl(self, m, c):
            return ast.RelaxationsDecl(tuple(c), sp(m))

        def avoid_decl(self, m, c):
            names = tuple(name(t) for t in c if isinstance(t, Token))
            margin = next((x for x in c if not isinstance(x, Token)), None)
            return ast.AvoidDecl(names, margin, sp(m))

        def setting(self, m, c):
            return ast.Setting(name(c[0]), c[1], sp(m))

        def solver_decl(self, m, c):
            return ast.SolverDecl(tuple(c), sp(m))

        def v_number(self, m, c):
            return ast.Value(setting_number(c[0]), "number", sp(m))

        def v_negative(self, m, c):
            return ast.Value(-setting_number(c[0]), "number", sp(m))

        def v_string(self, m, c):
            return ast.Value(str(c[0])[1:-1], "string", sp(m))

        def v_name(self, m, c):
            return ast.Value(str(c[0]), "name", sp(m))

        def v_list(self, m, c):
            return ast.Value(tuple(real(c)), "list", sp(m))

        def name_list(self, m, c):
            return _NameList(name(t) for t in real(c))

        def heuristic(self, m, c):
            return ast.HeuristicAst(name(c[0]), tuple(c[1]), name(c[2]), tuple(c[3]), sp(m))

        def warmstart(self, m, c):
            return ast.WarmstartAst(name(c[0]), tuple(c[1]), sp(m))

        def reachability_decl(self, m, c):
            settings = tuple(x for x in c[1:] if isinstance(x, ast.Setting))
            heur = tuple(x for x in c[1:] if isinstance(x, ast.HeuristicAst))
            warm = tuple(x for x in c[1:] if isinstance(x, ast.WarmstartAst))
            return ast.ReachabilityDecl(name(c[0]), settings, heur, warm, sp(m))

        # ---- problems
        def scene_ref(self, m, c):
            return ast.SceneRef(str(c[0])[1:-1], tok_span(c[0]))

        def init_decl(self, m, c):
            return ast.InitDecl(tuple(c[0]), sp(m))

        def goal_decl(self, m, c):
            return ast.GoalDecl(tuple(c[0]), sp(m))

    return ToAst()


def _short(text: str, n: int = 24) -> str:
    """A literal as quoted in a message: a 5,000-digit number shows its first digits only."""
    return text if len(text) <= n else f"{text[:n]}... ({len(text):,} characters)"


def _too_deep(tree) -> object | None:
    """The first node deeper than `MAX_NESTING` (iterative: this is what guards recursion)."""
    from lark import Tree

    stack = [(tree, 1)]
    while stack:
        node, depth = stack.pop()
        if depth > MAX_NESTING:
            return node
        if isinstance(node, Tree):
            stack.extend((c, depth + 1) for c in node.children)
    return None


def _node_span(node, path: str) -> Span:
    """Where a tree node or token starts (its first token when the node has no position)."""
    from lark import Tree

    while isinstance(node, Tree) and getattr(node.meta, "empty", True) and node.children:
        node = node.children[0]
    meta = node.meta if isinstance(node, Tree) else node
    line = getattr(meta, "line", None) or 1
    col = getattr(meta, "column", None) or 1
    return Span(path, line, col, getattr(meta, "end_line", None), getattr(meta, "end_column", None))


# ----------------------------------------------------------------------------------------
# Entry points
# ----------------------------------------------------------------------------------------
def _syntax_diagnostic(err, path: str, text: str, reporter: Reporter) -> int:
    """Report one lark error; return the line where it happened."""
    from lark.exceptions import UnexpectedCharacters, UnexpectedEOF, UnexpectedToken

    if isinstance(err, UnexpectedToken):
        tok = err.token
        line = getattr(tok, "line", None) or err.line
        col = getattr(tok, "column", None) or err.column
        if tok.type == "$END" or line is None or line < 1:
            lines = text.splitlines() or [""]
            line, col = len(lines), len(lines[-1]) + 1
            span = Span(path, line, col)
            msg = "unexpected end of file"
        else:
            span = Span(path, line, col, tok.end_line, tok.end_column)
            msg = f"unexpected '{tok.value}'"
        expected = sorted({_terminal_text(t) for t in err.expected if not t.startswith("__ANON")}
                          | {_terminal_text(t) for t in err.expected if t.startswith("__ANON")})
        hint = _tags_hint(text, getattr(tok, "start_pos", None))
        if hint is not None:
            pass
        elif tok.type != "$END" and str(tok.value) in ("or", "and"):
            # `pre a or b`, `: p or q =>`: lists of facts here are conjunctions
            hint = (f"'{tok.value}' combines facts only in `derived` bodies and goals; here the "
                    + ("facts are a list (all must hold): for a disjunction declare "
                       "`derived NAME(...) := a or b` and use NAME(...)" if tok.value == "or"
                       else "facts are a list separated by `,` (all must hold)"))
        elif tok.type != "$END" and str(tok.value) in keywords() and "NAME" in err.expected:
            hint = (f"'{tok.value}' is a reserved word and cannot be used as a name here"
                    + ("; separate tags with commas" if tok.value in DECL_KEYWORDS else ""))
        elif expected:
            decls = [e for e in expected if e.strip("'") in DECL_KEYWORDS]
            if len(decls) >= 3:
                expected = [e for e in expected if e not in decls] + ["a declaration"]
            shown = expected if len(expected) <= 8 else expected[:8] + ["..."]
            hint = "expected " + (shown[0] if len(shown) == 1 else "one of: " + ", ".join(shown))
        reporter.error(span, msg, "syntax", hint)
        return line
    if isinstance(err, UnexpectedCharacters):
        ch = text[err.pos_in_stream] if 0 <= err.pos_in_stream < len(text) else "?"
        shown = ch if ch.isprintable() else f"U+{ord(ch):04X}"
        hint = None
        if ch == '"':
            hint = "strings are written in double quotes and end on the same line"
        elif ch in "{}":
            hint = "check the braces of the enclosing block"
        reporter.error(Span(path, err.line, err.column, err.line, err.column + 1),
                       f"unexpected character '{shown}'", "syntax", hint)
        return err.line
    if isinstance(err, UnexpectedEOF):
        lines = text.splitlines() or [""]
        reporter.error(Span(path, len(lines), len(lines[-1]) + 1), "unexpected end of file", "syntax")
        return len(lines)
    raise err


_TAGS_TAIL = re.compile(r"\btags\s+\w+(?:\s*,?\s*\w+)*\s*$")


def _tags_hint(text: str, pos: int | None) -> str | None:
    """`tags robot traj` + a newline: `traj` was read as the start of a trajectory declaration.
    Detect a reserved word inside a space-separated tag list shortly before the error."""
    if pos is None or pos < 0:
        return None
    before = text[:pos]
    lines = before.splitlines()[-3:]
    for line in reversed(lines):
        code = line.split("#", 1)[0]
        m = re.search(r"\btags\s+([\w\s,]*)$", code)
        if not m:
            continue
        words = re.findall(r"\w+", m.group(1))
        bad = [w for w in words[1:] if w in DECL_KEYWORDS]
        if bad:
            return (f"'{bad[0]}' starts a new declaration; separate tags with commas "
                    f"(`tags {', '.join(words)}`)")
    return None


# ----------------------------------------------------------------------------------------
# AST cache: unchanged files (the standard library above all) are not re-parsed
# ----------------------------------------------------------------------------------------
_CACHE_VERSION = "3"          # 2: JSON (gnppdsl.lang.ast_json) instead of pickle; 3: with layout warnings


@lru_cache(maxsize=1)
def _cache_dir() -> Path | None:
    """~/.cache/gnppdsl/ast, private to the user (0700), or None (GNPP_NO_CACHE, not ours)."""
    import os

    from gnppdsl.outputs import private_dir

    if os.environ.get("GNPP_NO_CACHE"):
        return None
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    root = private_dir(Path(base) / "gnppdsl")
    return private_dir(root / "ast") if root is not None else None


@lru_cache(maxsize=1)
def _grammar_signature() -> str:
    import hashlib

    from gnppdsl.lang import ast_json, lint, span
    from gnppdsl.resources import grammar_dir

    h = hashlib.sha1(_CACHE_VERSION.encode())
    h.update((grammar_dir() / "pntc.lark").read_bytes())
    # Span lives in span; the cached layout warnings are lint's
    for module in (__file__, ast.__file__, span.__file__, ast_json.__file__, lint.__file__):
        h.update(Path(module).read_bytes())
    return h.hexdigest()


def _cache_key(text: str, path: str) -> str:
    import hashlib

    return hashlib.sha1(f"{_grammar_signature()}\0{path}\0{text}".encode()).hexdigest()


def _cache_load(key: str) -> tuple[ast.FileAst, list] | None:
    """A cached tree and its layout warnings, or None. JSON only (`ast_json`): a planted file
    can at worst be a miss."""
    d = _cache_dir()
    if d is None:
        return None
    from gnppdsl.inputs import InputError, decode_utf8, read_bytes
    from gnppdsl.lang import ast_json

    try:
        return ast_json.loads_entry(decode_utf8(read_bytes(d / f"{key}.json")))
    except (InputError, ValueError, TypeError, RecursionError):
        return None


#: sources longer than this are parsed every time, not cached: the cache file is about 12 times
#: the source (175 KB for the Lab domain's 14 KB), and for a 400 KB one-line fuzz mutant writing
#: it took 8.6 s of 24 s CPU (more than the parse saved the next time); the largest bundled
#: `.pntc` is under 20 KB
MAX_CACHED_CHARS = 128 * 1024


def _cache_store(key: str, tree: ast.FileAst, layout: list, size: int = 0) -> None:
    d = _cache_dir()
    if d is None or size > MAX_CACHED_CHARS:
        return
    from gnppdsl.errors import UserError
    from gnppdsl.lang import ast_json
    from gnppdsl.outputs import write_atomic

    try:
        write_atomic(d / f"{key}.json", ast_json.dumps_entry(tree, layout), "parse cache", mode=0o600)
    except (UserError, ValueError, RecursionError):   # caching is an optimisation only
        pass


def parse_text(text: str, path: str, reporter: Reporter) -> ast.FileAst | None:
    """Parse one file's text; syntax errors go to `reporter` and the result is None."""
    reporter.sources.add(path, text)
    key = _cache_key(text, path)
    hit = _cache_load(key)
    if hit is not None:
        result, layout = hit
    else:
        result = _parse_text(text, path, reporter)
        if result is None:
            return None
        from gnppdsl.lang.lint import layout_warnings

        layout = layout_warnings(result, text)
        _cache_store(key, result, layout, len(text))
    _report_layout(layout, reporter)
    return result


def _report_layout(layout: list, reporter: Reporter) -> None:
    """Layout warnings (`gnppdsl.lang.lint`), once per place even if a file is parsed again."""
    from gnppdsl.lang.diagnostics import Diagnostic

    for span, message, hint in layout:
        reporter.add(Diagnostic(message, span, "layout", hint, severity="warning"))


@contextmanager
def _no_gc() -> Iterator[None]:
    """The cyclic garbage collector paused while a file is parsed and transformed: the parse
    allocates only acyclic trees, and the collector's passes over them were 40 % of the CPU
    time of a 200 KB file (parse 2.7 -> 1.8 s, transform 2.1 -> 1.2 s)."""
    import gc

    was = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if was:
            gc.enable()


def _parse_text(text: str, path: str, reporter: Reporter) -> ast.FileAst | None:
    with _no_gc():
        return _parse_text_gc_off(text, path, reporter)


def _parse_text_gc_off(text: str, path: str, reporter: Reporter) -> ast.FileAst | None:
    from lark.exceptions import UnexpectedInput
    parser = _lark()
    start = "file"
    current = text
    errors = 0
    result = None
    lines = text.splitlines(keepends=True)
    while True:
        try:
            tree = parser.parse(current, start=start)
        except UnexpectedInput as err:
            errors += 1
            line = _syntax_diagnostic(err, path, text, reporter)
            if errors >= MAX_SYNTAX_ERRORS:
                return None
            nxt = next((i for i in range(max(line, 1), len(lines)) if _DECL_LINE.match(lines[i])), None)
            if nxt is None:
                return None
            current = "".join("\n" for _ in lines[:nxt]) + "".join(lines[nxt:])
            start = "items"
            continue
        if errors:
            return None
        deep = _too_deep(tree)
        if deep is not None:
            reporter.error(_node_span(deep, path), f"nested more than {MAX_NESTING} levels deep",
                           "nesting", "brackets, parentheses, prefix operators and chained "
                           "operators each add a level; split the expression (a `const`, a template)")
            return None
        problems: list = []
        from lark.exceptions import VisitError

        try:
            header, items = _make_transformer(path, problems).transform(tree)
        except VisitError as exc:          # a value no check above foresaw: still located
            reporter.error(_node_span(exc.obj, path), f"cannot read this {exc.rule}: {exc.orig_exc}",
                           "syntax")
            return None
        for span, message, hint in problems:
            reporter.error(span, message, "syntax", hint)
        if problems:
            return None
        result = ast.FileAst(path, header, items)
        return result


def parse_file(path: str | Path, reporter: Reporter, ref: Span | None = None) -> ast.FileAst | None:
    """Read and parse a file; unreadable files and syntax errors are reported, not raised.
    `ref` is where the file is named (a `use` line), the place to report a file not read."""
    from gnppdsl import inputs
    from gnppdsl.lang.diagnostics import read_source

    p = str(path)
    text = read_source(reporter, p, ref, max_bytes=inputs.MAX_SOURCE_BYTES)
    return parse_text(text, p, reporter) if text is not None else None
