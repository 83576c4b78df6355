"""Background compiler of derivative kernels (`gnppdsl.nlp.jit`, background mode).

    python -m gnppdsl.nlp.jit_worker CACHE_DIR CC [FLAG ...]

A solve queues a kernel as a job directory `CACHE_DIR/jobs/<key>/` holding the casadi Function
(`kernel.casadi`, `Function.save`) and starts this worker. The worker detaches itself (a new
session: it is then no child of the solve, so its CPU is not in the solve's times, and it
outlives a `gnpp solve` that ends first), lowers its priority (nice and, where the kernel
groups processes by session, its autogroup's nice), and takes the cache's lock: one worker per
cache directory. Then it compiles the queued jobs one after the other, oldest first, until none
is left: each job is first renamed to `<key>.work` (so no solve re-queues or removes it
meanwhile), then C code from casadi's CodeGenerator, the C compiler, the library moved into
place atomically (`CACHE_DIR/<key>.so`: a reader sees no library or a complete one), and the
work directory removed. When the compiler rejects the code, `<key>.failed` keeps its message
and no later solve queues the kernel again; a timeout or an I/O error leaves no marker (a later
solve queues it again).
"""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

from gnppdsl.nlp.jit_codegen import generate_c

COMPILE_CPU_LIMIT = 300    # CPU seconds for one compiler run (RLIMIT_CPU of the compiler)
COMPILE_TIMEOUT = 3600.0   # wall seconds: generous, since a niced compile on a busy machine
                           # waits for CPU; the CPU limit is what stops a runaway compiler
KERNEL_FILE = "kernel.casadi"


def lock_path(cache: Path) -> Path:
    return cache / ".compile.lock"


def jobs(cache: Path) -> list[Path]:
    """Queued jobs, oldest first: directories `jobs/<key>` (written under a temporary name
    ending in `.tmp`, then renamed, so a name without a suffix is complete)."""
    root = cache / "jobs"
    if not root.is_dir():
        return []
    found = []
    for d in root.iterdir():
        if "." not in d.name and (d / KERNEL_FILE).exists():
            try:
                found.append((d.stat().st_mtime, d))
            except OSError:
                continue
    return [d for _, d in sorted(found)]


def remove_orphans(cache: Path) -> None:
    """Remove `.work` directories: with the lock held, no worker is working on them (one
    killed mid-compile left them; their kernels get queued again by a later solve)."""
    root = cache / "jobs"
    if root.is_dir():
        for d in root.glob("*.work"):
            shutil.rmtree(d, ignore_errors=True)


def compile_one(job: Path, cache: Path, cc: str, flags: list[str]) -> bool:
    """Compile one job into `cache/<key>.so` (True); remove it either way."""
    import casadi as ca                          # imported only when there is work

    key = job.name
    lib = cache / f"{key}.so"
    work = job.with_name(key + ".work")
    try:
        os.replace(job, work)
    except OSError:
        return False                             # gone meanwhile
    try:
        if lib.exists():
            return True
        src = generate_c(ca.Function.load(str(work / KERNEL_FILE)), key, work)
        out = src.with_suffix(".so")
        try:
            proc = subprocess.run([cc, *flags, "-o", str(out), str(src)], capture_output=True,
                                  text=True, timeout=COMPILE_TIMEOUT, preexec_fn=_limit_cpu)
        except (OSError, subprocess.TimeoutExpired):
            return False                         # not the code's fault: no marker
        if proc.returncode != 0:
            (cache / f"{key}.failed").write_text(proc.stderr[-2000:] or f"{cc} exited with {proc.returncode}")
            return False
        install_library(out, lib)
        return True
    except Exception:                            # an unreadable job, a full disk, ...
        return False
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _limit_cpu() -> None:
    """In the compiler's child process: a CPU-time limit, not a wall-clock one (why: the worker
    is niced, so on a loaded machine a compile of a few CPU seconds can wait minutes for CPU;
    a wall-clock limit would drop it without a marker and the kernel would never be ready)."""
    import resource
    resource.setrlimit(resource.RLIMIT_CPU, (COMPILE_CPU_LIMIT, COMPILE_CPU_LIMIT + 10))


def install_library(built: Path, lib: Path) -> None:
    """Copy a compiled library into the cache atomically (a part file, then a rename): a
    concurrent solve sees either no library or a complete one."""
    part = lib.with_name(f"{lib.name}.{os.getpid()}.part")
    try:
        shutil.copyfile(built, part)
        os.replace(part, lib)
    finally:
        part.unlink(missing_ok=True)


def cache_limit() -> int:
    """Bytes of compiled kernels a cache keeps (`GNPP_JIT_CACHE_MB`, default 512 MB; a Lab
    problem's kernels take 10-40 MB)."""
    try:
        return int(float(os.environ.get("GNPP_JIT_CACHE_MB", "512")) * 2 ** 20)
    except ValueError:
        return 512 * 2 ** 20


def prune(cache: Path, limit: int | None = None) -> list[Path]:
    """With the lock held: remove the least recently used libraries (by modification time,
    which a solve refreshes when it loads one) until the libraries take at most `limit`
    bytes; return the removed paths. Why safe: a process that has a removed library loaded
    keeps its mapping, and a later solve queues the kernel again."""
    limit = cache_limit() if limit is None else limit
    libs = []
    for lib in cache.glob("*.so"):
        try:
            st = lib.stat()
        except OSError:
            continue
        libs.append((st.st_mtime, st.st_size, lib))
    total = sum(size for _, size, _ in libs)
    removed = []
    for _, size, lib in sorted(libs):
        if total <= limit:
            break
        try:
            lib.unlink()
        except OSError:
            continue
        total -= size
        removed.append(lib)
    return removed


def run_queue(cache: Path, cc: str, flags: list[str]) -> int:
    """With the lock held: compile jobs until none is left, then keep the cache within its
    size limit (`prune`); return how many were compiled."""
    done = 0
    remove_orphans(cache)
    tried: set[str] = set()          # a job that reappears under the same key is not looped on
    while True:
        queue = [j for j in jobs(cache) if j.name not in tried]
        if not queue:
            prune(cache)
            return done
        tried.add(queue[0].name)
        done += compile_one(queue[0], cache, cc, flags)


def try_lock(cache: Path):
    """The open lock file with an exclusive lock, or None when another worker holds it."""
    fh = open(lock_path(cache), "a")
    try:
        fcntl.flock(fh, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError:
        fh.close()
        return None
    return fh


def serve(cache: Path, cc: str, flags: list[str], lock) -> None:
    """Compile the queue; after unlocking, look once more: a job queued between the last scan
    and the unlock was queued by a solve that saw the lock held and started no worker."""
    while lock is not None:
        try:
            run_queue(cache, cc, flags)
        finally:
            lock.close()
        lock = try_lock(cache) if jobs(cache) else None


def lower_priority() -> None:
    try:
        os.nice(10)
    except OSError:
        pass
    try:                             # Linux autogroups: nice counts only inside the group
        Path("/proc/self/autogroup").write_text("19")
    except OSError:
        pass


def main(argv: list[str]) -> int:
    """Fork: the child (new session, low priority) tries the lock and tells the parent
    whether it got it; the parent exits then. So while the parent runs, a worker is starting
    (the solve does not start another), and once it has exited, the lock says whether one is
    working. The child is reparented: its CPU never shows up in the solve's RUSAGE_CHILDREN."""
    if len(argv) < 2:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    cache, cc, flags = Path(argv[0]), argv[1], argv[2:]
    r, w = os.pipe()
    if os.fork() > 0:
        os.close(w)
        os.read(r, 1)                # the child has tried the lock (or died: EOF)
        return 0
    os.close(r)
    code = 0
    try:
        os.setsid()
        lower_priority()
        lock = try_lock(cache)
        os.write(w, b"1" if lock is not None else b"0")
        os.close(w)
        serve(cache, cc, flags, lock)
    except BaseException:
        code = 1
    finally:
        os._exit(code)               # the forked child never returns into the interpreter's exit path


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
