"""Importing gnppdsl before numpy / casadi keeps OpenBLAS to one thread (its waiting threads
spin and were a third of a Lab 5 run's CPU time), unless the user chose a number."""
from __future__ import annotations

import os
import subprocess
import sys

PROBE = ("import os, gnppdsl, numpy, casadi; "
         "numpy.ones((300, 300)) @ numpy.ones((300, 300)); "
         "print(os.environ['OPENBLAS_NUM_THREADS'], len(os.listdir('/proc/self/task')))")


def _run(extra_env: dict) -> list[str]:
    env = {k: v for k, v in os.environ.items() if k not in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS")}
    env.update(extra_env)
    out = subprocess.run([sys.executable, "-c", PROBE], env=env, capture_output=True, text=True, check=True)
    return out.stdout.split()


def test_one_blas_thread_by_default():
    assert _run({}) == ["1", "1"]


def test_the_users_choice_is_kept():
    assert _run({"OPENBLAS_NUM_THREADS": "2"})[0] == "2"
