"""Template Functions persisted across processes (`gnppdsl.nlp.function_store`): a body loaded
from the store must evaluate equal to the same body built fresh (values, distance queries,
open form, Jacobian and Hessian with their sparsity), on Lab bodies with Panda kinematics and
coal distances; the key must change with the template, its body, the slots, the names, the
robot model and the code version; a corrupt file is a miss, never a wrong Function."""
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
from gnppdsl.nlp.lowering import SlotSignature, structure_key
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


def _structure(compiler, body):
    names = set()
    skey, params = structure_key(body, lambda n: (names.add(n), compiler._structure_of(n))[1])
    return skey, names, len(params)


def test_the_key_changes_with_the_template_body_slots_names_model_and_code(lab, tmp_path, monkeypatch):
    c, factors = lab
    store = FunctionStore(tmp_path)
    bc = BodyCompiler(c.geometry, store=None)
    f = next(f for f in factors if "fk" in str(f.body))
    skey, names, n = _structure(bc, f.body)
    sigs = tuple(SlotSignature.of(v) for v in f.variables)
    assert names and all(isinstance(x, str) for x in names)
    key = store.key(c.geometry, f.template, skey, names, sigs, n, True)
    assert key is not None and key == store.key(c.geometry, f.template, skey, set(names), sigs, n, True)
    other = next(g for g in factors if g.template != f.template)
    assert store.key(c.geometry, f.template + "_x", skey, names, sigs, n, True) != key
    assert store.key(c.geometry, f.template, skey[:-1], names, sigs, n, True) != key
    assert store.key(c.geometry, f.template, _structure(bc, other.body)[0], names, sigs, n, True) != key
    wider = tuple(SlotSignature(s.dim, s.waypoints + 1) for s in sigs)
    assert store.key(c.geometry, f.template, skey, names, wider, n, True) != key
    assert store.key(c.geometry, f.template, skey, names, sigs, n, False) != key
    extra = next(o for o in c.geometry.scene.objects if o not in names)
    assert store.key(c.geometry, f.template, skey, names | {extra}, sigs, n, True) != key
    # another kinematic model of the same robot name (a joint moved by 1 cm)
    name = next(iter(c.geometry.models))
    assert name in names
    rm = c.geometry.models[name]
    import pinocchio as pin
    moved = pin.Model(rm.model)
    moved.jointPlacements[1] = pin.SE3(moved.jointPlacements[1].rotation,
                                       moved.jointPlacements[1].translation + np.array([0.01, 0, 0]))
    geo2 = GeometryContext(c.geometry.scene, {**c.geometry.models, name: dataclasses.replace(rm, model=moved)})
    assert FunctionStore(tmp_path).key(geo2, f.template, skey, names, sigs, n, True) != key
    # another code version
    monkeypatch.setattr(function_store, "_CODE_VERSION", "another version")
    assert FunctionStore(tmp_path).key(c.geometry, f.template, skey, names, sigs, n, True) != key


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


def test_a_body_stored_for_other_objects_of_the_same_shape_is_renamed_at_load(lab, tmp_path):
    """b1 and b2 are equal boxes: the bodies of `stack(b1 onto b2)` are found under the keys
    of those stored for `stack(b2 onto b1)` and come back with the names swapped (distance
    queries, row groups), evaluating as the fresh bodies do."""
    from gnppdsl.ir.expr import Obj

    c, _ = lab
    assert c.geometry.structure_key("b1") == c.geometry.structure_key("b2")

    def plan_factors(plan):
        return c.factory.factors(plan_states(c.task, parse_plan(c.task, plan)))

    writer = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    for f in plan_factors(PLAN):                                   # b2 onto b1
        writer.compile(f)
    swapped = plan_factors("pick(b1, left_arm, table); stack(b1, left_arm, b2)")
    reader = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    fresh = BodyCompiler(c.geometry, store=None)
    rng = np.random.default_rng(2)
    renamed = 0
    for f in swapped:
        b, pb = reader.compile(f)
        a, pa = fresh.compile(f)
        np.testing.assert_array_equal(pa, pb)
        assert a.groups == b.groups                 # the fresh body's names, not the stored ones
        args = _inputs(a.function, rng)
        _same(a.function, b.function, args)
        if a.open_function is not None:
            _same(a.evaluate, b.evaluate, args)
        names = {x.name for g in b.groups for x in _objs(g.key)}
        renamed += "b1" in names and "b2" in names
    assert reader.loaded > 0 and renamed > 0


def _objs(e):
    from gnppdsl.ir.expr import Obj
    if isinstance(e, Obj):
        yield e
    elif isinstance(e, (tuple, list)):
        for x in e:
            yield from _objs(x)
    elif dataclasses.is_dataclass(e) and not isinstance(e, type):
        for f in dataclasses.fields(e):
            yield from _objs(getattr(e, f.name))


def test_a_store_directory_that_is_not_private_is_never_read_or_written(lab, tmp_path):
    """Loading unpickles, so a directory another user could write to is not used: a symbolic
    link to a stored directory reads nothing, and a shared (0777) directory of ours is
    tightened to 0700 before use."""
    import os
    import stat
    c, factors = lab
    f = factors[0]
    real = tmp_path / "real"
    BodyCompiler(c.geometry, store=FunctionStore(real)).compile(f)
    assert len(list(real.rglob("*.pkl"))) == 1
    link = tmp_path / "link"
    link.symlink_to(real, target_is_directory=True)
    reader = BodyCompiler(c.geometry, store=FunctionStore(link))
    reader.compile(f)
    assert reader.loaded == 0 and reader.store.misses == 1 and reader.store.written == 0
    assert not FunctionStore(link).save("ab" + "0" * 62, {"function": ""})
    shared = tmp_path / "shared"
    shared.mkdir()
    os.chmod(shared, 0o777)
    store = FunctionStore(shared)
    assert store.save("ab" + "0" * 62, {"function": ""})
    assert stat.S_IMODE(os.stat(shared).st_mode) == 0o700


def test_the_callback_form_is_built_only_when_read(lab, tmp_path):
    """`CompiledBody.function` (the rows with the differentiable distance callbacks) is built on
    first use: compiling, loading from the store, the per-template derivatives and a keyframe
    solve with ipopt never read it (they use `evaluate`, `open_function` and `stops`), and read
    later it is the same Function as an eager build would give (the test above compares it
    between a stored and a fresh body)."""
    from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
    from gnppdsl.solve.plan_graph import plan_graph

    c, factors = lab
    writer = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    for f in factors:
        writer.compile(f)
    reader = BodyCompiler(c.geometry, store=FunctionStore(tmp_path))
    g = plan_graph(c.factory, plan_states(c.task, parse_plan(c.task, PLAN)))
    modes = g.subgraph(variables=[v for v in g.variables if not v.waypoints], suffix="{modes}")
    solver = FeasibilitySolver(c.geometry, SolverOptions(restarts=0), compiler=reader)
    assert solver.solve(modes, seed=0).feasible
    lazy = 0
    for f in factors:
        for comp in (writer, reader):
            cb, _ = comp.compile(f)
            comp.jacobian(cb)
            comp.hessian(cb)
            if cb.open_function is None:
                assert isinstance(cb.source, ca.Function)
                continue
            lazy += 1
            assert not isinstance(cb.source, ca.Function)        # not built by any of the above
            F = cb.function
            assert cb.source is F and cb.function is F            # built once, then kept
            assert (cb.name, cb.slot_dims) == (F.name(), tuple(F.size1_in(j) for j in range(F.n_in() - 1)))
            args = _inputs(F, np.random.default_rng(2))
            np.testing.assert_allclose(np.array(F(*args)), np.array(cb.evaluate(*args)), rtol=1e-9, atol=1e-9)
    assert lazy > 0
