"""Shared pytest switches and the suite's honesty rules.

- `@pytest.mark.slow` tests (long end-to-end solves: lab2-lab5, mobile, the planar reference of
  p6/p7, the default JIT path) are *deselected* unless GNPP_SLOW=1, so `make test` stays quick
  and the run says how many it left out ("N deselected") instead of listing them as skips.
  `.ci/run` sets GNPP_SLOW=1 and runs them all.
- A skip may name only a missing optional external tool (ALLOWED_SKIP). Any other skip -- a
  project module "not available yet", an example file "not present" -- is turned into a failure
  here, at collection and at run time: a missing piece of the project must never pass as a skip.
"""
import os
import re

import pytest

# The external tools a test may be skipped for (none is a dependency of the package itself):
# Fast Downward (up-fast-downward, test extra; its binary may fail to build on a platform), a C
# or C++ compiler (the JIT kernels, the native distance library), the `false` program (a
# failing-compiler stand-in), a Chromium-type browser (the viewer's page test), ray and
# matplotlib (optional packages of `gnpp bench --workers` / `--plot`), unified_planning (the
# lifted PDDL test's second parser).
ALLOWED_SKIP = re.compile(r"Fast Downward|up_fast_downward|unified_planning|C\+\+ compiler|C compiler"
                          r"|`false` program|chromium|browser|\bray\b|matplotlib", re.IGNORECASE)


def _skip_reason(report) -> str:
    lr = report.longrepr
    return lr[2] if isinstance(lr, tuple) and len(lr) == 3 else str(lr)


def _forbid_skip(report) -> None:
    if report.skipped and not hasattr(report, "wasxfail"):
        reason = _skip_reason(report)
        if not ALLOWED_SKIP.search(reason):
            report.outcome = "failed"
            report.longrepr = (f"a skip that names no allowed external tool is a failure "
                               f"(tests/conftest.py ALLOWED_SKIP): {reason}")


@pytest.hookimpl(hookwrapper=True)
def pytest_runtest_makereport(item, call):
    outcome = yield
    _forbid_skip(outcome.get_result())


@pytest.hookimpl(hookwrapper=True)
def pytest_make_collect_report(collector):
    outcome = yield
    _forbid_skip(outcome.get_result())


@pytest.hookimpl(tryfirst=True)      # before `-m` selects by the markers added here
def pytest_collection_modifyitems(config, items):
    # a test that reads a shared mobile solve runs where the mobile problems run (`.ci/run`:
    # `-m "slow and mobile"` in one process, `-m "slow and not mobile"` in the other)
    for it in items:
        if SHARED_MOBILE & set(getattr(it, "fixturenames", ())):
            it.add_marker(pytest.mark.mobile)
    if os.environ.get("GNPP_SLOW") == "1":
        return
    keep = [it for it in items if "slow" not in it.keywords]
    dropped = [it for it in items if "slow" in it.keywords]
    if dropped:
        config.hook.pytest_deselected(items=dropped)
        items[:] = keep


# Solves in the tests never start background kernel compilers (gnppdsl.nlp.jit's default mode):
# they would write to the user's cache and compete with the tests for the CPU. The jit tests
# build their KernelCaches explicitly, in temporary directories; tests/solve/test_solve_jit_default.py
# runs the users' default JIT path in a subprocess with its own cache.
os.environ.setdefault("GNPP_JIT", "0")
# Nor do they start the background build of the native distance library (gnppdsl.geometry.native):
# `make setup` builds it, and tests/geometry/test_geometry_native.py builds it when it is missing.
os.environ.setdefault("GNPP_NATIVE_BUILD", "0")
# The template Functions persisted across processes (gnppdsl.nlp.function_store) go to one
# temporary directory per test session, not to the user's cache; tests/nlp/test_nlp_function_store.py
# builds its stores in their own directories.
# The same for the pre-built reachability graphs (gnppdsl.reach.persist) and the compiled
# dataclass methods (gnppdsl.classcode).
for _var, _prefix in (("GNPP_FUNCTION_CACHE", "gnpp-functions-"), ("GNPP_REACH_CACHE", "gnpp-reach-"),
                      ("GNPP_CODE_CACHE", "gnpp-classcode-")):
    if _var not in os.environ:
        import tempfile
        os.environ[_var] = tempfile.mkdtemp(prefix=_prefix)


# ---- solves shared by several slow tests (tests/shared_solves.py), once per session ----------
SHARED_MOBILE = {"pick_place_rlgp"}


@pytest.fixture(scope="session")
def pick_place_rlgp(tmp_path_factory):
    """examples/mobile/pick_place.pntc by `gnpp solve --algorithm rlgp --seed 0 --time-limit 900
    --json` (R-LGP, as examples/README.md documents): the mobile solve-and-verify test, the JSON
    schema test and the CLI's `--algorithm rlgp` test read this one run (shared_solves.CliRun)."""
    from shared_solves import PICK_PLACE_ARGV, run_cli_capturing

    return run_cli_capturing(PICK_PLACE_ARGV, tmp_path_factory.mktemp("pick_place") / "pick_place.json")


@pytest.fixture(scope="session")
def lab1_kernels(tmp_path_factory):
    """lab1's derivative kernels compiled by `gnpp solve --jit` into an empty cache, once: the
    `--jit` test checks that run, the default-JIT test starts from a copy missing a few kernels
    (shared_solves.KernelCacheRun). Skips without a C compiler."""
    from gnppdsl.nlp import jit
    from shared_solves import compile_lab1_kernels

    if jit.find_compiler() is None:
        pytest.skip("no C compiler")
    return compile_lab1_kernels(tmp_path_factory.mktemp("lab1_kernels"))


@pytest.fixture(scope="session")
def native_library():
    """The native distance twin (`geometry/native_witness.cpp`), built here when it is missing
    and a compiler and coal's headers exist (about 6 s; a failed build is a failure), loaded
    whatever the user's GNPP_NATIVE says (that switch only turns its use off). Skips without a
    C++ compiler or coal's headers: the solver then uses the Python callback."""
    from gnppdsl.geometry import native

    path = native.library_path()
    if path is None:
        pytest.skip("no C++ compiler or no coal headers: the Python callback is used")
    saved = os.environ.pop("GNPP_NATIVE", None)
    try:
        if not path.is_file():
            native.build()
        native._LOADED.pop("lib", None)
        out = native.load(start_build=False)
        assert out is not None, f"{path} was built but does not load"
        yield out
    finally:
        if saved is not None:
            os.environ["GNPP_NATIVE"] = saved
