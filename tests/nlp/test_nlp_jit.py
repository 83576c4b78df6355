"""Compiled derivative kernels (`gnppdsl.nlp.jit`): the same numbers as casadi's virtual
machine, a disk cache that later processes load without compiling, and every failure (a
damaged library, no compiler) leaves the original Function in place. Also the `jit` solver
setting and its located error. Skipped where there is no C compiler."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from gnppdsl.errors import UserError
from gnppdsl.nlp import jit
from gnppdsl.nlp.jit import KernelCache

needs_cc = pytest.mark.skipif(jit.find_compiler() is None, reason="no C compiler")
ROOT = Path(__file__).resolve().parents[2]


def _kernel(n: int = 6) -> ca.Function:
    """A Hessian of a trigonometric chain: a dense SX graph like the robots' kernels."""
    q, lam = ca.SX.sym("q", n), ca.SX.sym("lam", 3)
    R, p = ca.SX.eye(3), ca.SX.zeros(3)
    for k in range(n):
        c, s = ca.cos(q[k]), ca.sin(q[k])
        Rk = ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1)) if k % 2 \
            else ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c))
        p = p + ca.mtimes(R, ca.DM([0.1, 0.0, 0.3]))
        R = ca.mtimes(R, Rk)
    h = ca.vertcat(ca.sumsqr(p) - 0.2, p[0] * p[1], ca.sqrt(ca.sumsqr(p) + 1e-9))
    H = ca.hessian(ca.dot(lam, h), q)[0]
    return ca.Function("chain_hessian", [q, lam], [H])


def _damaged_cache(directory):
    """A cache holding one library for `_kernel()` whose bytes are then overwritten."""
    f = _kernel()
    KernelCache(directory, min_instructions=10).native(f)
    (lib,) = directory.glob("*.so")
    lib.write_bytes(b"not a shared library")
    return f


def _same(f, g, seed=0):
    rng = np.random.default_rng(seed)
    for _ in range(5):
        args = [rng.uniform(-3, 3, f.size_in(i)) for i in range(f.n_in())]
        a = [np.asarray(y) for y in f.call(args)]
        b = [np.asarray(y) for y in g.call(args)]
        assert all(np.array_equal(x, y) for x, y in zip(a, b))


@needs_cc
def test_a_compiled_kernel_gives_the_same_numbers_and_is_loaded_from_the_cache_later(tmp_path):
    f = _kernel()
    kc = KernelCache(tmp_path, min_instructions=10)
    g = kc.native(f)
    assert g is not f and not g.is_a("SXFunction")
    assert (kc.compiled, kc.loaded, kc.failed) == (1, 1, 0)
    _same(f, g)
    assert kc.native(f) is g                      # memo within a process
    # another process (a fresh cache object) loads the library without compiling
    kc2 = KernelCache(tmp_path, min_instructions=10)
    g2 = kc2.native(_kernel())
    assert (kc2.compiled, kc2.loaded) == (0, 1)
    _same(f, g2)
    # a different function gets a different library
    kc2.native(_kernel(5))
    assert kc2.compiled == 1 and len(list(tmp_path.glob("*.so"))) == 2


@needs_cc
def test_small_kernels_and_non_sx_functions_stay_in_the_virtual_machine(tmp_path):
    f = _kernel(2)
    assert KernelCache(tmp_path, min_instructions=10 ** 6).native(f) is f
    x = ca.MX.sym("x", 2)
    m = ca.Function("m", [x], [ca.sin(x)])
    assert KernelCache(tmp_path, min_instructions=1).native(m) is m
    assert not list(tmp_path.glob("*.so"))


@needs_cc
def test_a_damaged_library_in_the_cache_is_not_used(tmp_path):
    f = _damaged_cache(tmp_path)
    false = jit.shutil.which("false")               # and it cannot be built again
    kc = KernelCache(tmp_path, min_instructions=10, cc=false or str(tmp_path / "no-cc"))
    assert kc.native(f) is f and kc.failed == 1 and kc.loaded == 0
    assert not list(tmp_path.glob("*.so"))          # the damaged library was removed


def test_without_a_compiler_nothing_changes(tmp_path, monkeypatch):
    monkeypatch.setenv("GNPP_CC", str(tmp_path / "no-such-cc"))
    assert jit.find_compiler() is None
    kc = KernelCache(tmp_path, min_instructions=10)
    f = _kernel()
    assert kc.native(f) is f and kc.compiled == 0


def test_the_environment_can_turn_the_setting_off(monkeypatch):
    monkeypatch.delenv("GNPP_JIT", raising=False)     # tests/conftest.py sets it for the solves
    assert jit.enabled(True) and not jit.enabled(False)
    monkeypatch.setenv("GNPP_JIT", "0")
    assert not jit.enabled(True)


@needs_cc
def test_panda_derivatives_through_compiled_kernels_match_the_virtual_machine(tmp_path):
    """The Jacobian and Hessian Functions the solver assembles for lab1's factors, with and
    without compiled kernels, agree bit for bit at random points (two large Panda bodies, to
    keep the compile time of the test short)."""
    from gnppdsl.nlp.body_compiler import BodyCompiler
    from gnppdsl.solve.compiled import load_and_compile

    comp = load_and_compile(str(ROOT / "examples" / "lab" / "lab1.pntc"))
    plan_states = [comp.task.initial]
    factors = comp.factory.factors(plan_states)
    plain = BodyCompiler(comp.geometry)
    kc = KernelCache(tmp_path, min_instructions=15000)
    fast = BodyCompiler(comp.geometry, kernels=kc)
    bodies = {}
    for f in factors:
        cb, _ = plain.compile(f)
        bodies.setdefault(cb.function.name(), f)
    for name, f in sorted(bodies.items()):
        cb, p = plain.compile(f)
        cf, _ = fast.compile(f)
        hp, hf = plain.hessian(cb), fast.hessian(cf)
        jp, jf = plain.jacobian(cb), fast.jacobian(cf)
        rng = np.random.default_rng(1)
        for _ in range(2):
            args = [rng.uniform(-1, 1, hp.size_in(i)) for i in range(hp.n_in() - 2)]
            args += [p, rng.normal(size=hp.size_in(hp.n_in() - 1))]
            assert np.array_equal(np.asarray(hp.call(args)[0]), np.asarray(hf.call(args)[0])), name
            assert np.array_equal(np.asarray(jp.call(args[:-1])[0]), np.asarray(jf.call(args[:-1])[0])), name
        if kc.loaded >= 2:
            break
    assert kc.loaded >= 2 and kc.failed == 0


def _planar_problem(tmp_path, line: str) -> Path:
    planar = ROOT / "examples" / "planar"
    text = (planar / "p1_one_block.pntc").read_text().rstrip("\n") + "\n" + line + "\n"
    for extra in planar.iterdir():
        if extra.name != "p1_one_block.pntc":
            (tmp_path / extra.name).write_text(extra.read_text())
    (tmp_path / "p1_one_block.pntc").write_text(text)
    return tmp_path / "p1_one_block.pntc"


def test_jit_setting_reaches_the_options_and_a_bad_value_is_located(tmp_path):
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.options import SolveOptions

    c = load_and_compile(str(_planar_problem(tmp_path, "solver { jit = true }")))
    assert c.problem.settings.jit is True
    assert SolveOptions.from_settings(c.problem.settings).jit is True
    assert SolveOptions.from_settings(c.problem.settings, jit=False).jit is False
    (tmp_path / "b").mkdir()
    bad = _planar_problem(tmp_path / "b", "solver { jit = 3 }")
    with pytest.raises(UserError) as e:
        load_and_compile(str(bad))
    line = len(bad.read_text().splitlines())
    assert "'jit' must be true or false" in str(e.value) and f"p1_one_block.pntc:{line}:" in str(e.value)


@needs_cc
def test_a_failing_compiler_leaves_the_function_and_no_files(tmp_path):
    false = jit.shutil.which("false")
    if false is None:
        pytest.skip("no `false` program")
    kc = KernelCache(tmp_path, min_instructions=10, cc=false)
    f = _kernel()
    assert kc.native(f) is f and kc.failed == 1 and "failed" in kc.last_error
    assert not list(tmp_path.iterdir())              # no library, no part file


@needs_cc
def test_a_damaged_library_is_rebuilt_once(tmp_path):
    f = _damaged_cache(tmp_path)
    kc = KernelCache(tmp_path, min_instructions=10)
    g = kc.native(f)
    assert g is not f and kc.compiled == 1 and kc.failed == 0
    _same(f, g)


def test_an_unwritable_cache_is_a_clear_user_error(tmp_path):
    blocker = tmp_path / "file"
    blocker.write_text("not a directory")
    with pytest.raises(UserError, match="not writable.*--no-jit"):
        KernelCache(blocker / "cache", min_instructions=10)


@needs_cc
def test_kernels_with_nan_at_a_probe_are_not_compiled(tmp_path):
    x = ca.SX.sym("x", 3)
    e = ca.log(x - 5.0)                               # NaN on the probes' range [-1, 1]
    for _ in range(6):
        e = ca.sin(e) * e + x[0]
    f = ca.Function("nan_at_probes", [x], [ca.hessian(ca.sum1(e), x)[0]])
    kc = KernelCache(tmp_path, min_instructions=10)
    assert kc.native(f) is f and kc.compiled == 0


def test_compiling_stops_near_the_deadline(tmp_path):
    import time

    kc = KernelCache(tmp_path, min_instructions=10, deadline=time.perf_counter())
    f = _kernel()
    assert kc.native(f) is f and kc.compiled == 0 and not list(tmp_path.glob("*.so"))
    # a compiler shared by later solves is rebuilt once, so that the next solve compiles it
    assert kc.newly_ready() and not kc.newly_ready()
