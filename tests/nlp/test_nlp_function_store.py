"""Template Functions persisted across processes (`gnppdsl.nlp.function_store`): a body loaded
from the store must evaluate equal to the same body built fresh (values, distance queries,
open form, Jacobian and Hessian with their sparsity), on Lab bodies with Panda kinematics and
coal distances; the key must change with the template, its body, the slots, the robot model
and the code version; a corrupt file is a miss, never a wrong Function."""
from __future__ import annotations

import dataclasses
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.geometry.context import GeometryContext
from gnppdsl.nlp import function_store
from gnppdsl.nlp.body_compiler import BodyCompiler
from gnppdsl.nlp.function_store import FunctionStore
from gnppdsl.nlp.lowering import SlotSignature, lift_constants
from gnppdsl.solve.compiled import load_and_compile

LAB1 = Path(__file__).resolve().parents[2] / "examples" / "lab" / "lab1.pntc"
PLAN = "pick(b2, left_arm, table); stack(b2, left_arm, b1)"


@pytest.fixture(scope="module")
def lab():
    c = load_and_compile(str(LAB1))
    factors = c.factory.factors(plan_states(c.task, parse_plan(c.task, PLAN)))
    # one factor per template, those with distances and kinematics first
    seen, picked = set(), []
    for f in sorted(factors, key=lambda f: ("sdist" not in str(f.body), f.template)):
        if f.template not in seen:
            seen.add(f.template)
            picked.append(f)
    return c, picked[:8]


def _inputs(F: ca.Function, rng) -> list:
    return [rng.uniform(-0.5, 0.5, F.size1_in(i)) for i in range(F.n_in())]


def _same(fa: ca.Function, fb: ca.Function, args: list) -> None:
    assert fa.sparsity_out(0) == fb.sparsity_out(0)
    np.testing.assert_allclose(np.array(fa(*args)), np.array(fb(*args)), rtol=1e-12, atol=1e-12)


def test_a_stored_body_evaluates_equal_to_a_fresh_one(lab, tmp_path):
    c, factors = lab
    assert any("sdist" in str(f.body) for f in factors) and any("fk" in str(f.body) for f in factors)
    fresh = BodyCompiler(c.geometry, store=None)
    writer = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    for f in factors:
        writer.compile(f)
    assert writer.store.written == writer.compiled > 0 and writer.loaded == 0
    reader = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    rng = np.random.default_rng(0)
    with_stops = 0
    for f in factors:
        a, pa = fresh.compile(f)
        b, pb = reader.compile(f)
        np.testing.assert_array_equal(pa, pb)
        assert (a.kinds, a.n_params, a.symbolic, a.primitives) == (b.kinds, b.n_params, b.symbolic, b.primitives)
        assert a.groups == b.groups
        args = _inputs(a.function, rng)
        _same(a.function, b.function, args)
        assert (a.open_function is None) == (b.open_function is None)
        if a.open_function is not None:
            with_stops += 1
            _same(a.evaluate, b.evaluate, args)
            _same(a.stops, b.stops, args)
            _same(a.open_function, b.open_function, _inputs(a.open_function, rng))
        _same(fresh.jacobian(a), reader.jacobian(b), args)
        lam = rng.uniform(-1, 1, a.n_rows)
        _same(fresh.hessian(a), reader.hessian(b), [*args, lam])
    assert with_stops > 0
    assert reader.loaded == reader.compiled == writer.compiled
    assert reader.store.hits == reader.compiled


def test_the_key_changes_with_the_template_body_slots_model_and_code(lab, tmp_path, monkeypatch):
    c, factors = lab
    store = FunctionStore(tmp_path)
    f = next(f for f in factors if "fk" in str(f.body))
    body, params = lift_constants(f.body)
    sigs = tuple(SlotSignature.of(v) for v in f.variables)
    key = store.key(c.geometry, f.template, body, sigs, len(params), True)
    assert key is not None and key == store.key(c.geometry, f.template, body, sigs, len(params), True)
    other = next(g for g in factors if g.template != f.template)
    assert store.key(c.geometry, f.template + "_x", body, sigs, len(params), True) != key
    assert store.key(c.geometry, f.template, body[:-1], sigs, len(params), True) != key
    assert store.key(c.geometry, f.template, lift_constants(other.body)[0], sigs, len(params), True) != key
    wider = tuple(SlotSignature(s.dim, s.waypoints + 1) for s in sigs)
    assert store.key(c.geometry, f.template, body, wider, len(params), True) != key
    assert store.key(c.geometry, f.template, body, sigs, len(params), False) != key
    # another kinematic model of the same robot name (a joint moved by 1 cm)
    name = next(iter(c.geometry.models))
    rm = c.geometry.models[name]
    import pinocchio as pin
    moved = pin.Model(rm.model)
    moved.jointPlacements[1] = pin.SE3(moved.jointPlacements[1].rotation,
                                       moved.jointPlacements[1].translation + np.array([0.01, 0, 0]))
    geo2 = GeometryContext(c.geometry.scene, {**c.geometry.models, name: dataclasses.replace(rm, model=moved)})
    assert FunctionStore(tmp_path).key(geo2, f.template, body, sigs, len(params), True) != key
    # another code version
    monkeypatch.setattr(function_store, "_CODE_VERSION", "another version")
    assert FunctionStore(tmp_path).key(c.geometry, f.template, body, sigs, len(params), True) != key


def test_a_corrupt_file_is_a_miss_and_the_body_is_built_again(lab, tmp_path):
    c, factors = lab
    writer = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    f = factors[0]
    writer.compile(f)
    files = list(tmp_path.rglob("*.pkl"))
    assert len(files) == 1
    files[0].write_bytes(b"not a pickle")
    reader = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    b, _ = reader.compile(f)
    assert reader.loaded == 0 and reader.store.misses == 1 and reader.store.written == 1
    a, _ = BodyCompiler(c.geometry, store=None).compile(f)
    args = _inputs(a.function, np.random.default_rng(1))
    _same(a.function, b.function, args)


def test_the_store_is_off_with_gnpp_function_cache_0(monkeypatch, tmp_path):
    monkeypatch.setenv("GNPP_FUNCTION_CACHE", "0")
    assert FunctionStore.default() is None and BodyCompiler(None).store is None
    monkeypatch.setenv("GNPP_FUNCTION_CACHE", str(tmp_path))
    assert FunctionStore.default().directory == tmp_path


def test_every_object_name_of_a_body_is_found_for_its_key():
    from gnppdsl.ir.expr import Call, Obj, Str
    body = (Call("fk", (Obj("left_arm"), Str("x"))), Obj("b1"), Obj("o'k"), Obj('a"b\'c'))
    assert function_store._names(repr(body)) == {"left_arm", "b1", "o'k", 'a"b\'c'}
    # a text whose objects cannot all be read is not keyed (nothing stored)
    assert function_store._names(repr(body) + " Obj(") is None


def test_stores_of_other_code_versions_unused_for_a_week_are_removed(tmp_path):
    import os
    import time
    store = FunctionStore(tmp_path)
    old, recent, other = tmp_path / ("a" * 16), tmp_path / ("b" * 16), tmp_path / "not-a-version"
    for d in (old, recent, other):
        (d / "00").mkdir(parents=True)
    week = time.time() - 8 * 86400
    os.utime(old, (week, week))
    os.utime(other, (week, week))
    assert store.save("ff" + "0" * 62, {"function": ""})        # the first write prunes
    assert not old.exists() and recent.exists() and other.exists()
    mine = tmp_path / function_store.code_version()[:16]
    assert (mine / "ff").is_dir()
