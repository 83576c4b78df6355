"""Native compilation of large SX derivative kernels, kept in a cache on disk.

Why: on the robot domains most of an ipopt iteration goes into the per-template Hessians and
Jacobians (`BodyCompiler.hessian` / `.jacobian`): a Panda link-object distance differentiated
through forward kinematics is a ~9,000-instruction SX graph per row, which casadi's virtual
machine runs at ~7 ns per instruction. Generated as C and compiled, the same graph runs about
3x faster (lab1's path_clear representative Hessian, 53k instructions: 410 us in the virtual
machine, 115 us compiled with gcc -O0; -O1 was 4x faster but took 5-16 s per kernel to
compile against 1-2 s). Measured on whole solves with a warm cache (seed 0, CPU s):
lab1 3.3 -> 3.0, lab2 6.4 -> 5.5, lab4 26.0 -> 19.2.

Compiling costs 1-2 s per kernel (lab1: 32 kernels, 43 s), so the libraries are kept in a
cache directory keyed by a fingerprint of the Function (see `KernelCache.key`): a domain's
kernels are compiled once per machine and loaded by later solves. Only pure SX Functions of at
least `MIN_INSTRUCTIONS` instructions are compiled (callbacks cannot be generated as C; small
kernels gain less than they cost to compile). Whatever goes wrong (no C compiler, a compile
error, a library that does not reproduce the virtual machine's numbers bit for bit at the
fingerprint's probe points) leaves the Function as it was: a speed option, never a change of
results.

Three modes (`mode`), from the solver setting `jit` (`SolveOptions.jit`, `gnpp solve
--jit/--no-jit`):
- "background" (setting unset, the default): kernels already in the cache are loaded; a missing
  one is saved as a job (`Function.save`) for a detached worker process at low priority
  (`gnppdsl.nlp.jit_worker`: C code, compiler; one worker per cache) while this solve runs it
  in the virtual machine. The first solve on a machine is not slowed down by compiling (its workers'
  CPU is not in its `cpu_time`: they may outlive it), later solves load the libraries.
  Without a compiler or a writable cache it quietly does nothing.
- "now" (`jit = true`, `--jit`): missing kernels are compiled during the solve (the first
  solve of the Lab compiles for ~1 min; its CPU time includes the compiler's); an unwritable
  cache is a clear error. What the benchmarks use to measure with every kernel compiled.
- "off" (`jit = false`, `--no-jit`, or `GNPP_JIT=0` whatever the setting says).
`GNPP_JIT_CACHE` sets the cache directory (default `~/.cache/gnppdsl/jit`), `GNPP_CC` the
compiler (`cc`). The cache keeps at most `GNPP_JIT_CACHE_MB` (default 512) MB of libraries:
after compiling, the least recently loaded ones are removed (`jit_worker.prune`; a Lab problem
adds ~30-60 files of 100-400 kB). Delete the directory to retry kernels whose background
compile failed (they are marked `<key>.failed`).
"""
from __future__ import annotations

import hashlib
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.nlp.jit_codegen import generate_c, kernel_symbol
from gnppdsl.nlp.jit_worker import install_library, prune, try_lock

MIN_INSTRUCTIONS = 5000
FLAGS = ("-O0", "-shared", "-fPIC")
COMPILE_MARGIN = 5.0       # seconds before the solve's deadline after which nothing is compiled
COMPILE_TIMEOUT = 120.0    # seconds one compiler run may take
MODES = ("off", "now", "background")


def mode(requested: bool | None) -> str:
    """The mode of the `jit` setting: True -> "now", False -> "off", None (unset) ->
    "background"; "off" whatever the setting says when the environment has GNPP_JIT=0."""
    if os.environ.get("GNPP_JIT", "1") == "0" or requested is False:
        return "off"
    return "now" if requested else "background"


def enabled(requested: bool | None) -> bool:
    """Whether the setting asks for compiled kernels at all (see `mode`)."""
    return mode(requested) != "off"


def kernel_cache(jit_mode: str) -> "KernelCache | None":
    """The KernelCache of a mode, or None for "off". In the default background mode a cache
    that cannot be written, or a machine without a compiler, just means no kernels (the user
    did not ask for them); "now" (asked for explicitly) says why it cannot."""
    if jit_mode not in MODES:
        raise ValueError(f"jit mode {jit_mode!r} (use one of {', '.join(MODES)})")
    if jit_mode == "off":
        return None
    if jit_mode == "background":
        if find_compiler() is None or not hasattr(os, "fork"):
            return None                    # the worker forks and locks with fcntl (POSIX)
        try:
            return KernelCache(background=True)
        except UserError:
            return None
    return KernelCache()


def cache_dir() -> Path:
    env = os.environ.get("GNPP_JIT_CACHE")
    if env:
        return Path(env)
    try:
        return Path.home() / ".cache" / "gnppdsl" / "jit"
    except RuntimeError:           # no home directory (HOME unset, no passwd entry)
        return Path(tempfile.gettempdir()) / "gnppdsl-jit"


def writable_cache(directory: Path) -> Path:
    """`directory`, created if needed, after checking that files can be written there."""
    try:
        directory.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryFile(dir=directory):
            pass
    except OSError as err:
        raise UserError(f"jit: the kernel cache {directory} is not writable ({err.strerror or err}); "
                        f"set GNPP_JIT_CACHE to a writable directory or solve with --no-jit") from None
    return directory


def find_compiler() -> str | None:
    """Path of the C compiler, or None when there is none (then nothing is compiled)."""
    return shutil.which(os.environ.get("GNPP_CC", "cc"))


class KernelCache:
    """Replaces large SX Functions by compiled ones; counts what it did (solve statistics)."""

    def __init__(self, directory: Path | None = None, min_instructions: int = MIN_INSTRUCTIONS,
                 cc: str | None = None, deadline: float = float("inf"), background: bool = False):
        """`deadline` (time.perf_counter clock): no kernel is compiled when less than
        `COMPILE_MARGIN` seconds are left (libraries already in the cache are still used).
        `background`: missing kernels go to a worker process instead (see the module doc)."""
        self.directory = writable_cache(Path(directory) if directory is not None else cache_dir())
        self.deadline = deadline
        self.background = background
        self.min_instructions = min_instructions
        self.cc = cc if cc is not None else find_compiler()
        self.compiled = 0          # libraries built by this process
        self.queued = 0            # kernels handed to background workers by this process
        self.loaded = 0            # kernels in use as native code
        self.failed = 0            # kernels left to the virtual machine after an error
        self.compile_time = 0.0    # seconds spent generating and compiling C (in this process)
        self.last_error = ""
        self._memo: dict[str, ca.Function] = {}
        self._pending: dict[str, Path] = {}    # key -> library a worker is (or was) building
        self._workers: list[subprocess.Popen] = []    # started workers (their short-lived parents)
        self._skipped = 0          # kernels left to the VM for the deadline, not yet reported
        self.last: tuple[str, bytes] | None = None    # see `native`
        self._last: tuple[str, bytes] | None = None

    def native(self, f: ca.Function) -> ca.Function:
        """A compiled Function with f's inputs, outputs and values, or f itself. After a
        compiled one, `last` is its (key, expected values at the probes): what `cached` needs
        to load it again without f (`BodyCompiler`'s stored derivatives); else None."""
        self.last = None
        g = self._native(f)
        if g is not f:
            self.last = self._last
        return g

    def cached(self, key: str, expected: bytes) -> ca.Function | None:
        """The compiled kernel of cache key `key` (`KernelCache.key`) without its SX Function:
        the library in the cache, checked to give `expected` at the probes (as `native` checks a
        library against the Function's own values), or None (absent, or other values). Why:
        building a large derivative's SX graph only to compute its key cost a cold process
        most of its set-up (field3: the per-body Hessians, 0.6-0.9 s CPU); the key and values
        are remembered per body instead (`BodyCompiler._stored_derivative`)."""
        hit = self._memo.get(key)
        if hit is not None:
            return hit
        lib = self.directory / f"{key}.so"
        if not lib.exists():
            return None
        try:
            g = ca.external(kernel_symbol(key), str(lib))
            if self.values(g, self.probes(g)) != expected:
                return None
        except Exception:          # a damaged library: `native` rebuilds it when it meets f
            return None
        self.loaded += 1
        self._memo[key] = g
        try:
            os.utime(lib)
        except OSError:
            pass
        return g

    def _native(self, f: ca.Function) -> ca.Function:
        self._last = None
        if self.cc is None or not f.is_a("SXFunction") or f.n_instructions() < self.min_instructions \
                or f.has_free():
            return f
        try:
            key, expected = self.key(f)
        except Exception:          # cannot be evaluated at the probes: leave it
            return f
        if not np.isfinite(np.frombuffer(expected, dtype=float)).all():
            return f               # a NaN or inf at a probe would make the key ambiguous
        hit = self._memo.get(key)
        self._last = (key, expected)
        if hit is not None:
            return hit
        lib = self.directory / f"{key}.so"
        if self.background and not lib.exists():
            marker = lib.with_suffix(".failed")
            if marker.exists():
                self.failed += 1           # a worker could not compile it: do not try again
                try:
                    self.last_error = marker.read_text(errors="replace")[-500:]
                except OSError:
                    pass
            else:
                self._enqueue(f, key, lib)
            return f
        g = None
        for attempt in range(2):   # a damaged or stale library is removed and built again once
            try:
                if not lib.exists():
                    if self.background:
                        return f           # a damaged library was removed: a later solve queues it
                    if time.perf_counter() > self.deadline - COMPILE_MARGIN:
                        self._skipped += 1
                        return f
                    self._build(f, key, lib)
                g = ca.external(kernel_symbol(key), str(lib))
                if self.values(g, self.probes(f)) != expected:
                    if self.background:    # compiled, but not to the same numbers: never again
                        lib.with_suffix(".failed").write_text("the compiled kernel does not reproduce "
                                                              "the virtual machine's values\n")
                        lib.unlink(missing_ok=True)
                    raise RuntimeError(f"{lib}: the compiled kernel does not reproduce the original")
                break
            except Exception as err:   # no compiler output, a damaged or stale library, ...
                g = None
                self.last_error = str(err)[-500:]
                if attempt == 0 and lib.exists():
                    lib.unlink(missing_ok=True)
                    continue
                break
        if g is None:
            self.failed += 1
            return f
        self.loaded += 1
        self._memo[key] = g
        try:
            os.utime(lib)          # recently used: the size limit removes the oldest (`prune`)
        except OSError:
            pass
        return g

    def newly_ready(self) -> bool:
        """True, once, when a caller holding Functions built before should rebuild them:
        background mode, every kernel this process queued has been compiled (or has failed)
        and at least one of them is a library now (why all and not each: rebuilding the
        templates costs seconds, so it is done once per batch; a worker is started again if
        jobs wait and none runs); "now" mode, kernels were left to the VM because a solve's
        deadline was near (the next solve compiles them)."""
        if self._skipped:
            self._skipped = 0
            return True
        if not self._pending:
            return False
        waiting = {k: lib for k, lib in self._pending.items()
                   if not lib.exists() and not lib.with_suffix(".failed").exists()}
        if waiting:
            self._start_worker()
            return False
        ready = any(lib.exists() for lib in self._pending.values())
        self._pending.clear()
        return ready

    def _enqueue(self, f: ca.Function, key: str, lib: Path) -> None:
        """Queue f for the background worker (`gnppdsl.nlp.jit_worker`): the Function saved in
        a directory of this process (`<key>.<random>.tmp`), renamed to `jobs/<key>` when
        complete, and a worker started unless one runs. Not twice in one process; a job for the
        same kernel queued by another process is left as it is (a worker is started for it if
        none runs: its own worker may have died)."""
        if key in self._pending:
            return
        root = self.directory / "jobs"
        job = root / key
        t0 = time.perf_counter()
        tmp = None
        try:
            if not job.exists():
                root.mkdir(parents=True, exist_ok=True)
                tmp = Path(tempfile.mkdtemp(dir=root, prefix=key + ".", suffix=".tmp"))
                f.save(str(tmp / "kernel.casadi"))
                try:
                    os.rename(tmp, job)            # fails if another process queued it meanwhile
                    self.queued += 1
                except OSError:
                    if not job.exists():
                        raise
            self._pending[key] = lib
            self._start_worker()
        except Exception as err:                   # no job: the kernel stays in the VM
            self.failed += 1
            self.last_error = str(err)[-500:]
        finally:
            if tmp is not None:
                shutil.rmtree(tmp, ignore_errors=True)
            self.compile_time += time.perf_counter() - t0

    def _start_worker(self) -> None:
        """Start a worker unless one is starting (its parent, which exits once the child has
        tried the lock, is still running) or one holds the cache's lock."""
        self._workers = [w for w in self._workers if w.poll() is None]      # reap finished parents
        if self._workers or _locked(self.directory):
            return
        try:
            self._workers.append(subprocess.Popen(
                [sys.executable, "-m", "gnppdsl.nlp.jit_worker", str(self.directory), self.cc, *FLAGS],
                stdin=subprocess.DEVNULL, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
                close_fds=True))
        except OSError as err:                     # the jobs stay queued for a later solve
            self.last_error = f"cannot start the jit worker: {err}"

    @staticmethod
    def probes(f: ca.Function) -> list[list[np.ndarray]]:
        """Two fixed pseudo-random inputs (the same in every process)."""
        rng = np.random.default_rng(20261121)
        return [[rng.uniform(-1.0, 1.0, f.size_in(i)) for i in range(f.n_in())] for _ in range(2)]

    @staticmethod
    def values(f: ca.Function, probes: list) -> bytes:
        out = []
        for args in probes:
            out += [np.asarray(ca.DM(y).nonzeros(), dtype=float).tobytes() for y in f.call(args)]
        return b"".join(out)

    @classmethod
    def key(cls, f: ca.Function) -> tuple[str, bytes]:
        """(cache key, f's values at the probes). The key hashes the casadi version, the flags,
        f's shape (input sizes, output sparsity, instruction count) and its values at two
        fixed random inputs. Why not `Function.serialize`: it took 24 ms on a 50k-instruction
        Hessian (0.75 s of a 3 s lab1 solve), two evaluations take ~1 ms; two different SX
        graphs of the same shape agreeing bit for bit at two random points is not a practical
        concern, and a loaded library is checked against these values anyway."""
        h = hashlib.sha256()
        h.update(f"{ca.__version__}|{' '.join(FLAGS)}|{f.n_instructions()}".encode())
        for i in range(f.n_in()):
            h.update(f"in{f.size_in(i)}".encode())
        for i in range(f.n_out()):
            sp = f.sparsity_out(i)
            h.update(f"out{sp.size()}{sp.nnz()}".encode())
            h.update(np.asarray(sp.colind(), dtype=np.int64).tobytes())
            h.update(np.asarray(sp.row(), dtype=np.int64).tobytes())
        vals = cls.values(f, cls.probes(f))
        h.update(vals)
        return h.hexdigest()[:32], vals

    def _build(self, f: ca.Function, key: str, lib: Path) -> None:
        t0 = time.perf_counter()
        try:
            self.directory.mkdir(parents=True, exist_ok=True)
            with tempfile.TemporaryDirectory(prefix="gnpp_jit_") as tmp:
                src = generate_c(f, key, Path(tmp))
                out = src.with_suffix(".so")
                proc = subprocess.run([self.cc, *FLAGS, "-o", str(out), str(src)],
                                      capture_output=True, text=True, timeout=COMPILE_TIMEOUT)
                if proc.returncode != 0:
                    raise RuntimeError(f"{self.cc} failed: {proc.stderr[-1000:]}")
                install_library(out, lib)
            self.compiled += 1
            lock = try_lock(self.directory)      # no worker busy: keep the size limit
            if lock is not None:
                try:
                    prune(self.directory)
                finally:
                    lock.close()
        finally:
            self.compile_time += time.perf_counter() - t0


def _locked(directory: Path) -> bool:
    """True when a background worker holds the cache's compile lock."""
    import fcntl

    try:
        with open(directory / ".compile.lock", "a") as fh:
            try:
                fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
            except OSError:
                return True
            fcntl.flock(fh, fcntl.LOCK_UN)
            return False
    except OSError:
        return False
