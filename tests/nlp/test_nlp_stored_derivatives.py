"""Per-body derivative kernels found again in a new process without building their SX graphs
(`BodyCompiler._direct`, `KernelCache.cached`): a compiler with the same function store and
kernel cache as one that built them gives the same Jacobians and Hessians (values, sparsity)
without calling `direct_hessian` / `direct_jacobian`; a missing or damaged library, or a
record whose values the library does not give, is a rebuild, never a wrong Function."""
from __future__ import annotations

import shutil
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.nlp import body_compiler, jit
from gnppdsl.nlp.body_compiler import BodyCompiler, _has_repeats
from gnppdsl.nlp.function_store import FunctionStore
from gnppdsl.nlp.jit import KernelCache
from gnppdsl.solve.compiled import load_and_compile

LAB1 = Path(__file__).resolve().parents[2] / "examples" / "lab" / "lab1.pntc"
PLAN = "pick(b2, left_arm, table); stack(b2, left_arm, b1)"

needs_cc = pytest.mark.skipif(jit.find_compiler() is None, reason="no C compiler")


@pytest.fixture(scope="module")
def lab():
    c = load_and_compile(str(LAB1))
    factors = c.factory.factors(plan_states(c.task, parse_plan(c.task, PLAN)))
    probe = BodyCompiler(c.geometry, store=None)
    # bodies differentiated directly (no repeated rows), one querying distances, one not
    picked, kinds = [], set()
    for f in sorted(factors, key=lambda f: f.template):
        cb, _ = probe.compile(f)
        kind = cb.open_function is not None
        if cb.symbolic == "SX" and cb.n_rows and not _has_repeats(cb) and kind not in kinds:
            kinds.add(kind)
            picked.append(f)
    assert kinds == {True, False}
    return c, picked


def _compiler(c, tmp_path: Path) -> BodyCompiler:
    return BodyCompiler(c.geometry, kernels=KernelCache(tmp_path / "jit", min_instructions=0),
                        store=FunctionStore(tmp_path / "functions"))


def _args(cb, rng) -> list:
    return [rng.uniform(-0.5, 0.5, d) for d in cb.slot_dims] + [rng.uniform(-0.5, 0.5, cb.n_params)]


def _same(fa: ca.Function, fb: ca.Function, args: list) -> None:
    assert fa.sparsity_out(0) == fb.sparsity_out(0)
    np.testing.assert_allclose(np.array(fa(*args)), np.array(fb(*args)), rtol=1e-12, atol=1e-12)


def _no_builds(monkeypatch) -> None:
    def fail(*a, **k):
        raise AssertionError("built the SX derivative although its kernel is stored")
    monkeypatch.setattr(body_compiler, "direct_hessian", fail)
    monkeypatch.setattr(body_compiler, "direct_jacobian", fail)


@needs_cc
def test_a_new_compiler_loads_the_derivative_kernels_without_building_them(lab, tmp_path, monkeypatch):
    c, factors = lab
    writer = _compiler(c, tmp_path)
    for f in factors:
        cb, _ = writer.compile(f)
        writer.hessian(cb), writer.jacobian(cb)
    assert writer.kernels.compiled == 2 * len(factors)
    fresh = BodyCompiler(c.geometry, store=None)
    built = [(a, fresh.jacobian(a), fresh.hessian(a)) for a in (fresh.compile(f)[0] for f in factors)]
    reader = _compiler(c, tmp_path)
    _no_builds(monkeypatch)
    rng = np.random.default_rng(1)
    for f, (a, jf, hf) in zip(factors, built):
        b, _ = reader.compile(f)
        args = _args(a, rng)
        _same(jf, reader.jacobian(b), args)
        _same(hf, reader.hessian(b), [*args, rng.uniform(-1, 1, a.n_rows)])
    assert reader.kernels.loaded == 2 * len(factors) and reader.kernels.compiled == 0


@needs_cc
def test_a_missing_or_foreign_library_is_rebuilt(lab, tmp_path):
    c, factors = lab
    writer = _compiler(c, tmp_path)
    for f in factors:
        writer.hessian(writer.compile(f)[0])
    # a copy (other paths: the libraries loaded above are not the ones the reader opens)
    shutil.copytree(tmp_path / "jit", tmp_path / "b" / "jit")
    shutil.copytree(tmp_path / "functions", tmp_path / "b" / "functions")
    libs = sorted((tmp_path / "b" / "jit").glob("*.so"))
    assert len(libs) == len(factors)
    libs[0].unlink()                         # gone
    # another kernel's library under the second one's name: it does not give the stored values
    other = KernelCache(tmp_path / "other", min_instructions=0)
    x = ca.SX.sym("x", 3)
    other.native(ca.Function("k", [x], [ca.sin(x) * x[0]]))
    libs[1].unlink()
    shutil.copy(next((tmp_path / "other").glob("*.so")), libs[1])
    fresh = BodyCompiler(c.geometry, store=None)
    reader = _compiler(c, tmp_path / "b")
    rng = np.random.default_rng(2)
    for f in factors:
        a, _ = fresh.compile(f)
        b, _ = reader.compile(f)
        args = [*_args(a, rng), rng.uniform(-1, 1, a.n_rows)]
        _same(fresh.hessian(a), reader.hessian(b), args)
    assert reader.kernels.compiled == 2          # both built again, through `native`
