"""Signed distance between convex bodies through coal, inside casadi with exact gradients.

How the derivative is exact without differentiating coal: coal returns, for the current poses, the
normal n and the witness points wA, wB (nearest points when separated, deepest points when
penetrating) with d = n . (wB - wA). By the envelope theorem the gradient of d with respect to
both rigid poses equals the gradient of

    d_lin(poses) = n . ((RB wB_loc + pB) - (RA wA_loc + pA))

with n, wA_loc, wB_loc (witness points in the bodies' own frames) held fixed. So a
`casadi.Callback` returns (n, wA_loc, wB_loc) and declares a structurally zero Jacobian (a
"stop gradient"), and the distance is the casadi expression d_lin around it: casadi then
differentiates the pose part exactly (rotation through quaternions or forward kinematics
included) and even supplies the rigid-motion part of the Hessian.

A body is a list of convex shapes with fixed placements in the body frame (a robot link has
several; a scene object one); its distance to another body is the minimum over shape pairs.
"""
from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np


@dataclass
class ConvexBody:
    """A rigid set of convex coal shapes. `placements[i]` is a 4x4 of shape i in the body frame."""

    name: str
    shapes: list
    placements: list[np.ndarray]


def _transform(R: np.ndarray, p: np.ndarray):
    import coal
    return coal.Transform3s(np.ascontiguousarray(R, dtype=float), np.ascontiguousarray(p, dtype=float))


def _request():
    import coal
    req = coal.DistanceRequest()
    req.enable_signed_distance = True
    req.gjk_tolerance = 1e-9
    req.epa_tolerance = 1e-9
    return req


_REQ = None


def witness(body_a: ConvexBody, RA, pA, body_b: ConvexBody, RB, pB):
    """Minimum signed distance between two bodies at world poses, with the world normal
    (gradient w.r.t. B's translation) and the two witness points in world coordinates."""
    import coal
    global _REQ
    if _REQ is None:
        _REQ = _request()
    best = None
    for sa, Ma in zip(body_a.shapes, body_a.placements):
        Ta = _transform(RA @ Ma[:3, :3], RA @ Ma[:3, 3] + pA)
        for sb, Mb in zip(body_b.shapes, body_b.placements):
            Tb = _transform(RB @ Mb[:3, :3], RB @ Mb[:3, 3] + pB)
            res = coal.DistanceResult()
            d = coal.distance(sa, Ta, sb, Tb, _REQ, res)
            if best is None or d < best[0]:
                best = (d, np.array(res.normal), np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2()))
    if best is None:
        raise ValueError(f"body {body_a.name} or {body_b.name} has no collision shape")
    return best


class WitnessCallback(ca.Callback):
    """(RA, pA, RB, pB) as one 24-vector [vec(RA) column-major, pA, vec(RB), pB] ->
    [n (world), wA in A's frame, wB in B's frame]; Jacobian structurally zero (stop gradient)."""

    def __init__(self, name: str, body_a: ConvexBody, body_b: ConvexBody):
        ca.Callback.__init__(self)
        self.body_a, self.body_b = body_a, body_b
        self.calls = 0
        self.construct(name, {})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(24, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(9, 1)

    # Buffer evaluation: casadi hands over raw memory, skipping DM conversions (about 2x faster).
    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        x = np.frombuffer(arg[0], dtype=np.float64, count=24)
        out = np.frombuffer(res[0], dtype=np.float64, count=9)
        out[:] = self._witness_vector(x)
        return 0

    def eval(self, arg):
        return [ca.DM(self._witness_vector(np.array(arg[0], dtype=float).ravel()))]

    def _witness_vector(self, x: np.ndarray) -> np.ndarray:
        RA = x[0:9].reshape(3, 3, order="F")
        pA = x[9:12]
        RB = x[12:21].reshape(3, 3, order="F")
        pB = x[21:24]
        self.calls += 1
        d, n, wa, wb = witness(self.body_a, RA, pA, self.body_b, RB, pB)
        nn = np.linalg.norm(n)
        if not np.isfinite(d) or nn < 1e-12:
            # Touching exactly (or a degenerate query): fall back to the centre direction.
            c = pB - pA
            n = c / np.linalg.norm(c) if np.linalg.norm(c) > 1e-12 else np.array([0.0, 0.0, 1.0])
            wa = wb = (pA + pB) / 2
        else:
            n = n / nn
        return np.r_[n, RA.T @ (wa - pA), RB.T @ (wb - pB)]

    def has_jacobian(self):
        return True

    def get_jacobian(self, name, inames, onames, opts):
        x = ca.SX.sym("x", 24)
        o = ca.SX.sym("o", 9)
        return ca.Function(name, [x, o], [ca.SX.zeros(9, 24)], inames, onames, opts)

    # Forward and reverse modes say the same thing (zero sensitivities), so that casadi never
    # builds them from the Jacobian with 0 * NaN products in SX graphs.
    def has_forward(self, nfwd):
        return True

    def get_forward(self, nfwd, name, inames, onames, opts):
        x, o, s = ca.SX.sym("x", 24), ca.SX.sym("o", 9), ca.SX.sym("s", 24, nfwd)
        return ca.Function(name, [x, o, s], [ca.SX.zeros(9, nfwd)], inames, onames, opts)

    def has_reverse(self, nadj):
        return True

    def get_reverse(self, nadj, name, inames, onames, opts):
        x, o, s = ca.SX.sym("x", 24), ca.SX.sym("o", 9), ca.SX.sym("s", 9, nadj)
        return ca.Function(name, [x, o, s], [ca.SX.zeros(24, nadj)], inames, onames, opts)


def signed_distance_expr(cb: WitnessCallback, RA, pA, RB, pB):
    """d_lin: the signed distance as a casadi expression with exact first derivatives."""
    x = ca.vertcat(ca.reshape(RA, 9, 1), pA, ca.reshape(RB, 9, 1), pB)
    out = cb(x)
    n, wa, wb = out[0:3], out[3:6], out[6:9]
    return ca.dot(n, (ca.mtimes(RB, wb) + pB) - (ca.mtimes(RA, wa) + pA))


def se2_to_rp(v):
    """SE2 [x, y, theta] -> (R, p) at z = 0 (casadi)."""
    c, s = ca.cos(v[2]), ca.sin(v[2])
    R = ca.vertcat(ca.horzcat(c, -s, 0), ca.horzcat(s, c, 0), ca.horzcat(0, 0, 1))
    return R, ca.vertcat(v[0], v[1], 0)


def se2_to_matrix(v) -> np.ndarray:
    v = np.asarray(v, dtype=float).ravel()
    c, s = np.cos(v[2]), np.sin(v[2])
    T = np.eye(4)
    T[:2, :2] = [[c, -s], [s, c]]
    T[:2, 3] = v[:2]
    return T
