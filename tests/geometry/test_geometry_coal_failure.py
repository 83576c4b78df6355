"""coal's failed signed-distance query does not reach the NLP as NaN.

Measured (field5 seed 0 of 709ab9a, "solver fault: avoid(station_n, o3) evaluates to NaN"): on
two aligned boxes touching face to face within 1e-12, coal's EPA gave up inside the solve's
process and returned the distance -DBL_MAX (a finite number, so every `isfinite` check passed)
with a NaN normal and NaN witness points; the contact model then carried NaN into the rows, the
Jacobian and the verdict. The same query in a fresh process answers (-1.07e-12), so the failure
is injected here as coal reported it: the plain query fails, the retries
(`distance.robust_query`: the shapes swapped, then Nesterov's GJK) run on coal for real.
"""
from __future__ import annotations

import math
import sys

import casadi as ca
import numpy as np
import pytest

import coal
from gnppdsl.geometry.distance import ConvexBody, WitnessCallback, signed_distance, witness
from gnppdsl.geometry.features import model_expression

# station_n (a table top) and o3 (an item standing on it) where the solve stopped
X = np.array([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, -1.95, 0.4, 0.25,
              1.0, -1.1630529872515635e-11, 1.0867973188059735e-11, 1.1630529872523257e-11, 1.0,
              -7.013278845925112e-13, -1.086797318805158e-11, 7.013278847189115e-13, 1.0,
              -1.950000000009951, 0.39999999999894875, 0.5500000000039269])
REAL = coal.distance


def bodies():
    return (ConvexBody("station_n", [coal.Box(0.5, 0.45, 0.5)], [np.eye(4)]),
            ConvexBody("o3", [coal.Box(0.05, 0.05, 0.1)], [np.eye(4)]))


def poses(x):
    return x[0:9].reshape(3, 3, order="F"), x[9:12], x[12:21].reshape(3, 3, order="F"), x[21:24]


def true_distance(x) -> float:
    a, b = bodies()
    RA, pA, RB, pB = poses(x)
    req = coal.DistanceRequest()
    req.enable_signed_distance, req.gjk_tolerance, req.epa_tolerance = True, 1e-9, 1e-9
    return REAL(a.shapes[0], coal.Transform3s(RA, pA), b.shapes[0], coal.Transform3s(RB, pB), req,
                coal.DistanceResult())


def failing(monkeypatch, k: int | None):
    """coal.distance whose first k plain queries (None: every query) fail as measured."""
    left = [math.inf if k is None else k]

    def distance(s1, T1, s2, T2, req, res):
        d = REAL(s1, T1, s2, T2, req, res)
        if left[0] > 0:
            left[0] -= 1
            res.normal = np.full(3, np.nan)
            return -sys.float_info.max
        return d
    monkeypatch.setattr(coal, "distance", distance)


def value_and_gradient(o, x):
    """The contact model's value at x and its gradient in B's position (o held fixed)."""
    RA, pA, RB, pB = poses(x)
    p = ca.SX.sym("p", 3)
    d = model_expression(ca.DM(list(o)), ca.DM(RA), ca.DM(pA), ca.DM(RB), p)
    f = ca.Function("f", [p], [d, ca.gradient(d, p)])
    v, g = f(pB)
    return float(v), np.asarray(g).ravel()


def finite_difference_gradient(x, h=1e-6):
    g = np.zeros(3)
    for i in range(3):
        xp, xm = x.copy(), x.copy()
        xp[21 + i] += h
        xm[21 + i] -= h
        g[i] = (true_distance(xp) - true_distance(xm)) / (2 * h)
    return g


def test_the_configuration_touches():
    assert abs(true_distance(X)) < 1e-9
    np.testing.assert_allclose(finite_difference_gradient(X), [0.0, 0.0, 1.0], atol=1e-6)


@pytest.mark.parametrize("general", [False, True])
def test_callback_recovers_from_a_failed_query(monkeypatch, general):
    a, b = bodies()
    cb = WitnessCallback("f", a, b)
    failing(monkeypatch, 1)
    o = cb._model_general(X) if general else cb._single_list(X)
    assert o is not None and np.all(np.isfinite(o))
    v, g = value_and_gradient(o, X)
    assert abs(v - true_distance(X)) <= 1e-9
    np.testing.assert_allclose(g, finite_difference_gradient(X), atol=1e-4)


def test_witness_and_signed_distance_recover(monkeypatch):
    a, b = bodies()
    RA, pA, RB, pB = poses(X)
    failing(monkeypatch, 1)
    d, n, wa, wb = witness(a, RA, pA, b, RB, pB)
    assert abs(d - true_distance(X)) <= 1e-9
    assert np.all(np.isfinite(wa)) and np.all(np.isfinite(wb))
    np.testing.assert_allclose(n / np.linalg.norm(n), [0.0, 0.0, 1.0], atol=1e-4)
    failing(monkeypatch, 1)
    assert abs(signed_distance(a, RA, pA, b, RB, pB) - true_distance(X)) <= 1e-9


def test_every_query_failing_still_gives_finite_rows(monkeypatch):
    """coal failing every way: the degenerate-query fallback (touching, centre direction)."""
    a, b = bodies()
    cb = WitnessCallback("f", a, b)
    RA, pA, RB, pB = poses(X)
    failing(monkeypatch, None)
    o = cb._model(X)
    assert np.all(np.isfinite(o))
    v, g = value_and_gradient(o, X)
    assert abs(v) <= 1e-9 and np.all(np.isfinite(g))
    assert signed_distance(a, RA, pA, b, RB, pB) == 0.0


def test_native_twin_recovers_like_the_callback(monkeypatch, native_library):
    lib = native_library
    a, b = bodies()
    fn = lib.function("station_o3_failure", a, b, False)
    lib.forget()
    lib.fail_next(1)
    o = np.asarray(fn(X)).ravel()
    lib.fail_next(0)
    assert np.all(np.isfinite(o))
    failing(monkeypatch, 1)
    np.testing.assert_allclose(o, WitnessCallback("f", a, b)._single_list(X), rtol=0, atol=1e-12)
    v, g = value_and_gradient(o, X)
    assert abs(v - true_distance(X)) <= 1e-9
    np.testing.assert_allclose(g, finite_difference_gradient(X), atol=1e-4)
