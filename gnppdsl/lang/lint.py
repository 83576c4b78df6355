"""Layout warnings: places where the text parses, but most likely not as it was meant.

Why: newlines are plain whitespace in the grammar (statements need no terminator), so a line
that starts with `-`, `[` or `(` silently continues the expression of the line above:

    pos(o)[0] >= lo
    -pos(o)[1] >= -hi          # parsed as  pos(o)[0] >= lo - pos(o)[1] >= -hi

and `with` binds tighter than a comparison, so in `sdist(a, b) >= margin with q = path[k]` the
substitution applies to `margin` only. Both give wrong constraints without any error, so the
parser reports them as warnings (file:line:col, with the fix as a hint). A pure function of the
syntax tree and the source text; nothing here changes what was parsed.
"""
from __future__ import annotations

import dataclasses
from typing import Any, Iterator

from gnppdsl.lang import ast
from gnppdsl.lang.span import Span

LayoutWarning = tuple[Span, str, str]          # (where, message, hint)


def layout_warnings(file_ast: ast.FileAst, text: str) -> list[LayoutWarning]:
    """Every layout warning of one parsed file, in source order."""
    starts = [0]
    for i, ch in enumerate(text):
        if ch == "\n":
            starts.append(i + 1)
    found: list[LayoutWarning] = []
    for node in _walk(file_ast):
        w = _check(node, text, starts, file_ast.path)
        if w is not None:
            found.append(w)
    found.sort(key=lambda w: (w[0].line, w[0].column))
    return found


#: per type: the field names `_walk` descends into (all but `span`), None for a non-dataclass
_CHILDREN: dict[type, tuple[str, ...] | None] = {}


def _children(cls: type) -> tuple[str, ...] | None:
    """The fields of an AST node type to walk, once per type. Why: `dataclasses.fields` per
    node was most of the walk (the Lab domain's five files: ~4,800 nodes, 10-30 ms CPU); the
    parse cache keeps each file's warnings, so a cached parse does not walk at all."""
    names = _CHILDREN.get(cls, ())
    if names == ():
        names = (tuple(f.name for f in dataclasses.fields(cls) if f.name != "span")
                 if dataclasses.is_dataclass(cls) else None)
        _CHILDREN[cls] = names
    return names


def _walk(node: Any) -> Iterator[Any]:
    if isinstance(node, (tuple, list)):
        for x in node:
            yield from _walk(x)
        return
    if isinstance(node, type):
        return
    names = _children(type(node))
    if names is not None:
        yield node
        for name in names:
            yield from _walk(getattr(node, name))


def _offset(starts: list[int], line: int, column: int) -> int:
    return starts[line - 1] + column - 1


def _line_start_token(text: str, starts: list[int], begin: int, end: int, token: str) -> int | None:
    """Offset of `token` in text[begin:end] (skipping comments) if it is the first thing on a
    line after a line break; None otherwise."""
    i, newline = begin, False
    while i < end:
        ch = text[i]
        if ch == "#":
            while i < end and text[i] != "\n":
                i += 1
            continue
        if ch == "\n":
            newline = True
        elif not ch.isspace():
            return i if ch == token and newline else None
        i += 1
    return None


def _span_at(path: str, starts: list[int], offset: int) -> Span:
    line = max(i for i, s in enumerate(starts) if s <= offset) + 1
    return Span(path, line, offset - starts[line - 1] + 1, line, offset - starts[line - 1] + 2)


def _gap(a: Any, b: Any, starts: list[int]) -> tuple[int, int] | None:
    sa, sb = getattr(a, "span", None), getattr(b, "span", None)
    if sa is None or sb is None or sa.end_line is None or sa.end_column is None:
        return None
    return _offset(starts, sa.end_line, sa.end_column), _offset(starts, sb.line, sb.column)


_FIX_NEW = "if a new constraint starts here, end the previous one with ';'"


def _check(node: Any, text: str, starts: list[int], path: str) -> LayoutWarning | None:
    if isinstance(node, ast.EBin) and node.op in "+-":
        gap = _gap(node.lhs, node.rhs, starts)
        at = _line_start_token(text, starts, gap[0], gap[1], node.op) if gap else None
        if at is not None:
            return (_span_at(path, starts, at),
                    f"this line starts with '{node.op}', so it continues the expression of the line above "
                    f"(read as `... {node.op} ...`)",
                    f"{_FIX_NEW}; if the continuation is meant, put '{node.op}' at the end of the line above")
    if isinstance(node, ast.EIndex):
        gap = _gap(node.base, node.index, starts)
        at = _line_start_token(text, starts, gap[0], gap[1], "[") if gap else None
        if at is not None:
            return (_span_at(path, starts, at),
                    "this line starts with '[', so it indexes the expression that ends the line above",
                    f"{_FIX_NEW}; if the index is meant, put '[' on the line above")
    if isinstance(node, ast.ECall) and node.qname and node.span is not None:
        last = node.qname[-1].span
        if last is not None and last.end_line is not None and last.end_column is not None:
            begin = _offset(starts, last.end_line, last.end_column)
            end = _offset(starts, node.span.end_line or node.span.line,
                          node.span.end_column or node.span.column)
            at = _line_start_token(text, starts, begin, end, "(")
            if at is not None:
                return (_span_at(path, starts, at),
                        f"this line starts with '(', so it calls `{node.text}` from the line above",
                        f"{_FIX_NEW}; if the call is meant, put '(' on the line above")
    if isinstance(node, ast.EWith) and isinstance(node.body, (ast.ENum, ast.ERef)):
        what = node.body.text
        return (node.span,
                f"`with` applies only to `{what}`, which the substitution cannot change: `with` binds "
                f"tighter than a comparison",
                "put the side to substitute in parentheses: `(lhs with x = e) >= rhs`")
    return None
