"""Template Functions persisted across processes: a new `gnpp solve` loads the casadi Functions
of the templates (`BodyCompiler`) from disk instead of lowering the bodies again.

Why: lowering a body (the expression walk in Python, forward-kinematics chains, the contact
models of its signed distances) is the largest cost of a cold process before ipopt runs.
Measured (cProfile, cold process, seed 0): 1.5 s of lab1_paper's 6.2 s, 2.0 s of lab4_paper's
19 s, 1.2 s of work1's; loading the same Functions costs a small part of that.

What is stored, per built body: casadi's serialization of the body's pure SX part and the
rest as plain data (row kinds, row groups, the body pairs of its distance queries). The
distance queries themselves (`casadi.Callback`s into coal, or the native twins) cannot be
serialized; the stored Function is the *open* form (x.., p, o) -> (h, a), with o the queries'
outputs as a plain input and a their inputs, and the queries are attached again at load from
the live geometry (`BodyCompiler._from_store`), so h equals the fresh Function's graph.

Never stale: the key is a SHA-256 of everything the built Function depends on: the template
name, the body's structure with its constants lifted (`lowering.structure_key`: what the
in-memory cache keys by, objects by their geometry's structure, so that another problem's
same-shaped blocks find the stored body), the slots' signatures, the number of
parameters, per robot or object the body names its geometry (the geometry's `persist_key`:
the scene's structure key, the URDF / SRDF contents, the reduced pinocchio model's
serialization, the geometry's settings; a geometry without one is never stored), and the code
version: every source file of the package and the casadi, pinocchio and Python
versions. A change to any of them is a new key; an unreadable or corrupt file is a miss.

Where: `GNPP_FUNCTION_CACHE` (a directory; `0` or `off`: no store), else
`$XDG_CACHE_HOME/gnppdsl/functions` (default `~/.cache/...`), one subdirectory per code
version (the stores of versions unused for KEEP_DAYS are removed by the next process that
writes). The directory must be this user's own with mode 0700 (`outputs.private_dir`,
as the parse cache's): loading unpickles, so a directory others could write to is never
used. Files are written atomically (a temporary file renamed into place), so concurrent
processes never read half a file. Not through `outputs.atomic_open`: its fsync per file would
cost a cold process ~100 syncs for data that may be lost (a missing entry is a miss), and its
errors are a user's (`UserError`), where a store that cannot write just does not store. Size: ~30 MB for the Lab problems' templates.
"""
from __future__ import annotations

import hashlib
import os
import pickle
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

FORMAT = 1
"""Version of the stored payload's layout (part of every key)."""

KEEP_DAYS = 7.0
"""Days a store of another code version is kept after its last write (`FunctionStore.prune`)."""

_VERSION_DIR = re.compile(r"[0-9a-f]{16}")

_CODE_VERSION: str | None = None


def code_version() -> str:
    """SHA-256 of the package's Python sources and the versions of casadi, pinocchio and
    Python (computed once per process)."""
    global _CODE_VERSION
    if _CODE_VERSION is None:
        import casadi as ca
        h = hashlib.sha256()
        h.update(f"format {FORMAT}; python {sys.version}; casadi {ca.__version__}".encode())
        try:
            import pinocchio
            h.update(f"; pinocchio {pinocchio.__version__}".encode())
        except ImportError:                 # pragma: no cover  (a dependency of the package)
            h.update(b"; no pinocchio")
        root = Path(__file__).resolve().parent.parent
        for f in sorted(root.rglob("*.py")):
            h.update(str(f.relative_to(root)).encode())
            h.update(f.read_bytes())
        _CODE_VERSION = h.hexdigest()
    return _CODE_VERSION


def default_directory() -> Path | None:
    """The store's directory (module docstring), or None when switched off."""
    from gnppdsl.outputs import cache_directory
    return cache_directory("GNPP_FUNCTION_CACHE", "functions")


class FunctionStore:
    """The on-disk store of built template Functions (module docstring)."""

    def __init__(self, directory: Path | str):
        self.directory = Path(directory)
        self._geo: dict[tuple, str] = {}      # (id(geometry), name) -> fingerprint
        self._geo_alive: dict[int, Any] = {}  # keeps those geometries alive: ids stay theirs
        self.hits = self.misses = self.written = 0
        self._private: bool | None = None

    def private(self) -> bool:
        """Whether the store's directory is this user's own with mode 0700
        (`outputs.private_dir`, checked once per store). Loading unpickles what the directory
        holds, so a directory another user could write to (a shared temporary directory, a
        symbolic link, another owner) is never read or written: the process then rebuilds."""
        if self._private is None:
            from gnppdsl.outputs import private_dir
            self._private = private_dir(self.directory) is not None
        return self._private

    @classmethod
    def default(cls) -> "FunctionStore | None":
        d = default_directory()
        return None if d is None else cls(d)

    # -- keys ---------------------------------------------------------------------------------
    def geometry_fingerprint(self, geometry: Any, name: str) -> str | None:
        """What the symbolic geometry of `name` depends on, as a digest (the geometry's
        `persist_key`); None when the geometry cannot say (then nothing is stored)."""
        if geometry is None:
            return "no geometry"
        fn = getattr(geometry, "persist_key", None)
        if fn is None:
            return None
        k = (id(geometry), name)
        hit = self._geo.get(k)
        if hit is None:
            self._geo_alive[id(geometry)] = geometry
            hit = self._geo[k] = f"{type(geometry).__module__}.{type(geometry).__qualname__}:{fn(name)}"
        return hit

    def key(self, geometry: Any, template: str, structure: Any, names: Any, sigs: tuple,
            n_params: int, open_stops: bool) -> str | None:
        """The store key of one body (module docstring), or None (not storable): `structure`
        the body's structure with its constants lifted (`lowering.structure_key`, whose
        objects are keyed by their geometry's structure), `names` the objects and robots it
        names, whose geometry's `persist_key` joins the key (not the names: a body stored for
        other objects of the same structure is renamed at load, `BodyCompiler._stored`)."""
        fps = set()
        for n in set(names):
            fp = self.geometry_fingerprint(geometry, n)
            if fp is None:
                return None
            fps.add(fp)
        fps = sorted(fps) + (["no geometry"] if geometry is None else [])
        text = "\n".join([code_version(), template, repr(structure), repr(sigs), str(n_params),
                          f"open_stops={open_stops}", *fps])
        if " at 0x" in text:                   # an object without a value repr: not a key
            return None
        return hashlib.sha256(text.encode()).hexdigest()

    # -- files --------------------------------------------------------------------------------
    def _path(self, key: str) -> Path:
        return self.directory / code_version()[:16] / key[:2] / f"{key}.pkl"

    def prune(self, max_age_days: float = KEEP_DAYS) -> int:
        """Remove the stores of other code versions not written for `max_age_days` (every
        code change starts a new one; a checkout used now and then keeps its own). Returns the
        number of version directories removed."""
        import shutil
        import time
        mine, removed = code_version()[:16], 0
        try:
            entries = list(self.directory.iterdir())
        except OSError:
            return 0
        for d in entries:
            if d.name == mine or not _VERSION_DIR.fullmatch(d.name) or not d.is_dir():
                continue
            try:
                if time.time() - d.stat().st_mtime > max_age_days * 86400:
                    shutil.rmtree(d)
                    removed += 1
            except OSError:
                pass
        return removed

    def load(self, key: str) -> dict | None:
        """The payload stored under `key`, or None (absent, unreadable, of another format, or
        in a directory that is not private)."""
        if not self.private():
            self.misses += 1
            return None
        try:
            with open(self._path(key), "rb") as fh:
                payload = pickle.load(fh)
        except FileNotFoundError:
            self.misses += 1
            return None
        except Exception:                      # a corrupt or foreign file: rebuild
            self.misses += 1
            return None
        if not isinstance(payload, dict) or payload.get("format") != FORMAT or payload.get("key") != key:
            self.misses += 1
            return None
        if not self.hits:                      # once per process: the version is in use
            try:
                os.utime(self._path(key).parent.parent)
            except OSError:
                pass
        self.hits += 1
        return payload

    def save(self, key: str, payload: dict) -> bool:
        """Store `payload` under `key` (atomically); False when the directory is not writable
        or not private."""
        if not self.private():
            return False
        path = self._path(key)
        try:
            if not self.written:               # once per process: the version directory's
                path.parent.parent.mkdir(parents=True, exist_ok=True)   # mtime is its last use
                os.utime(path.parent.parent)
                self.prune()
            path.parent.mkdir(parents=True, exist_ok=True)
            fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=".tmp-", suffix=".pkl")
            try:
                with os.fdopen(fd, "wb") as fh:
                    pickle.dump({**payload, "format": FORMAT, "key": key}, fh,
                                protocol=pickle.HIGHEST_PROTOCOL)
                os.replace(tmp, path)
            except BaseException:
                try:
                    os.unlink(tmp)
                except OSError:
                    pass
                raise
        except OSError:
            return False
        self.written += 1
        return True
