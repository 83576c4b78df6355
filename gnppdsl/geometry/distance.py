"""Signed distance between convex bodies through coal, inside casadi with exact derivatives.

How the derivatives are exact without differentiating coal: a `casadi.Callback` runs coal at the
current poses and returns a *local model* of the distance, as numbers whose own derivative is
declared zero (a "stop gradient"): the active contact features (face, edge, vertex, sphere
centre) in the bodies' frames (`gnppdsl.geometry.features`). The casadi expression around the
callback evaluates the model at the symbolic poses. The model has coal's value, the gradient of
the envelope theorem (d = n . (wB - wA) with witness points moving rigidly), and for polytopes
and spheres also the exact Hessian; for other curved shapes (cylinders) it falls back to the
world-fixed normal n . (wB - wA), whose Hessian has only the rigid-motion part.

A body is a list of convex shapes with fixed placements in the body frame (a scene object has
one; robot links are merged into one hull); the distance is the minimum over shape pairs.
"""
from __future__ import annotations

import math
from array import array
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from gnppdsl.geometry.features import (N_OUT, feature_list, feature_model, model_expression, placement_floats,
                                       pose_floats)


@dataclass
class ConvexBody:
    """A rigid set of convex coal shapes. `placements[i]` is a 4x4 of shape i in the body frame."""

    name: str
    shapes: list
    placements: list[np.ndarray]
    _spheres: dict = field(default_factory=dict)
    _identity: tuple | None = None

    def identity(self) -> tuple[bool, ...]:
        """Per shape: is its placement the identity (cached; placements are fixed)."""
        if self._identity is None or len(self._identity) != len(self.placements):
            self._identity = tuple(bool(np.array_equal(M, np.eye(4))) for M in self.placements)
        return self._identity

    def bounding_sphere(self, planar: bool = False) -> tuple[np.ndarray, float]:
        """(centre in the body frame, radius) of a sphere containing every shape; `planar`: a
        circle around the xy footprint (centre z = 0), for z-extrusions moving in the plane."""
        if planar not in self._spheres:
            from gnppdsl.geometry.shapes import shape_vertices
            pts = np.vstack([shape_vertices(s) @ M[:3, :3].T + M[:3, 3] for s, M in zip(self.shapes, self.placements)])
            if planar:
                pts = pts.copy()
                pts[:, 2] = 0.0
            c = (pts.min(axis=0) + pts.max(axis=0)) / 2
            # vertices of curved shapes are samples on their surface: pad 2 % for what lies between
            r = 1.02 * float(np.linalg.norm(pts - c, axis=1).max())
            self._spheres[planar] = (c, r)
        return self._spheres[planar]

    def local_box(self) -> tuple[np.ndarray, np.ndarray]:
        """(centre, half extents) in the body frame of an axis-aligned box containing every
        shape: the union of coal's local AABBs (exact for boxes, cylinders and convex hulls,
        unlike vertex samples of curved shapes), each turned by its placement."""
        if "box" not in self._spheres:
            lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
            for s, M in zip(self.shapes, self.placements):
                s.computeLocalAABB()
                a = s.aabb_local
                c0, h0 = (np.asarray(a.min_) + np.asarray(a.max_)) / 2, (np.asarray(a.max_) - np.asarray(a.min_)) / 2
                c, h = M[:3, :3] @ c0 + M[:3, 3], np.abs(M[:3, :3]) @ h0
                lo, hi = np.minimum(lo, c - h), np.maximum(hi, c + h)
            self._spheres["box"] = ((lo + hi) / 2, (hi - lo) / 2)
        return self._spheres["box"]


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
_RETRY = None

# coal reports a failed signed-distance query (EPA giving up on shapes that touch face to face,
# measured on two aligned boxes touching within 1e-12) as the distance -DBL_MAX with a NaN normal
# and NaN witness points; the value is finite, so it passed every isfinite check and reached
# ipopt as NaN rows (field5 seed 0: "solver fault: avoid(station_n, o3)"). Anything this large
# is such a failure: no scene is a light-year across.
_FAILED = 1e300


def _good(d: float, n, w1, w2) -> bool:
    """coal's answer is usable: a finite distance that is not the failure value, a finite
    nonzero normal and finite witness points (NaN fails every comparison, so `>=`)."""
    return (abs(d) < _FAILED and float(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]) >= 1e-24
            and math.isfinite(w1[0] + w1[1] + w1[2] + w2[0] + w2[1] + w2[2]))


def _retry_request():
    import coal
    global _RETRY
    if _RETRY is None:
        _RETRY = _request()
        _RETRY.gjk_variant = coal.GJKVariant.NesterovAcceleration
    return _RETRY


def robust_query(sa, Ta, sb, Tb, first=None):
    """(d, normal, witness on a, witness on b) of coal's signed-distance query of two placed
    shapes, as plain float tuples (normal not normalised), or None when coal fails every way.

    When the plain query fails (`_good`), it is asked again with the shapes swapped (normal
    and witnesses mapped back), then with Nesterov-accelerated GJK: a different path through
    GJK and EPA on the same shapes, which on the failing configurations measured answers where
    the first did not. `first`: the (d, DistanceResult) of a plain query already made."""
    import coal
    global _REQ
    if _REQ is None:
        _REQ = _request()
    if first is None:
        res = coal.DistanceResult()
        first = (coal.distance(sa, Ta, sb, Tb, _REQ, res), res)
    attempts = (first, (sb, Tb, sa, Ta, _REQ), (sa, Ta, sb, Tb, _retry_request()))
    for k, att in enumerate(attempts):
        if k == 0:
            d, res = att
        else:
            res = coal.DistanceResult()
            d = coal.distance(*att[:4], att[4], res)
        n = tuple(res.normal.tolist())
        w1, w2 = tuple(res.getNearestPoint1().tolist()), tuple(res.getNearestPoint2().tolist())
        if k == 1:                                   # swapped: B's normal points from B to A
            n, w1, w2 = (-n[0], -n[1], -n[2]), w2, w1
        if math.isfinite(d) and _good(d, n, w1, w2):
            return float(d), n, w1, w2
    return None


def _place(T, R, p, M, identity: bool) -> None:
    """`_placed` into an existing coal transform T (the single-shape fast path reuses its two)."""
    if identity:
        T.setRotation(R)
        T.setTranslation(p)
    else:
        T.setRotation(R @ M[:3, :3])
        T.setTranslation(R @ M[:3, 3] + p)


def _placed(R, p, M, identity: bool):
    """coal transform of a shape placed at M in a body at (R, p); a scene object's identity
    placement skips the two products (R @ I = R, R @ 0 + p = p up to the sign of zeros)."""
    if identity:
        return _transform(R, p)
    return _transform(R @ M[:3, :3], R @ M[:3, 3] + p)


def witness(body_a: ConvexBody, RA, pA, body_b: ConvexBody, RB, pB, with_shapes: bool = False):
    """Minimum signed distance between two bodies at world poses, with the world normal
    (gradient w.r.t. B's translation) and the two witness points in world coordinates."""
    import coal
    global _REQ
    if _REQ is None:
        _REQ = _request()
    best = None
    Tbs = [_placed(RB, pB, Mb, i) for Mb, i in zip(body_b.placements, body_b.identity())]
    for sa, Ma, ia in zip(body_a.shapes, body_a.placements, body_a.identity()):
        Ta = _placed(RA, pA, Ma, ia)
        for sb, Mb, Tb in zip(body_b.shapes, body_b.placements, Tbs):
            res = coal.DistanceResult()
            d = coal.distance(sa, Ta, sb, Tb, _REQ, res)
            if not (abs(d) < _FAILED) or not _good(d, res.normal, res.getNearestPoint1(), res.getNearestPoint2()):
                q = robust_query(sa, Ta, sb, Tb, (d, res))
                # coal failed every way (it does so on shapes touching): touching, the caller's
                # degenerate-query fallback (NaN normal) takes the centre direction
                d, n, w1, w2 = q if q is not None else (0.0, (math.nan,) * 3, (math.nan,) * 3, (math.nan,) * 3)
                cand = (d, np.array(n), np.array(w1), np.array(w2), (sa, Ma, sb, Mb))
            else:
                cand = (d, np.array(res.normal), np.array(res.getNearestPoint1()), np.array(res.getNearestPoint2()),
                        (sa, Ma, sb, Mb))
            if best is None or cand[0] < best[0]:
                best = cand
    if best is None:
        raise ValueError(f"body {body_a.name} or {body_b.name} has no collision shape")
    return best[:4] if not with_shapes else best


def signed_distance(body_a: ConvexBody, RA, pA, body_b: ConvexBody, RB, pB) -> float:
    """`witness(...)[0]`, the minimum signed distance between two bodies at world poses,
    without building the normal and witness points: what the numeric checker and the
    independent verification read (lab5: 20k queries per solve)."""
    import coal
    global _REQ
    if _REQ is None:
        _REQ = _request()
    best = math.inf
    Tbs = [_placed(RB, pB, Mb, i) for Mb, i in zip(body_b.placements, body_b.identity())]
    for sa, Ma, ia in zip(body_a.shapes, body_a.placements, body_a.identity()):
        Ta = _placed(RA, pA, Ma, ia)
        for sb, Tb in zip(body_b.shapes, Tbs):
            res = coal.DistanceResult()
            d = coal.distance(sa, Ta, sb, Tb, _REQ, res)
            if not (abs(d) < _FAILED):           # coal's failure value (`_FAILED`): ask again
                q = robust_query(sa, Ta, sb, Tb, (d, res))
                d = q[0] if q is not None else 0.0       # failing every way: touching
            best = min(best, d)
    if best == math.inf:
        raise ValueError(f"body {body_a.name} or {body_b.name} has no collision shape")
    return float(best)


def _shape_transform(R: tuple, p: tuple, placement: tuple | None):
    """coal transform of a shape at `placement` ((rotation rows, translation) in floats; None:
    the identity) in a body at (R, p) (`features.pose_floats`): R M_R and R M_p + p in plain floats."""
    import coal
    if placement is not None:
        (m0, m1, m2), t = placement
        p = tuple(r[0] * t[0] + r[1] * t[1] + r[2] * t[2] + q for r, q in zip(R, p))
        R = tuple((r[0] * m0[0] + r[1] * m1[0] + r[2] * m2[0], r[0] * m0[1] + r[1] * m1[1] + r[2] * m2[1],
                   r[0] * m0[2] + r[1] * m1[2] + r[2] * m2[2]) for r in R)
    return coal.Transform3s(np.array(R), np.array(p))


def _single_placement(body: "ConvexBody") -> tuple | None:
    """The one shape's placement of a single-shape body as float rows (None: the identity),
    computed once per body."""
    pl = body._spheres.get("placement")
    if pl is None:
        R, t, identity = placement_floats(body.placements[0])
        pl = body._spheres["placement"] = (None if identity else (R, t),)
    return pl[0]


_PLACED: dict[tuple, tuple] = {}
_PLACED_MAX = 4096


def _placed_at(body: "ConvexBody", pose):
    """The coal transform of a single-shape body's shape at an SE3 pose, remembered for the
    last _PLACED_MAX (body, pose) pairs (by the pose's exact bytes; the body is held, so its id
    stays its own). Why: the checker asks each pose against many bodies (a link at one waypoint
    against every object, a resting object against every link), and building the transform
    is ~2/3 of a query's Python time (lab5_paper, py-spy)."""
    x = np.asarray(pose, dtype=float).ravel()[:7]
    key = (id(body), x.tobytes())
    hit = _PLACED.get(key)
    if hit is not None and hit[0] is body:
        return hit[1]
    T = _shape_transform(*pose_floats(x), _single_placement(body))
    if len(_PLACED) >= _PLACED_MAX:
        _PLACED.clear()
    _PLACED[key] = (body, T)
    return T


def signed_distance_at(body_a: ConvexBody, pose_a, body_b: ConvexBody, pose_b) -> float:
    """`signed_distance` of two bodies at SE3 7-vector poses: the numeric checker's query
    (`GeometryContext.sdist_numeric`). Why its own path: a query of two single-shape bodies
    cost ~30 us in Python around ~4.4 us of coal (lab3_paper's links against blocks: 4x4
    matrices built, sliced and multiplied in numpy, ~26 us for a link's shape placement alone);
    here poses and placements are composed in plain floats and turned into coal transforms
    once. The same coal query; the transforms equal numpy's products to rounding (1e-16)."""
    import coal
    global _REQ
    if len(body_a.shapes) != 1 or len(body_b.shapes) != 1:
        (Ra, pa), (Rb, pb) = pose_floats(pose_a), pose_floats(pose_b)
        return signed_distance(body_a, np.array(Ra), np.array(pa), body_b, np.array(Rb), np.array(pb))
    if _REQ is None:
        _REQ = _request()
    sa, sb = body_a.shapes[0], body_b.shapes[0]
    Ta, Tb = _placed_at(body_a, pose_a), _placed_at(body_b, pose_b)
    res = coal.DistanceResult()
    d = coal.distance(sa, Ta, sb, Tb, _REQ, res)
    if not (abs(d) < _FAILED):               # coal's failure value (`_FAILED`): ask again
        q = robust_query(sa, Ta, sb, Tb, (d, res))
        d = q[0] if q is not None else 0.0   # failing every way: touching
    return float(d)


class WitnessCallback(ca.Callback):
    """(RA, pA, RB, pB) as one 24-vector [vec(RA) column-major, pA, vec(RB), pB] -> the local
    contact model of `gnppdsl.geometry.features` (N_OUT numbers); all sensitivities are zero
    (a "stop gradient"): derivatives come from the model expression around it."""

    def __init__(self, name: str, body_a: ConvexBody, body_b: ConvexBody, features: bool = True,
                 planar: bool = False, far_field: float | None = None):
        ca.Callback.__init__(self)
        self.body_a, self.body_b = body_a, body_b
        self.features, self.planar = features, planar
        # far_field: beyond this bounding-sphere gap, answer with the sphere-sphere distance (a
        # smooth lower bound of the true distance, no coal query). Only sound for constraints
        # `sdist >= m` with m < far_field, which is how the templates use it; off by default.
        self.far_field = far_field
        self.far = 0
        if far_field is not None:
            ca_, ra = body_a.bounding_sphere(planar)
            cb_, rb = body_b.bounding_sphere(planar)
            self._bounds = (ca_.tolist(), ra, cb_.tolist(), rb)
        self.calls = 0
        # one shape on each side (scene objects, merged robot links): `_model_single` queries coal
        # directly with reused transforms and runs the feature model on plain floats
        self._single = None
        if len(body_a.shapes) == 1 and len(body_b.shapes) == 1 and features:
            import coal
            self._single = (body_a.shapes[0], body_a.placements[0], placement_floats(body_a.placements[0]),
                            coal.Transform3s(), body_b.shapes[0], body_b.placements[0],
                            placement_floats(body_b.placements[0]), coal.Transform3s())
        # ipopt evaluates constraints, their Jacobian and the Hessian at the same point: remember
        # recent answers (keyed by the exact input bytes) so coal runs once per point.
        self._memo: dict[bytes, bytes] = {}
        self.hits = 0
        self.construct(name, {})

    def get_n_in(self):
        return 1

    def get_n_out(self):
        return 1

    def get_sparsity_in(self, i):
        return ca.Sparsity.dense(24, 1)

    def get_sparsity_out(self, i):
        return ca.Sparsity.dense(N_OUT, 1)

    # Buffer evaluation: casadi hands over raw memory, skipping DM conversions (about 2x faster).
    # The memo holds the outputs as bytes keyed by the input bytes, so a repeated point (the
    # Jacobian and Hessian at ipopt's current x) costs two byte copies and one dict lookup.
    def has_eval_buffer(self):
        return True

    def eval_buffer(self, arg, res):
        key = arg[0].tobytes()                  # arg[0], res[0]: memoryviews of 24 / N_OUT doubles
        out = self._memo.get(key)
        if out is None:
            out = self._remember(key, self._model(np.frombuffer(key, dtype=np.float64)))
        else:
            self.hits += 1
        res[0][:] = out
        return 0

    def eval(self, arg):
        return [ca.DM(self.model(np.array(arg[0], dtype=float).ravel()))]

    def forget(self) -> None:
        """Empty the memo (see `GeometryContext.forget_evaluations`)."""
        self._memo.clear()

    def model(self, x: np.ndarray) -> np.ndarray:
        """The callback output at x (24 numbers), through the memo."""
        x = np.ascontiguousarray(x, dtype=np.float64)
        key = x.tobytes()
        out = self._memo.get(key)
        if out is None:
            out = self._remember(key, self._model(x))
        else:
            self.hits += 1
        return np.frombuffer(out, dtype=np.float64).copy()

    def _remember(self, key: bytes, out) -> bytes:
        b = array("d", out).tobytes() if isinstance(out, list) else np.asarray(out, dtype=np.float64).tobytes()
        if len(b) != 8 * N_OUT:
            raise ValueError(f"distance model returned {len(b) // 8} numbers, expected {N_OUT}")
        if len(self._memo) >= 4096:
            self._memo.pop(next(iter(self._memo)))    # oldest first (dicts keep insertion order)
        self._memo[key] = b
        return b

    def _model(self, x: np.ndarray):
        """The callback output at x without the memo: a list or an array of N_OUT numbers."""
        if self._single is not None and self.far_field is None:
            out = self._single_list(x)
            if out is not None:
                return out
        return self._model_general(x)

    def _model_single(self, x: np.ndarray) -> np.ndarray | None:
        """`_model_general` for one shape per body: the same coal query and the same arithmetic
        (bitwise equal outputs, `tests/geometry/test_geometry_fastpath.py`) at about half the
        cost; None for a degenerate query (touching exactly), which the general path handles."""
        out = self._single_list(x)
        return None if out is None else np.array(out)

    def _single_list(self, x: np.ndarray) -> list | None:
        """`_model_single` as a list (what the memo stores as bytes, without a numpy array)."""
        import coal
        global _REQ
        if _REQ is None:
            _REQ = _request()
        sa, Ma, pla, Ta, sb, Mb, plb, Tb = self._single
        _place(Ta, x[0:9].reshape(3, 3, order="F"), x[9:12], Ma, pla[2])
        _place(Tb, x[12:21].reshape(3, 3, order="F"), x[21:24], Mb, plb[2])
        res = coal.DistanceResult()
        d = coal.distance(sa, Ta, sb, Tb, _REQ, res)
        n = res.normal
        nn = math.sqrt(n.dot(n))                # == np.linalg.norm(n) (the same dot product)
        w1, w2 = res.getNearestPoint1().tolist(), res.getNearestPoint2().tolist()
        n0, n1, n2 = n.tolist()
        # (`not >=`: a NaN normal fails it too; coal's failure value, `_FAILED`, is finite)
        if not (abs(d) < _FAILED and nn >= 1e-12) or not math.isfinite(sum(w1) + sum(w2)):
            q = robust_query(sa, Ta, sb, Tb, (d, res))
            if q is None:
                return None                     # the general path's degenerate-query fallback
            d, (n0, n1, n2), w1, w2 = q
            nn = math.sqrt(n0 * n0 + n1 * n1 + n2 * n2)
            if not nn >= 1e-12:
                return None
        self.calls += 1
        xl = x.tolist()
        RA_ = [xl[0:9:3], xl[1:9:3], xl[2:9:3]]     # rows of the column-major 3x3
        RB_ = [xl[12:21:3], xl[13:21:3], xl[14:21:3]]
        return feature_list(sa, pla, sb, plb, RA_, xl[9:12], RB_, xl[21:24], d, (n0 / nn, n1 / nn, n2 / nn),
                            w1, w2, self.planar)

    def _model_general(self, x: np.ndarray) -> np.ndarray:
        RA = x[0:9].reshape(3, 3, order="F")
        pA = x[9:12]
        RB = x[12:21].reshape(3, 3, order="F")
        pB = x[21:24]
        if self.far_field is not None:
            out = self._far_model(RA, pA, RB, pB)
            if out is not None:
                return out
        self.calls += 1
        d, n, wa, wb, (sa, Ma, sb, Mb) = witness(self.body_a, RA, pA, self.body_b, RB, pB, with_shapes=True)
        nn = np.linalg.norm(n)
        if not np.isfinite(d) or not nn >= 1e-12 or not np.all(np.isfinite(wa)) or not np.all(np.isfinite(wb)):
            # Touching exactly (or a degenerate query): fall back to the centre direction.
            c = pB - pA
            n = c / np.linalg.norm(c) if np.linalg.norm(c) > 1e-12 else np.array([0.0, 0.0, 1.0])
            wa = wb = (pA + pB) / 2
            d = 0.0
        else:
            n = n / nn
        if self.features:
            return feature_model(sa, Ma, sb, Mb, RA, pA, RB, pB, d, n, wa, wb, self.planar)
        out = np.zeros(N_OUT)
        out[3], out[4] = 1.0, 1.0
        out[5:8], out[8:11] = RA.T @ (wa - pA), RB.T @ (wb - pB)
        out[11:14], out[14:17] = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
        out[21:24] = n
        return out

    def _far_model(self, RA, pA, RB, pB) -> np.ndarray | None:
        la, ra, lb, rb = self._bounds
        cA = RA @ la + pA
        cB = RB @ lb + pB
        gap = float(np.linalg.norm(cB - cA)) - ra - rb
        if gap <= self.far_field:
            return None
        self.far += 1
        out = np.zeros(N_OUT)
        out[2], out[4] = 1.0, 1.0                    # point-point model with radii
        out[5:8], out[8:11] = la, lb
        out[11:14], out[14:17] = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0)
        out[19], out[20] = ra, rb
        return out

    def has_jacobian(self):
        return True

    # Dense zeros (not structural ones): with structurally empty derivative functions casadi's SX
    # Hessians of call nodes came out as NaN constants. Forward and reverse modes say the same.
    def get_jacobian(self, name, inames, onames, opts):
        x = ca.SX.sym("x", 24)
        o = ca.SX.sym("o", N_OUT)
        return ca.Function(name, [x, o], [ca.SX.zeros(N_OUT, 24)], inames, onames, opts)

    def has_forward(self, nfwd):
        return True

    def get_forward(self, nfwd, name, inames, onames, opts):
        x, o, s = ca.SX.sym("x", 24), ca.SX.sym("o", N_OUT), ca.SX.sym("s", 24, nfwd)
        return ca.Function(name, [x, o, s], [ca.SX.zeros(N_OUT, nfwd)], inames, onames, opts)

    def has_reverse(self, nadj):
        return True

    def get_reverse(self, nadj, name, inames, onames, opts):
        x, o, s = ca.SX.sym("x", 24), ca.SX.sym("o", N_OUT), ca.SX.sym("s", N_OUT, nadj)
        return ca.Function(name, [x, o, s], [ca.SX.zeros(24, nadj)], inames, onames, opts)


def signed_distance_expr(cb: WitnessCallback, RA, pA, RB, pB):
    """The signed distance as a casadi expression: the local contact model around the callback
    (exact value and first derivatives; exact Hessian wherever the feature model applies)."""
    x = ca.vertcat(ca.reshape(RA, 9, 1), pA, ca.reshape(RB, 9, 1), pB)
    return model_expression(cb(x), RA, pA, RB, pB)


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
