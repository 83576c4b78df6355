"""`body_compiler.sx_jacobian`: each template's constraint Jacobian by reverse AD when it has at
most as many rows as inputs, else by the shorter of forward and reverse AD, instead of casadi's
own choice (`ca.jacobian`, which picks forward mode for most Panda bodies although reverse mode
is 1.4-2x shorter there). The Jacobians must be the same functions: on the Lab's Panda
templates, at random points, entry by entry and in sparsity, equal to `ca.jacobian`'s, and
shorter in total."""
from __future__ import annotations

from pathlib import Path

import casadi as ca
import numpy as np

from gnppdsl.nlp.body_compiler import BodyCompiler, _closed, _open_rows, _symbols, sx_jacobian

ROOT = Path(__file__).resolve().parents[2]


def _reference_jacobian(cb) -> ca.Function:
    """The body's Jacobian as `direct_jacobian` built it before: `ca.jacobian` of the whole body."""
    slots, p = _symbols(cb)
    out, O, Ov = _open_rows(cb, slots, p)
    return _closed("ref_jac", [*slots, p], O, Ov, ca.jacobian(out, ca.vertcat(*slots)))


def _instructions(f: ca.Function) -> int:
    return f.expand().n_instructions() if f.is_a("MXFunction") else f.n_instructions()


def _lab_bodies():
    from gnppdsl.logic.planner import IncrementalPlanner
    from gnppdsl.solve.compiled import load_and_compile

    c = load_and_compile(str(ROOT / "examples" / "lab" / "lab1.pntc"))
    res = IncrementalPlanner(c.task).next_plan(max_horizon=8)
    assert res.found
    bc = BodyCompiler(c.geometry)
    bodies = {}
    for f in c.factory.factors(res.plan.states):
        cb, params = bc.compile(f)
        if "fk" in cb.primitives and not any(v.waypoints for v in f.variables):
            bodies.setdefault(id(cb), (cb, params))
    return bc, list(bodies.values())


def test_lab_panda_jacobians_equal_casadis_and_are_shorter():
    bc, bodies = _lab_bodies()
    assert len(bodies) >= 4
    rng = np.random.default_rng(0)
    ours_total = ref_total = 0
    for cb, params in bodies:
        jf, ref = bc.jacobian(cb), _reference_jacobian(cb)
        assert jf.sparsity_out(0) == ref.sparsity_out(0), cb.function.name()
        ours_total += _instructions(jf)
        ref_total += _instructions(ref)
        F = cb.function
        for _ in range(3):
            args = [rng.normal(0.0, 0.5, F.size1_in(j)) for j in range(F.n_in() - 1)] + [params]
            a, b = np.asarray(jf(*args)), np.asarray(ref(*args))
            assert np.allclose(a, b, rtol=1e-10, atol=1e-10), (cb.function.name(), np.max(np.abs(a - b)))
    # reverse mode where it is shorter: the Panda bodies of one configuration
    assert ours_total < 0.85 * ref_total, (ours_total, ref_total)


def test_sx_jacobian_takes_the_shorter_mode_of_the_same_function():
    # a chain of 7 rotations (the shape of forward kinematics) read by 6 rows
    q = ca.SX.sym("q", 7)
    p = ca.SX.sym("p", 2)
    R = ca.SX.eye(3)
    for i in range(7):
        c, s = ca.cos(q[i] + p[0]), ca.sin(q[i])
        R = ca.mtimes(R, ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1)) if i % 2
                      else ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c, -s), ca.horzcat(0, s, c)))
    out = ca.vertcat(R[:, 0] * p[1], R[:, 2])
    J = sx_jacobian(out, q, [p])
    fn = ca.Function("j", [q, p], [J])
    modes = []
    for w in (0.0, 1.0):
        F = ca.Function("h", [q, p], [out], {"ad_weight": w, "ad_weight_sp": w})
        modes.append(F.factory("J", F.name_in(), ["jac:o0:i0"]).n_instructions())
    assert fn.n_instructions() <= min(modes)
    ref = ca.Function("r", [q, p], [ca.jacobian(out, q)])
    rng = np.random.default_rng(1)
    for _ in range(5):
        x, pp = rng.normal(size=7), rng.normal(size=2)
        assert np.allclose(np.asarray(fn(x, pp)), np.asarray(ref(x, pp)), rtol=1e-12, atol=1e-12)
