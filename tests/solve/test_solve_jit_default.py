"""The users' default JIT path (no --jit / --no-jit, no `jit` setting, GNPP_JIT unset): the
tests' conftest turns it off for every other solve (GNPP_JIT=0), so here it runs in child
processes with their own kernel cache. A first solve of lab1 queues its large derivative
kernels for the background compiler and still solves; once they are built, a second solve
loads them from the cache (native kernels) and gives the same plan. Slow (~30 kernels through
the C compiler): GNPP_SLOW=1, as `.ci/run` sets."""
from __future__ import annotations

import json
import os
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gnppdsl.nlp import jit

ROOT = Path(__file__).resolve().parents[2]
LAB1 = ROOT / "examples" / "lab" / "lab1.pntc"


def _solve(tmp_path: Path, out: str, env: dict) -> dict:
    p = subprocess.run([sys.executable, "-m", "gnppdsl.cli.main", "solve", str(LAB1), "--json",
                        str(tmp_path / out), "--quiet"], env=env, capture_output=True, text=True, timeout=900)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads((tmp_path / out).read_text())


@pytest.mark.slow
def test_default_jit_compiles_in_the_background_and_the_next_solve_uses_the_kernels(tmp_path):
    if jit.find_compiler() is None:
        pytest.skip("no C compiler")
    cache = tmp_path / "cache"
    env = {k: v for k, v in os.environ.items() if k != "GNPP_JIT"}
    env.update(GNPP_JIT_CACHE=str(cache), PYTHONPATH=str(ROOT))
    first = _solve(tmp_path, "a.json", env)
    assert first["solved"]
    s = first["stats"]
    assert s["kernels_queued"] > 0 and s["kernels_native"] == 0, s
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
    assert len(libs) + len(failed) == s["kernels_queued"] and not failed, [p.read_text() for p in failed]
    second = _solve(tmp_path, "b.json", env)
    assert second["solved"] and second["plan"] == first["plan"]
    assert second["stats"]["kernels_native"] > 0, second["stats"]
