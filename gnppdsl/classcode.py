"""The compiled code of the methods `dataclasses` generates, cached across processes.

Why: `@dataclass` writes each generated method (`__init__`, `__repr__`, `__eq__`, and for a
frozen class `__setattr__`, `__delattr__`, `__hash__`) as Python source and compiles it with
`exec` when the class is created, one compilation per method on Python 3.11 and 3.12. A
`gnpp solve` creates ~190 dataclasses (the syntax tree, the IR, the scene, the results), and
those ~1,000 compilations were 0.2-0.26 s CPU of every process's imports (cProfile: compiling
is ~55 % of `dataclasses._process_class`).

What: `install()` gives the `dataclasses` module its own `exec` (a module global shadows the
builtin; nothing else in that module calls it) that looks the source text up in a table of
code objects and runs `exec(code, globals, ns)`, which is what `exec(text, globals, ns)` does
after compiling the text: the same functions, names, defaults, annotations and line numbers
(`tests/test_classcode.py` compares them with a normal creation). A text not in the table is
compiled as before and appended to the table's file, so the next process finds it.

Where: `GNPP_CODE_CACHE` (a directory; `0` or `off`: no cache), else
`$XDG_CACHE_HOME/gnppdsl/classcode` (default `~/.cache/...`), one file per Python build
(`sys.implementation.cache_tag` and `sys.version`: marshalled code is only valid for the
interpreter that wrote it), holding `marshal` records (source text, code object). Loading
runs what the file holds as methods, as Python runs `__pycache__` files: the directory must
be this user's own with mode 0700 (`outputs.private_dir`, as the function store's), and a
file that cannot be read to the end (a concurrent writer's partial record, corruption) is
used up to its last complete record. Records are appended with one `write` each (O_APPEND),
so concurrent processes do not interleave them; a file over MAX_BYTES starts again.
"""
from __future__ import annotations

import dataclasses
import hashlib
import io
import marshal
import os
import sys
from pathlib import Path
from types import CodeType

MAX_BYTES = 16 * 1024 * 1024
"""A table file larger than this (texts of many code versions) is emptied and filled anew."""

_builtin_exec = exec
_table: dict[str, CodeType] | None = None     # source text -> code object (None: not read yet)
_file: Path | None = None
_writable = False
stats = {"hits": 0, "misses": 0}


def _path() -> Path | None:
    from gnppdsl.outputs import cache_directory, private_dir

    d = cache_directory("GNPP_CODE_CACHE", "classcode")
    if d is None or private_dir(d) is None:
        return None
    tag = hashlib.sha256(f"{sys.implementation.cache_tag}\0{sys.version}".encode()).hexdigest()[:16]
    return d / f"{tag}.marshal"


def _read(path: Path) -> dict[str, CodeType]:
    table: dict[str, CodeType] = {}
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError:
        return table
    if len(data) > MAX_BYTES:
        try:
            os.truncate(path, 0)
        except OSError:
            pass
        return table
    buf = io.BytesIO(data)
    while buf.tell() < len(data):
        try:
            rec = marshal.load(buf)
        except (EOFError, ValueError, TypeError):
            break                          # a partial or corrupt tail: what came before counts
        if (type(rec) is tuple and len(rec) == 2 and type(rec[0]) is str
                and type(rec[1]) is CodeType):
            table[rec[0]] = rec[1]
    return table


def _load() -> dict[str, CodeType]:
    global _table, _file, _writable
    if _table is None:
        _table = {}
        try:
            _file = _path()
        except Exception:                  # no cache directory: compile as before
            _file = None
        if _file is not None:
            _table = _read(_file)
            _writable = True
    return _table


def _append(text: str, code: CodeType) -> None:
    global _writable
    if not _writable or _file is None:
        return
    try:
        rec = marshal.dumps((text, code))
        fd = os.open(_file, os.O_WRONLY | os.O_APPEND | os.O_CREAT, 0o600)
        try:
            os.write(fd, rec)
        finally:
            os.close(fd)
    except (OSError, ValueError):
        _writable = False                  # a cache that cannot be written is just not filled


def cached_exec(source, globals=None, locals=None, /):
    """`exec` for the `dataclasses` module: a source text runs from its cached code object."""
    if type(source) is not str:
        return _builtin_exec(source, globals, locals)
    table = _load()
    code = table.get(source)
    if code is None:
        stats["misses"] += 1
        code = compile(source, "<string>", "exec", dont_inherit=True)
        table[source] = code
        _append(source, code)
    else:
        stats["hits"] += 1
    return _builtin_exec(code, globals, locals)


def install() -> None:
    """Route the `dataclasses` module's `exec` through `cached_exec` (once; a no-op when the
    module already has an `exec` of its own that is not this one, or when switched off)."""
    current = vars(dataclasses).get("exec")
    if current is cached_exec or current is not None:
        return
    dataclasses.exec = cached_exec
