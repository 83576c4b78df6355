"""Native distance queries: `native_witness.cpp` built once per machine, called by casadi directly.

Why: ipopt evaluates every distance of a graph-NLP at every iteration (and the Jacobian and
Hessian at the same point); through the Python callback (`distance.WitnessCallback`) one query
costs ~40-50 us, of which coal is ~6 us, and on the Lab problems the queries were a quarter to
a half of the solve time. The C++ twin does the same coal query and the same contact feature
arithmetic (`features.feature_list`) as a casadi external function, so ipopt's evaluations
never enter Python. The Python callback stays the reference and the fallback: for bodies of
several shapes, shapes the twin does not know, the far-field model, and machines without a C++
compiler or coal's headers.

The library is keyed by the source, coal's version and the compiler, and lives in the user
cache (`GNPP_NATIVE_CACHE`, else `$XDG_CACHE_HOME/gnppdsl/native`). `make setup` builds it
(`python -m gnppdsl.geometry.native`); a process that finds none starts that build in the
background (never waits for it) and uses the Python callback meanwhile. `GNPP_NATIVE=0` turns
the native path off, `GNPP_NATIVE_BUILD=0` stops the background build.
"""
from __future__ import annotations

import ctypes
import fcntl
import hashlib
import os
import platform
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path
from typing import Any

import numpy as np

SOURCE = Path(__file__).with_name("native_witness.cpp")
ABI = 1


class NativeBuildError(Exception):
    """The C++ twin could not be built (no compiler, no headers, a compile error)."""


def enabled() -> bool:
    return os.environ.get("GNPP_NATIVE", "1") != "0"


def _compiler() -> str | None:
    return shutil.which(os.environ.get("GNPP_CXX", "c++")) or shutil.which("g++")


def _prefix() -> Path | None:
    """The cmeel prefix holding coal's headers and library (the directory above `include/coal`)."""
    try:
        import coal
    except ImportError:
        return None
    for parent in Path(coal.__file__).resolve().parents:
        if (parent / "include" / "coal" / "distance.h").is_file():
            return parent
    return None


def _eigen(prefix: Path) -> Path | None:
    for cand in (prefix / "include" / "eigen3", Path("/usr/include/eigen3"), Path("/usr/local/include/eigen3")):
        if (cand / "Eigen" / "Core").is_file():
            return cand
    return None


def cache_dir() -> Path:
    env = os.environ.get("GNPP_NATIVE_CACHE")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or os.path.join(os.path.expanduser("~"), ".cache")
    return Path(base) / "gnppdsl" / "native"


def library_path() -> Path | None:
    """Where the library for this source, coal and compiler lives (None: cannot be built here)."""
    cxx, prefix = _compiler(), _prefix()
    if cxx is None or prefix is None:
        return None
    try:
        import coal
        version = getattr(coal, "__version__", "")
    except ImportError:
        return None
    h = hashlib.sha256()
    for part in (SOURCE.read_bytes(), version.encode(), str(prefix).encode(), cxx.encode(),
                 platform.machine().encode(), sys.platform.encode()):
        h.update(part)
        h.update(b"\0")
    return cache_dir() / f"witness_{h.hexdigest()[:16]}.so"


def build(verbose: bool = False) -> Path:
    """Compile the library into the cache (part file, then rename: a reader never sees half a
    library). Raises NativeBuildError with the reason."""
    cxx, prefix = _compiler(), _prefix()
    if cxx is None:
        raise NativeBuildError("no C++ compiler (set GNPP_CXX)")
    if prefix is None:
        raise NativeBuildError("coal's C++ headers were not found next to the coal package")
    eigen = _eigen(prefix)
    if eigen is None:
        raise NativeBuildError("Eigen's headers were not found (pip install cmeel-eigen)")
    target = library_path()
    assert target is not None
    target.parent.mkdir(parents=True, exist_ok=True)
    fd, part = tempfile.mkstemp(prefix=target.name + ".", suffix=".part", dir=target.parent)
    os.close(fd)
    lib = prefix / "lib"
    cmd = [cxx, "-O2", "-std=c++17", "-shared", "-fPIC", "-DNDEBUG", f"-I{prefix / 'include'}", f"-I{eigen}",
           str(SOURCE), "-o", part, f"-L{lib}", "-lcoal", f"-Wl,-rpath,{lib}"]
    try:
        p = subprocess.run(cmd, capture_output=True, text=True)
        if p.returncode != 0:
            raise NativeBuildError(f"{cxx} failed: {p.stderr.strip()[-2000:]}")
        os.replace(part, target)
    finally:
        if os.path.exists(part):
            os.unlink(part)
    if verbose:
        print(f"native distance library: {target}")
    return target


def _start_background_build() -> None:
    """One detached `python -m gnppdsl.geometry.native` per cache (a lock file says one runs)."""
    if os.environ.get("GNPP_NATIVE_BUILD", "1") == "0":
        return
    try:
        d = cache_dir()
        d.mkdir(parents=True, exist_ok=True)
        lock = open(d / ".build.lock", "a")
    except OSError:
        return
    try:
        fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        lock.close()
        return                       # another process is building it
    fcntl.flock(lock, fcntl.LOCK_UN)
    lock.close()
    try:
        subprocess.Popen([sys.executable, "-m", "gnppdsl.geometry.native", "--background"],
                         stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                         start_new_session=True, close_fds=True)
    except OSError:
        pass


class NativeWitness:
    """The loaded library: registers shapes and body pairs, hands out casadi Functions."""

    def __init__(self, path: Path):
        import casadi as ca
        self.path = path
        self.lib = ctypes.CDLL(str(path))
        if self.lib.gnpp_native_abi() != ABI:
            raise OSError(f"{path}: ABI mismatch")
        d, i = ctypes.c_double, ctypes.c_int
        pd, pi = ctypes.POINTER(d), ctypes.POINTER(i)
        self.lib.gnpp_add_shape.argtypes = [i, d, d, pd, pd, i, i, pd, pd, pd, pi, d]
        self.lib.gnpp_add_pair.argtypes = [i, pd, i, i, pd, i, i]
        self.lib.gnpp_model.argtypes = [i, pd, pd]
        self.lib.gnpp_queries.restype = ctypes.c_longlong
        self.lib.gnpp_fail_next.argtypes = [i]
        self.external = ca.external("gnpp_witness", str(path))
        self._shapes: dict[int, tuple[Any, int]] = {}    # id(coal shape) -> (shape, native id)
        self._pairs: dict[tuple, tuple[int, Any]] = {}

    @staticmethod
    def _arr(x, dtype=np.float64) -> np.ndarray:
        return np.ascontiguousarray(np.asarray(x, dtype=dtype).reshape(-1))

    def _ptr(self, a: np.ndarray, ctype=ctypes.c_double):
        return a.ctypes.data_as(ctypes.POINTER(ctype))

    def shape_id(self, shape: Any) -> int:
        """Native twin of a coal shape (-1: a kind the twin does not handle)."""
        hit = self._shapes.get(id(shape))
        if hit is not None and hit[0] is shape:
            return hit[1]
        import coal
        from gnppdsl.geometry.features import _planes
        radius = length = 0.0
        half = np.zeros(3)
        points = np.zeros((0, 3))
        if isinstance(shape, coal.Sphere):
            kind, radius = 0, float(shape.radius)
        elif isinstance(shape, coal.Cylinder):
            kind, radius, length = 1, float(shape.radius), 2.0 * float(shape.halfLength)
        elif isinstance(shape, coal.Box):
            kind, half = 2, np.array(shape.halfSide, dtype=float)
        elif type(shape).__name__ in ("ConvexBase", "Convex") and hasattr(shape, "points"):
            kind, points = 3, np.array(shape.points(), dtype=float).reshape(-1, 3)
        else:
            self._shapes[id(shape)] = (shape, -1)
            return -1
        pl = _planes(shape)
        if pl is not None:
            normals, offsets = self._arr(pl.N), self._arr(pl.O)
            dirs = self._arr([[*u1, *u2] for u1, u2 in pl.face_dirs])
            side = self._arr(pl.side, np.int32)
            m, tol = len(pl.O), float(pl.tol)
        else:
            normals = offsets = dirs = np.zeros(1)
            side, m, tol = np.zeros(1, np.int32), 0, 0.0
        half, pts = self._arr(half), self._arr(points if points.size else np.zeros(3))
        sid = self.lib.gnpp_add_shape(kind, radius, length, self._ptr(half), self._ptr(pts), len(points), m,
                                      self._ptr(normals), self._ptr(offsets), self._ptr(dirs),
                                      self._ptr(side, ctypes.c_int), tol)
        self._shapes[id(shape)] = (shape, sid)
        return sid

    def pair_id(self, shape_a: Any, Ma: np.ndarray, shape_b: Any, Mb: np.ndarray, planar: bool) -> int:
        """Register a pair of single-shape bodies (placements Ma, Mb in the body frames)."""
        sa, sb = self.shape_id(shape_a), self.shape_id(shape_b)
        if sa < 0 or sb < 0:
            return -1
        ma = self._arr(np.r_[np.asarray(Ma)[:3, :3].reshape(-1), np.asarray(Ma)[:3, 3]])
        mb = self._arr(np.r_[np.asarray(Mb)[:3, :3].reshape(-1), np.asarray(Mb)[:3, 3]])
        ida = int(np.array_equal(Ma, np.eye(4)))
        idb = int(np.array_equal(Mb, np.eye(4)))
        return self.lib.gnpp_add_pair(sa, self._ptr(ma), ida, sb, self._ptr(mb), idb, int(planar))

    def function(self, name: str, body_a: Any, body_b: Any, planar: bool) -> Any:
        """casadi Function x[24] -> o[24], the native twin of the WitnessCallback of two
        `ConvexBody`s, for evaluation only (casadi cannot differentiate it; the callback
        declares zero derivatives); None when the twin does not handle the bodies."""
        if len(body_a.shapes) != 1 or len(body_b.shapes) != 1:
            return None
        key = (id(body_a), id(body_b), planar)
        hit = self._pairs.get(key)
        if hit is None:
            pid = self.pair_id(body_a.shapes[0], body_a.placements[0], body_b.shapes[0],
                               body_b.placements[0], planar)
            fn = None
            if pid >= 0:
                import casadi as ca
                # an SX wrapper: called on SX it inlines to one call node of the library
                x = ca.SX.sym("x", 24)
                fn = ca.Function(name + "_native", [x], [self.external(x, float(pid))])
            hit = self._pairs[key] = (pid, fn, body_a, body_b)
        return hit[1]

    def model(self, pair: int, x: np.ndarray) -> np.ndarray:
        """One query without the memo (tests compare it with the Python model)."""
        xin = self._arr(x)
        out = np.zeros(24)
        if self.lib.gnpp_model(pair, self._ptr(xin), self._ptr(out)) != 0:
            raise RuntimeError("native distance query failed")
        return out

    def forget(self) -> None:
        self.lib.gnpp_forget()

    def fail_next(self, k: int) -> None:
        """Test hook: the next k plain coal queries report coal's failure value (-DBL_MAX with
        NaN normal and witness points), so that tests reach the retries (`distance.robust_query`)."""
        self.lib.gnpp_fail_next(int(k))

    def queries(self) -> int:
        """Queries computed through casadi so far (memo hits not counted)."""
        return int(self.lib.gnpp_queries())


_LOADED: dict[str, NativeWitness | None] = {}


def load(start_build: bool = True) -> NativeWitness | None:
    """The native library of this machine, or None (disabled, not built yet, cannot be built).
    One load per process; a missing library starts its background build."""
    if not enabled():
        return None
    if "lib" in _LOADED:
        return _LOADED["lib"]
    lib = None
    path = library_path()
    if path is not None and path.is_file():
        try:
            lib = NativeWitness(path)
        except (OSError, RuntimeError):
            lib = None
    elif path is not None:
        if not start_build:
            return None      # not remembered: a later load(start_build=True) still builds it
        _start_background_build()
    _LOADED["lib"] = lib
    return lib


def describe() -> str:
    """For benchmark headers: which implementation answers the distance queries."""
    if not enabled():
        return "python (GNPP_NATIVE=0)"
    return "native (C++)" if load(start_build=False) is not None else "python (native library not built)"


def main(argv: list[str] | None = None) -> int:
    """`python -m gnppdsl.geometry.native`: build the library (make setup); never fails the
    setup: without a compiler the Python callback does the work."""
    argv = sys.argv[1:] if argv is None else argv
    background = "--background" in argv
    try:
        d = cache_dir()
        d.mkdir(parents=True, exist_ok=True)
        with open(d / ".build.lock", "a") as lock:
            fcntl.flock(lock, fcntl.LOCK_EX)
            path = library_path()
            if path is not None and path.is_file():
                if not background:
                    print(f"native distance library: {path} (already built)")
                return 0
            if background:
                os.nice(10)
            build(verbose=not background)
    except (NativeBuildError, OSError) as e:
        if not background:
            print(f"native distance library not built ({e}); the Python distance callback will be used")
        return 0
    return 0


if __name__ == "__main__":
    sys.exit(main())
