"""The users' default JIT path (no --jit / --no-jit, no `jit` setting, GNPP_JIT unset): the
tests' conftest turns it off for every other solve (GNPP_JIT=0), so here it runs in child
processes with their own kernel cache. The cache starts as a copy of the session's lab1 kernels
(tests/conftest.py lab1_kernels: compiled once by `gnpp solve --jit`, whose test is in
tests/cli) with `MISSING` of them removed: a first solve loads the others from the cache,
queues the missing ones for the background compiler and still solves; once they are built, a
second solve runs every kernel natively and gives the same plan. Slow (the session's kernels
through the C compiler): GNPP_SLOW=1, as `.ci/run` sets."""
from __future__ import annotations

import time

import pytest

from shared_solves import copy_cache, jit_env, solve_lab1_child

MISSING = 3     # kernels left for the background worker (more than one: it works through a queue)


@pytest.mark.slow
def test_default_jit_compiles_in_the_background_and_the_next_solve_uses_the_kernels(tmp_path, lab1_kernels):
    cache = copy_cache(lab1_kernels, tmp_path / "cache")
    libs = sorted(cache.glob("*.so"))
    n = lab1_kernels.first["stats"]["kernels_native"]      # what a lab1 solve runs natively
    assert len(libs) == n > MISSING, (len(libs), n)
    removed = [lib.name for lib in libs[:MISSING]]    # names are kernel hashes: an arbitrary, fixed choice
    for name in removed:
        (cache / name).unlink()
    env = jit_env(cache)
    first = solve_lab1_child(tmp_path / "a.json", env)
    assert first["solved"]
    s = first["stats"]
    assert s["kernels_queued"] == MISSING and s["kernels_native"] == n - MISSING, s
    # the detached worker outlives the solve (at low priority: on a loaded machine it may take
    # long); its jobs are directories `jobs/<key>` until it takes one (renamed `<key>.work`, so
    # no longer queued) and compiles it into `<key>.so` (or rejects it: `<key>.failed`); it holds
    # the cache's lock until the queue is empty. So the kernels are all done only when no job is
    # queued *and* the lock is free (an empty queue alone can mean "the last one is compiling").
    # No wall-clock deadline; jobs left with the lock free mean the worker is gone: a failure.
    from gnppdsl.nlp.jit_worker import jobs as queued, try_lock

    def jobs() -> list[str]:           # the worker's own view of its queue (cache/jobs/<key>)
        return [p.name for p in queued(cache)]

    while True:
        lock = try_lock(cache)
        if lock is None:               # a worker is compiling
            time.sleep(2)
            continue
        lock.close()
        if not jobs():
            break
        time.sleep(5)                  # jobs and no worker: give a just-started one a moment
        lock = try_lock(cache)
        if lock is not None:
            lock.close()
            assert not jobs(), f"jobs left without a worker: {jobs()}"
    libs, failed = list(cache.glob("*.so")), list(cache.glob("*.failed"))
    assert len(libs) + len(failed) == n and not failed, [p.read_text() for p in failed]
    assert all((cache / name).is_file() for name in removed)        # built again by the worker
    second = solve_lab1_child(tmp_path / "b.json", env)
    assert second["solved"] and second["plan"] == first["plan"]
    assert second["stats"]["kernels_native"] == n and second["stats"]["kernels_queued"] == 0, second["stats"]
