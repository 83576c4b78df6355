"""Background compiler of derivative kernels (`gnppdsl.nlp.jit`, background mode).

    python -m gnppdsl.nlp.jit_worker CACHE_DIR CC [FLAG ...]

A solve queues a kernel as a job directory `CACHE_DIR/jobs/<key>/` holding the casadi Function
(`kernel.casadi`, `Function.save`) and starts this worker. The worker detaches itself (it is
then no child of the solve: its CPU is not in the solve's times, and it outlives a `gnpp solve`
that ends first), lowers its priority, takes the cache's lock (one worker per cache directory)
and compiles the queued jobs one after the other, oldest first, until none is left: C code
from casadi's CodeGenerator, the C compiler, then the library moved into place atomically
(`CACHE_DIR/<key>.so`: a reader sees no library or a complete one) and the job removed. A
failed job leaves `<key>.failed` with the compiler's message, so no later solve queues it again.
"""
from __future__ import annotations

import fcntl
import os
import shutil
import subprocess
import sys
from pathlib import Path

COMPILE_TIMEOUT = 300.0     # seconds for one compiler run (niced: slower than in the foreground)
KERNEL_FILE = "kernel.casadi"


def lock_path(cache: Path) -> Path:
    return cache / ".compile.lock"


def jobs(cache: Path) -> list[Path]:
    """Complete job directories, oldest first (a job is written under `<key>.tmp`, then
    renamed, so a directory without the suffix is complete)."""
    root = cache / "jobs"
    if not root.is_dir():
        return []
    found = []
    for d in root.iterdir():
        if d.is_dir() and not d.name.endswith(".tmp") and (d / KERNEL_FILE).exists():
            try:
                found.append((d.stat().st_mtime, d))
            except OSError:
                continue
    return [d for _, d in sorted(found)]


def compile_one(job: Path, cache: Path, cc: str, flags: list[str]) -> bool:
    """Compile one job into `cache/<key>.so` (True), or mark it failed; remove the job."""
    import casadi as ca

    from gnppdsl.nlp.jit import KernelCache      # casadi: imported only when there is work

    key = job.name
    lib = cache / f"{key}.so"
    try:
        if lib.exists():
            return True
        src = KernelCache.generate(ca.Function.load(str(job / KERNEL_FILE)), key, job)
        out = src.with_suffix(".so")
        try:
            proc = subprocess.run([cc, *flags, "-o", str(out), str(src)],
                                  capture_output=True, text=True, timeout=COMPILE_TIMEOUT)
            failed = (proc.stderr[-2000:] or f"{cc} exited with {proc.returncode}") \
                if proc.returncode != 0 else None
        except (OSError, subprocess.TimeoutExpired) as err:
            failed = f"{cc}: {err}"
        if failed is not None:
            (cache / f"{key}.failed").write_text(failed)
            return False
        part = lib.with_name(f"{lib.name}.{os.getpid()}.part")
        try:
            shutil.copyfile(out, part)
            os.replace(part, lib)
        finally:
            part.unlink(missing_ok=True)
        return True
    except Exception as err:                    # an unreadable job, a full disk, ...
        try:
            (cache / f"{key}.failed").write_text(f"{type(err).__name__}: {err}")
        except OSError:
            pass
        return False
    finally:
        shutil.rmtree(job, ignore_errors=True)


def run_queue(cache: Path, cc: str, flags: list[str], seen: set[str] | None = None) -> int:
    """Compile jobs until none is left; return how many were compiled. Returns at once when
    another worker holds the lock (it will take the new jobs too). `seen`: jobs already tried
    (a job directory that cannot be removed is not compiled forever)."""
    seen = set() if seen is None else seen
    done = 0
    with open(lock_path(cache), "a") as lock:
        try:
            fcntl.flock(lock, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            return 0
        while True:
            queue = [j for j in jobs(cache) if j.name not in seen]
            if not queue:
                break
            seen.add(queue[0].name)
            done += compile_one(queue[0], cache, cc, flags)
    # a job queued between the last scan and the unlock: the solve that queued it saw the lock
    # held and started no worker, so look once more
    if any(j.name not in seen for j in jobs(cache)):
        done += run_queue(cache, cc, flags, seen)
    return done


def detach() -> bool:
    """Fork; the parent returns False (and exits), the child True in a new session. Why: the
    solve reaps the short-lived parent; the child is reparented, so its CPU time never shows
    up in the solve's RUSAGE_CHILDREN."""
    if os.fork() > 0:
        return False
    os.setsid()
    try:
        os.nice(10)
    except OSError:
        pass
    return True


def main(argv: list[str]) -> int:
    if len(argv) < 2:
        print(__doc__.strip().splitlines()[2].strip(), file=sys.stderr)
        return 2
    if not detach():
        return 0
    try:
        run_queue(Path(argv[0]), argv[1], argv[2:])
    finally:
        os._exit(0)                 # the forked child never returns into the interpreter's exit path


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
