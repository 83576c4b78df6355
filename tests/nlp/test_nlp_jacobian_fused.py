"""Without compiled kernels, a distance template's constraint Jacobian is one SX Function whose
stop-gradient values (the native distance queries) read the kinematic chains of the
Jacobian's own graph (`body_compiler._closed(fuse=True)`, `_open_rows(shared=True)`), instead
of an MX wrapper whose stop Function ran the chains a second time. The same function: on the
Lab's Panda distance templates (keyframe bodies and the per-waypoint representatives of path
bodies), at random points, entry by entry and in sparsity, equal to the wrapper form; and
shorter (fewer SX instructions per call)."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np

from gnppdsl.nlp.body_compiler import BodyCompiler, _closed, _open_rows, _symbols, sx_jacobian
from gnppdsl.nlp.geometry_protocol import DISTANCE_PRIMITIVES

ROOT = Path(__file__).resolve().parents[2]


def _wrapper_jacobian(cb) -> ca.Function:
    """The Jacobian as `direct_jacobian` built it before: the open Jacobian and the stop values
    as two SX Functions joined by an MX wrapper."""
    slots, p = _symbols(cb)
    out, O, Ov = _open_rows(cb, slots, p)
    return _closed("wrapped_jac", [*slots, p], O, Ov, sx_jacobian(out, ca.vertcat(*slots), [p, O]))


def _lab():
    from gnppdsl.logic.planner import IncrementalPlanner
    from gnppdsl.solve.compiled import load_and_compile

    c = load_and_compile(str(ROOT / "examples" / "lab" / "lab1.pntc"))
    res = IncrementalPlanner(c.task).next_plan(max_horizon=8)
    assert res.found
    return c, res.plan.states


def test_distance_jacobians_are_one_sx_graph_equal_to_the_wrapper_and_shorter():
    c, states = _lab()
    bc = BodyCompiler(c.geometry)          # no kernels: casadi's virtual machine
    bodies = {}
    for f in c.factory.factors(states):
        cb, params = bc.compile(f)
        if DISTANCE_PRIMITIVES & cb.primitives and "fk" in cb.primitives \
                and not any(v.waypoints for v in f.variables):
            bodies.setdefault(id(cb), (cb, params))
    assert len(bodies) >= 3
    rng = np.random.default_rng(0)
    fused_total = wrapped_total = 0
    for cb, params in bodies.values():
        jf, ref = bc.jacobian(cb), _wrapper_jacobian(cb)
        assert jf.is_a("SXFunction"), cb.name
        assert jf.sparsity_out(0) == ref.sparsity_out(0), cb.name
        fused_total += jf.n_instructions()
        wrapped_total += ref.expand().n_instructions()
        for _ in range(3):
            args = [rng.normal(0.0, 0.5, d) for d in cb.slot_dims] + [params]
            a, b = np.asarray(jf(*args)), np.asarray(ref(*args))
            assert np.allclose(a, b, rtol=1e-12, atol=1e-12), (cb.name, np.max(np.abs(a - b)))
    # the chains once (lab1's distance templates: 98338 -> 89603 instructions, and no MX
    # wrapper around two Functions)
    assert fused_total < 0.95 * wrapped_total, (fused_total, wrapped_total)


def test_path_body_jacobian_from_fused_representatives_equals_the_direct_one():
    c, states = _lab()
    bc = BodyCompiler(c.geometry)
    body = None
    for f in c.factory.factors(states):
        cb, params = bc.compile(f)
        if DISTANCE_PRIMITIVES & cb.primitives and any(v.waypoints for v in f.variables) \
                and any(len(g.members) > 1 for g in cb.groups):
            body = (cb, params)
            break
    assert body is not None
    cb, params = body
    jf = bc.jacobian(cb)                   # grouped: one fused representative per row group
    reps = [fn for (key, hess), fn in bc._reps.items() if not hess and fn is not None]
    assert reps and all(fn.is_a("SXFunction") for fn in reps)
    ref = _wrapper_jacobian(cb)
    assert jf.sparsity_out(0) == ref.sparsity_out(0)
    rng = np.random.default_rng(1)
    for _ in range(2):
        args = [rng.normal(0.0, 0.5, d) for d in cb.slot_dims] + [params]
        a, b = np.asarray(jf(*args)), np.asarray(ref(*args))
        assert np.allclose(a, b, rtol=1e-10, atol=1e-10), np.max(np.abs(a - b))
