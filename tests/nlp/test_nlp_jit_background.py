"""The default jit mode (`gnppdsl.nlp.jit`, "background"): a missing kernel is queued for a
detached worker (`gnppdsl.nlp.jit_worker`) and the solve keeps casadi's Function; a later
cache loads the compiled library, which gives the same numbers bit for bit; a kernel whose
compile failed is marked and not queued again; a job another process queued is not queued
twice; the modes of the setting (the rebuild of the shared template compiler once the queued
kernels are ready: tests/solve/test_solve_shared_templates.py). Skipped where there is no C
compiler."""
from __future__ import annotations

import time
from pathlib import Path

import pytest

from gnppdsl.errors import UserError
from gnppdsl.nlp import jit
from gnppdsl.nlp.jit import KernelCache
from test_nlp_jit import _kernel, _same

needs_cc = pytest.mark.skipif(jit.find_compiler() is None, reason="no C compiler")


def _wait_for(path: Path, timeout: float = 180.0) -> None:
    t0 = time.monotonic()
    while not path.exists():
        if time.monotonic() - t0 > timeout:
            raise AssertionError(f"no {path.name} after {timeout:.0f} s")
        time.sleep(0.1)


@needs_cc
def test_a_queued_kernel_is_compiled_in_the_background_and_loaded_by_a_later_cache(tmp_path):
    f = _kernel()
    kc = KernelCache(tmp_path, min_instructions=10, background=True)
    assert kc.native(f) is f                         # this solve keeps the VM Function
    assert kc.native(f) is f and kc.queued == 1 and kc.compiled == 0
    key, _ = KernelCache.key(f)
    _wait_for(tmp_path / f"{key}.so")
    t0 = time.monotonic()
    while list((tmp_path / "jobs").iterdir()) and time.monotonic() - t0 < 30:
        time.sleep(0.1)                              # the worker removes the job after the move
    assert not list((tmp_path / "jobs").iterdir())
    assert kc.newly_ready() and not kc.newly_ready()     # reported once
    later = KernelCache(tmp_path, min_instructions=10, background=True)
    g = later.native(f)
    assert g is not f and later.loaded == 1 and later.queued == 0
    _same(f, g)


@needs_cc
def test_a_failed_background_compile_is_marked_and_not_queued_again(tmp_path):
    false = jit.shutil.which("false")
    if false is None:
        pytest.skip("no `false` program")
    f = _kernel()
    kc = KernelCache(tmp_path, min_instructions=10, cc=false, background=True)
    assert kc.native(f) is f and kc.queued == 1
    key, _ = KernelCache.key(f)
    _wait_for(tmp_path / f"{key}.failed")
    assert not (tmp_path / f"{key}.so").exists()
    assert not kc.newly_ready()                      # failed: nothing to rebuild for
    again = KernelCache(tmp_path, min_instructions=10, background=True)
    assert again.native(f) is f and again.queued == 0 and again.failed == 1
    assert again.last_error                          # the compiler's message


def _job(directory: Path, f) -> Path:
    """A complete job for f, as another process would have queued it."""
    key, _ = KernelCache.key(f)
    job = directory / "jobs" / key
    job.mkdir(parents=True)
    f.save(str(job / "kernel.casadi"))
    return job


def test_a_job_queued_by_another_process_is_not_queued_twice(tmp_path, monkeypatch):
    f = _kernel()
    job = _job(tmp_path, f)
    before = (job / "kernel.casadi").read_bytes()
    kc = KernelCache(tmp_path, min_instructions=10, cc="cc", background=True)
    monkeypatch.setattr(kc, "_start_worker", lambda: None)     # only the queue is looked at here
    assert kc.native(f) is f and kc.queued == 0 and kc.failed == 0
    assert (job / "kernel.casadi").read_bytes() == before     # not rewritten
    assert not [p for p in (tmp_path / "jobs").iterdir() if p.name.endswith(".tmp")]


def test_queueing_the_same_kernel_in_two_processes_at_once(tmp_path, monkeypatch):
    """The second process's rename finds the first one's job: it waits for that job, without
    a failure, and leaves no temporary directory."""
    f = _kernel()
    kc = KernelCache(tmp_path, min_instructions=10, cc="cc", background=True)
    monkeypatch.setattr(kc, "_start_worker", lambda: None)
    real_save = jit.ca.Function.save

    def save_then_other_process_wins(self, path):
        real_save(self, path)
        other = tmp_path / "jobs" / KernelCache.key(f)[0]     # the other process renames first
        other.mkdir()
        (other / "kernel.casadi").write_text("queued by the other process")

    monkeypatch.setattr(jit.ca.Function, "save", save_then_other_process_wins)
    assert kc.native(f) is f
    assert kc.queued == 0 and kc.failed == 0 and kc._pending
    assert sorted(p.name for p in (tmp_path / "jobs").iterdir()) == [KernelCache.key(f)[0]]


@needs_cc
def test_an_orphaned_job_is_compiled_by_the_next_solve_s_worker(tmp_path):
    """A job whose worker died (and a `.work` directory it left) is not a reason to wait: the
    next solve that needs the kernel starts a worker, which compiles it."""
    f = _kernel()
    job = _job(tmp_path, f)
    orphan = job.with_name("0" * 32 + ".work")
    orphan.mkdir()
    kc = KernelCache(tmp_path, min_instructions=10, background=True)
    assert kc.native(f) is f and kc.queued == 0
    _wait_for(tmp_path / f"{job.name}.so")
    t0 = time.monotonic()
    while orphan.exists() and time.monotonic() - t0 < 30:
        time.sleep(0.1)
    assert not orphan.exists()
    assert kc.newly_ready()
    _same(f, KernelCache(tmp_path, min_instructions=10, background=True).native(f))


@needs_cc
def test_a_library_that_gives_other_numbers_is_marked_and_never_queued_again(tmp_path):
    f = _kernel()
    key, _ = KernelCache.key(f)
    q, lam = jit.ca.SX.sym("q", 6), jit.ca.SX.sym("lam", 3)
    other = jit.ca.Function("other", [q, lam], [2 * f(q, lam)])   # same shape, other numbers
    KernelCache(tmp_path, min_instructions=10)._build(other, key, tmp_path / f"{key}.so")
    kc = KernelCache(tmp_path, min_instructions=10, background=True)
    assert kc.native(f) is f and kc.failed == 1 and kc.loaded == 0
    assert (tmp_path / f"{key}.failed").exists() and not (tmp_path / f"{key}.so").exists()
    again = KernelCache(tmp_path, min_instructions=10, background=True)
    assert again.native(f) is f and again.queued == 0 and again.failed == 1


def test_the_modes_of_the_setting(tmp_path, monkeypatch):
    monkeypatch.delenv("GNPP_JIT", raising=False)
    assert (jit.mode(None), jit.mode(True), jit.mode(False)) == ("background", "now", "off")
    monkeypatch.setenv("GNPP_JIT", "0")
    assert jit.mode(None) == jit.mode(True) == "off" and jit.kernel_cache("off") is None
    monkeypatch.delenv("GNPP_JIT")
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    monkeypatch.setenv("GNPP_JIT_CACHE", str(blocker / "cache"))
    monkeypatch.setenv("GNPP_CC", jit.shutil.which("true") or "sh")
    assert jit.kernel_cache("background") is None    # not asked for: quietly no kernels
    with pytest.raises(UserError, match="not writable"):
        jit.kernel_cache("now")                      # asked for: says why not
    monkeypatch.setenv("GNPP_JIT_CACHE", str(tmp_path / "ok"))
    kc = jit.kernel_cache("background")
    assert kc is not None and kc.background
    monkeypatch.setenv("GNPP_CC", str(tmp_path / "no-such-cc"))
    assert jit.kernel_cache("background") is None    # no compiler: no kernels


def test_prune_keeps_the_cache_within_its_limit_removing_the_least_recently_used(tmp_path):
    """Libraries beyond the size limit go oldest first (by modification time, which loading
    refreshes); jobs, markers and the newest libraries stay."""
    import os

    from gnppdsl.nlp.jit_worker import prune
    libs = []
    for i in range(6):
        lib = tmp_path / f"k{i}.so"
        lib.write_bytes(b"x" * 1000)
        os.utime(lib, (1000 + i, 1000 + i))
        libs.append(lib)
    (tmp_path / "k9.failed").write_text("no")
    os.utime(libs[0], (5000, 5000))             # k0 was loaded last: the most recent
    removed = prune(tmp_path, limit=3500)
    assert sorted(p.name for p in removed) == ["k1.so", "k2.so", "k3.so"]
    assert sorted(p.name for p in tmp_path.glob("*.so")) == ["k0.so", "k4.so", "k5.so"]
    assert (tmp_path / "k9.failed").exists()
    assert prune(tmp_path, limit=3500) == []


def test_loading_a_library_marks_it_recently_used(tmp_path):
    """A kernel loaded from the cache gets a fresh modification time (what `prune` keeps)."""
    import os

    import casadi as ca

    from gnppdsl.nlp.jit import KernelCache
    if KernelCache(tmp_path).cc is None:
        pytest.skip("no C compiler")
    x = ca.SX.sym("x", 30)
    e = x
    for _ in range(60):
        e = ca.sin(e) * ca.cos(e[::-1]) + e
    f = ca.Function("big", [x], [ca.jacobian(ca.sum1(e), x)])
    first = KernelCache(tmp_path, min_instructions=10)
    g = first.native(f)
    assert first.compiled == 1 and g is not f
    lib = next(tmp_path.glob("*.so"))
    os.utime(lib, (1000, 1000))
    second = KernelCache(tmp_path, min_instructions=10)
    second.native(f)
    assert second.loaded == 1 and lib.stat().st_mtime > 1000
