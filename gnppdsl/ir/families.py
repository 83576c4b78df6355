"""What writing problem families needs: object ranges (`b1..b16 : block`) and quantified
`init` / `goal` facts (`forall b: block . parent(b) = table`, `forall i in 1..8 { parent(b{2*i})
= b{2*i-1} }`), expanded here into the plain names and literals the rest of the resolver reads.

Why expansion at the syntax level (and not a lifted init/goal in the IR): an initial state and a
goal are ground partial states of the SAS+ task (paper 000, Sec. III); a quantifier over the
problem's finite objects is a way of writing many facts, not a new kind of fact. Expanding into
`ast.Lit`s keeps every later check (types, values, duplicates, missing initial values) as it is,
and each expanded fact keeps the span of what the user wrote, so a diagnostic about it points at
the `forall` body. Every misuse (bad range, unknown type, a binder that shadows an object, an
index that is not an integer) is a located diagnostic here.
"""
from __future__ import annotations

import re
from dataclasses import replace
from itertools import product
from typing import Callable, Iterator

from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter, did_you_mean

MAX_EXPANSION = 200_000
"""Most names one range, or facts one `forall`, may expand to: a typo such as `b1..b1000000`
should be a diagnostic, not minutes of resolution and gigabytes of facts."""

_SUFFIX = re.compile(r"^(.*?)([0-9]+)$")


def range_names(r: ast.ObjRange, reporter: Reporter) -> list[ast.Name]:
    """The names of `lo..hi`: same prefix, integer suffixes lo <= hi; `b01..b16` keeps the
    width of a zero-padded lower bound (b01, b02, ..., b16). Errors are reported at the range."""
    lo, hi = _SUFFIX.match(r.lo.value), _SUFFIX.match(r.hi.value)
    hint = "a range is PREFIX<first>..PREFIX<last>, e.g. `b1..b16`"
    if lo is None or hi is None:
        bad = r.lo if lo is None else r.hi
        reporter.error(bad.span, f"'{bad.value}' does not end in a number", "range", hint)
        return []
    if lo.group(1) != hi.group(1):
        reporter.error(r.span, f"the ends of '{r.lo.value}..{r.hi.value}' have different prefixes "
                       f"('{lo.group(1)}' and '{hi.group(1)}')", "range", hint)
        return []
    a, b = int(lo.group(2)), int(hi.group(2))
    if a > b:
        reporter.error(r.span, f"empty range '{r.lo.value}..{r.hi.value}' ({a} > {b})", "range",
                       f"write `{lo.group(1)}{b}..{lo.group(1)}{a}`")
        return []
    if b - a + 1 > MAX_EXPANSION:
        reporter.error(r.span, f"'{r.lo.value}..{r.hi.value}' names {b - a + 1} objects "
                       f"(at most {MAX_EXPANSION})", "range")
        return []
    width = len(lo.group(2)) if lo.group(2).startswith("0") and len(lo.group(2)) > 1 else 0
    return [ast.Name(f"{lo.group(1)}{k:0{width}d}", r.span) for k in range(a, b + 1)]


def group_names(g: ast.ObjGroup, reporter: Reporter) -> list[ast.Name]:
    """The object names of an `objects` / `constants` group, ranges expanded in order."""
    out: list[ast.Name] = []
    for n in g.names:
        out.extend(range_names(n, reporter) if isinstance(n, ast.ObjRange) else [n])
    return out


class FactExpander:
    """Expands the `forall`s and indexed names (`b{2*i}`) of `init` / `goal` into plain literals.

    `objects` maps each problem object (and domain constant) to its type; `is_subtype(a, b)`
    is the domain's subtype test; `types` its declared types; `reserved` the names a binder must
    not shadow (state variables, derived predicates, builtin values)."""

    def __init__(self, objects: dict[str, str], types: Iterator[str] | set[str],
                 is_subtype: Callable[[str, str], bool], reserved: set[str], reporter: Reporter) -> None:
        self.objects = objects
        self.types = set(types)
        self.is_subtype = is_subtype
        self.reserved = reserved
        self.r = reporter
        self.count = 0

    def expand(self, items, env: dict[str, str | int] | None = None) -> list[ast.Lit]:
        env = env or {}
        out: list[ast.Lit] = []
        for it in items:
            if isinstance(it, ast.FactForall):
                out.extend(self._forall(it, env))
            elif isinstance(it, (ast.FOr, ast.FAnd)):      # a goal's `or` / `and`: expand inside
                items = self.expand(it.items, env)
                if len(items) == len(it.items):
                    out.append(replace(it, items=tuple(items)))
            else:
                lit = self._lit(it, env)
                if lit is not None:
                    out.append(lit)
            if self.count > MAX_EXPANSION:
                return out
        return out

    def _forall(self, f: ast.FactForall, env: dict[str, str | int]) -> list[ast.Lit]:
        domains: list[list[str | int]] = []
        names: list[str] = []
        for b in f.binders:
            n = b.name.value
            if n in env or n in names:
                self.r.error(b.name.span, f"'{n}' is already bound by an enclosing forall", "forall",
                             "give each quantified variable its own name")
                return []
            if n in self.objects or n in self.reserved:
                what = "an object" if n in self.objects else "a state variable, predicate or builtin value"
                self.r.error(b.name.span, f"the forall variable '{n}' shadows {what}", "forall",
                             "rename the variable (e.g. a single letter that names no object)")
                return []
            dom = self._domain(b)
            if dom is None:
                return []
            names.append(n)
            domains.append(dom)
        out: list[ast.Lit] = []
        for combo in product(*domains):
            out.extend(self.expand(f.body, {**env, **dict(zip(names, combo))}))
            if self.count > MAX_EXPANSION:
                self.r.error(f.span, f"this forall expands to more than {MAX_EXPANSION} facts", "forall")
                return out
        return out

    def _domain(self, b) -> list[str | int] | None:
        if isinstance(b, ast.IndexBinder):
            lo, hi = b.lo.value, b.hi.value
            if lo != int(lo) or hi != int(hi):
                self.r.error(b.span, "a forall index range has integer bounds", "forall",
                             "e.g. `forall i in 1..8 . ...`")
                return None
            if lo > hi:
                self.r.error(b.span, f"empty index range {b.lo.text}..{b.hi.text}", "forall")
                return None
            return list(range(int(lo), int(hi) + 1))
        for t in b.types:
            if t.value not in self.types:
                self.r.error(t.span, f"unknown type '{t.value}'", "unknown-type",
                             did_you_mean(t.value, self.types))
                return None
        return [o for o, ot in self.objects.items()
                if any(ot == t.value or self.is_subtype(ot, t.value) for t in b.types)]

    def _lit(self, lit: ast.Lit, env) -> ast.Lit | None:
        lhs = self._term(lit.lhs, env)
        rhs = self._term(lit.rhs, env) if lit.rhs is not None else None
        if lhs is None or (lit.rhs is not None and rhs is None):
            return None
        self.count += 1
        return replace(lit, lhs=lhs, rhs=rhs) if (lhs is not lit.lhs or rhs is not lit.rhs) else lit

    def _term(self, t: ast.LTerm, env) -> ast.LTerm | None:
        name = t.name
        if isinstance(name, ast.IndexedName):
            k = self._index(name.index, env)
            if k is None:
                return None
            if k < 0:
                self.r.error(name.index.span or name.span, f"the index of '{name.prefix.value}{{...}}' is "
                             f"{k}; object names end in a non-negative number", "forall")
                return None
            new_name = ast.Name(f"{name.prefix.value}{k}", name.span)
        elif name.value in env:
            v = env[name.value]
            if isinstance(v, int):
                self.r.error(name.span, f"'{name.value}' is an integer index, not an object", "forall",
                             f"build an object name from it: `b{{{name.value}}}`")
                return None
            if t.args is not None:
                self.r.error(name.span, f"'{name.value}' is a forall variable, not a state variable", "forall")
                return None
            new_name = ast.Name(v, name.span)
        else:
            new_name = name
        args = t.args
        if args is not None:
            new_args = tuple(self._term(a, env) for a in args)
            if any(a is None for a in new_args):
                return None
            if all(a is b for a, b in zip(new_args, args)):
                new_args = args
            args = new_args
        if new_name is t.name and args is t.args:
            return t
        return ast.LTerm(new_name, args, t.span)

    def _index(self, e, env) -> int | None:
        """The integer value of an index expression: numbers, forall indices, + - * / and
        unary minus; a division must be exact."""
        if isinstance(e, ast.ENum):
            if e.value != int(e.value):
                self.r.error(e.span, f"'{e.text}' is not an integer", "forall")
                return None
            return int(e.value)
        if isinstance(e, ast.ERef) and len(e.qname) == 1:
            n = e.qname[0].value
            v = env.get(n)
            if isinstance(v, int):
                return v
            if v is not None:
                self.r.error(e.span, f"'{n}' is an object, not an integer index", "forall",
                             "index variables are bound by `forall i in LO..HI`")
            else:
                self.r.error(e.span, f"unknown index '{n}'", "forall",
                             did_you_mean(n, [k for k, x in env.items() if isinstance(x, int)])
                             or "index variables are bound by `forall i in LO..HI`")
            return None
        if isinstance(e, ast.ENeg):
            v = self._index(e.arg, env)
            return None if v is None else -v
        if isinstance(e, ast.EBin) and e.op in "+-*/":
            a, b = self._index(e.lhs, env), self._index(e.rhs, env)
            if a is None or b is None:
                return None
            if e.op == "/":
                if b == 0 or a % b:
                    self.r.error(e.span, f"{a} / {b} is not an integer", "forall")
                    return None
                return a // b
            return {"+": a + b, "-": a - b, "*": a * b}[e.op]
        self.r.error(getattr(e, "span", None), "an object index is an integer expression",
                     "forall", "use numbers, forall indices and + - * /, e.g. `b{2*i-1}`")
        return None
