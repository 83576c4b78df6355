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

Who: only the `gnpp` program (`cli.main.main()` run without arguments) installs it; importing
`gnppdsl` as a library leaves `dataclasses` alone (the patch would reach the user's own
classes too).

Where: `GNPP_CODE_CACHE` (a directory; `0` or `off`: no cache), else
`$XDG_CACHE_HOME/gnppdsl/classcode` (default `~/.cache/...`), one file per Python build
(`sys.implementation.cache_tag` and `sys.version`: marshalled code is only valid for the
interpreter that wrote it), holding length-prefixed `marshal` records: a snapshot of the
table (one dict) and (source text, code object) records appended by processes that missed,
folded into a new snapshot by the next process that reads them (`_read`). Loading runs what
the file holds as methods, as Python runs `__pycache__` files: the directory must be this
user's own with mode 0700 (`outputs.private_dir`, as the function store's), and a file that
cannot be read to the end (a concurrent writer's partial record, corruption) is used up to
its last complete record. Records are appended with one `write` each (O_APPEND), so
concurrent processes do not interleave them; a file over MAX_BYTES starts again.
"""
from __future__ import annotations

import hashlib
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


def _records(data: bytes):
    """The records of a table file: (a 4-byte little-endian length, that many bytes of
    `marshal`) each, up to the first one that is cut short or does not load."""
    pos = 0
    while pos + 4 <= len(data):
        n = int.from_bytes(data[pos:pos + 4], "little")
        blob = data[pos + 4:pos + 4 + n]
        if len(blob) < n:
            return                         # a partial tail (a writer still at it, a crash)
        try:
            yield marshal.loads(blob)
        except (EOFError, ValueError, TypeError):
            return                         # corrupt: what came before counts
        pos += 4 + n


def _record(obj) -> bytes:
    blob = marshal.dumps(obj)
    return len(blob).to_bytes(4, "little") + blob


def _read(path: Path) -> dict[str, CodeType]:
    """The table in `path`: a snapshot (one record, a dict: one `marshal.loads`) and the
    (text, code) records appended after it. Appended records are folded into a new snapshot
    (written to a temporary file, renamed over the table): one record per method was ~6x
    slower to load than one dict (65 vs 10 ms for ~800 methods)."""
    table: dict[str, CodeType] = {}
    try:
        with open(path, "rb") as fh:
            data = fh.read()
    except OSError:
        return table
    if len(data) > MAX_BYTES:
        _write(path, {})
        return table
    appended = 0
    for rec in _records(data):
        if type(rec) is dict:
            table.update((k, v) for k, v in rec.items() if type(k) is str and type(v) is CodeType)
        elif type(rec) is tuple and len(rec) == 2 and type(rec[0]) is str and type(rec[1]) is CodeType:
            table[rec[0]] = rec[1]
            appended += 1
    if appended:
        _write(path, table)
    return table


def _write(path: Path, table: dict[str, CodeType]) -> None:
    """`table` as the file's one snapshot record (`outputs.write_atomic`: a reader sees the old
    file or the new one, never a mix)."""
    from gnppdsl.errors import UserError
    from gnppdsl.outputs import write_atomic

    try:
        write_atomic(path, _record(table), "code cache", mode=0o600)
    except (UserError, OSError, ValueError):
        pass                               # not compacted: read record by record next time


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
    """One record at the table's end, in one `write` (O_APPEND: concurrent processes'
    records do not interleave)."""
    global _writable
    if not _writable or _file is None:
        return
    try:
        rec = _record((text, code))
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


def _patch(module) -> None:
    if vars(module).get("exec") is None:        # not if it has an `exec` of its own already
        module.exec = cached_exec


class _WhenImported:
    """A meta path finder that patches `dataclasses` once it is imported (then leaves)."""

    @classmethod
    def find_spec(cls, name, path=None, target=None):
        if name != "dataclasses":
            return None
        import importlib.util

        sys.meta_path.remove(cls)
        spec = importlib.util.find_spec(name)
        loader = getattr(spec, "loader", None)
        if loader is None or isinstance(loader, type) or not hasattr(loader, "exec_module"):
            return spec                        # (a frozen or odd loader: not cached)
        run = loader.exec_module

        def exec_module(module):
            run(module)
            _patch(module)
        loader.exec_module = exec_module       # this spec's own loader instance
        return spec


def install() -> None:
    """Route the `dataclasses` module's `exec` through `cached_exec`: now if it is imported,
    else when it is (`gnpp --help` need not import it)."""
    if "dataclasses" in sys.modules:
        _patch(sys.modules["dataclasses"])
    elif _WhenImported not in sys.meta_path:
        sys.meta_path.insert(0, _WhenImported)
