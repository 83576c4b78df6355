"""The AST as JSON, for the parse cache: data in, data out, no code ever runs from a cache file.

Why not pickle: `pickle.load` of a file planted in
`~/.cache/gnppdsl/ast/` runs arbitrary code as the user while `gnpp check` reports "ok". This
codec only builds the dataclasses of `gnppdsl.lang.ast` (and `Span`) by name from an allow
list, with positional field values that are JSON scalars, lists (read back as tuples: the
AST holds tuples only) or such objects; anything else in a file makes it a cache miss.
Encoding refuses what it cannot represent exactly (a subclass, a list, a non-finite float),
so a tree that would not come back equal is simply not cached.
"""
from __future__ import annotations

import dataclasses
import json
import math

from gnppdsl.lang import ast
from gnppdsl.lang.span import Span

_CLASSES: dict[str, type] = {c.__name__: c for c in vars(ast).values()
                             if isinstance(c, type) and dataclasses.is_dataclass(c)}
_CLASSES["Span"] = Span
_FIELDS = {name: tuple(f.name for f in dataclasses.fields(c)) for name, c in _CLASSES.items()}


class NotEncodable(ValueError):
    """A value the cache format does not represent exactly."""


def _encode(x):
    if x is None or isinstance(x, (bool, str, int)):
        return x
    if isinstance(x, float):
        if not math.isfinite(x):
            raise NotEncodable("non-finite float")
        return x
    if type(x) is tuple:
        return [_encode(v) for v in x]
    name = type(x).__name__
    if _CLASSES.get(name) is type(x):
        return {"@": name, "v": [_encode(getattr(x, f)) for f in _FIELDS[name]]}
    raise NotEncodable(f"cannot encode {type(x).__name__}")


def dumps(tree: ast.FileAst) -> str:
    """JSON text of a parsed file; `NotEncodable` if some node has no exact encoding."""
    return json.dumps(_encode(tree), separators=(",", ":"), allow_nan=False)


def _hook(obj: dict):
    name = obj.get("@")
    cls = _CLASSES.get(name) if isinstance(name, str) else None
    vals = obj.get("v")
    if cls is None or not isinstance(vals, list) or len(obj) != 2 or len(vals) != len(_FIELDS[name]):
        raise NotEncodable("not an AST node")
    return cls(*(_tuples(v) for v in vals))


def _tuples(v):
    """JSON arrays back to the tuples the AST holds (nodes inside are already built)."""
    return tuple(_tuples(x) for x in v) if isinstance(v, list) else v


def loads(text: str) -> ast.FileAst:
    """The tree back; `ValueError` (a cache miss for the caller) for anything else."""
    tree = json.loads(text, object_hook=_hook, parse_constant=_no_constant)
    if not isinstance(tree, ast.FileAst):
        raise NotEncodable("not a parsed file")
    return tree


def _no_constant(name: str):
    raise NotEncodable(f"{name} in a cache file")


def dumps_entry(tree: ast.FileAst, layout: list) -> str:
    """A parse cache entry: the tree and its layout warnings (`gnppdsl.lang.lint`: a pure
    function of the tree and the text, which the cache key holds), so a cached parse does not
    walk the tree again (~5,000 nodes, ~20 ms CPU of each Lab `gnpp solve`)."""
    rows = [[_encode(span), message, hint] for span, message, hint in layout]
    if not all(isinstance(m, str) and isinstance(h, str) for _, m, h in rows):
        raise NotEncodable("a layout warning's text")
    return json.dumps(["entry", _encode(tree), rows], separators=(",", ":"), allow_nan=False)


def loads_entry(text: str) -> tuple[ast.FileAst, list]:
    """(tree, layout warnings) back from `dumps_entry`; `ValueError` for anything else."""
    obj = json.loads(text, object_hook=_hook, parse_constant=_no_constant)
    if not (isinstance(obj, list) and len(obj) == 3 and obj[0] == "entry"
            and isinstance(obj[1], ast.FileAst) and isinstance(obj[2], list)):
        raise NotEncodable("not a cache entry")
    layout = []
    for row in obj[2]:
        if not (isinstance(row, list) and len(row) == 3 and isinstance(row[0], Span)
                and isinstance(row[1], str) and isinstance(row[2], str)):
            raise NotEncodable("not a layout warning")
        layout.append((row[0], row[1], row[2]))
    return obj[1], layout

