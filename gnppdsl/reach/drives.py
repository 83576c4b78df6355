"""R-LGP's keyframe bases: the drives of a mobile base among the tables (`TravelMap`) and the
plan's bases chosen by the least drive through all its picks and puts (`plan_bases`).

The ring points, footprints and facing are `gnppdsl.compile.placement`'s (the restarts' base
placements, one keyframe at a time); this module sits above it (R-LGP's layer) and
`solve.rlgp` hands `plan_bases` to `placement.restart_guesses`. Why here and not in compile: a
visibility graph among grown footprints is geometry of the base's travel, as the reachability
graph is of the arm's; compile only places one keyframe next to its target.

R-LGP's keyframe starts (`compile.placement.restart_guesses(plan=plan_bases)`, `solve.rlgp`) are
chosen per plan (`plan_bases`): one free point of any ring per pick or put, together the shortest
drive from home through all of them in the plan's order (a dynamic programme over the targets'
ring points; the drive between two points by `TravelMap`, around the tables' footprints grown by
the base's radius). Why: the side nearest the previous base can be the wrong one for the rest of
the plan. sort_random_pr2 instance 4 (seed 0): the greedy choice put the second pick (blue1, west
of the table's centre) west of it, the nearest side to the red tray's base; the NLP slid the base
to the north and the plan drove 4.28 m (GNPP 2.20 m). The plan's choice picks it from the south,
where the drive to the blue tray goes: 2.44 m, 10.8 s CPU instead of 18.6, verified. A point
beyond the innermost ring costs RING_WEIGHT metres of drive per metre (the NLP has to pull an out-
of-reach base in; without it instance 0's first pick started on the PR2's 1.1 m ring and the run
drove 4.07 m). Measured (`gnpp bench examples/mobile/sort_random_pr2.pntc --algorithms rlgp
--instances 10 --time-limit 120`, GNPP_REACH_CACHE=0, 996040d against this, load 4-9):
sort_random_pr2 R-LGP solved 9/10 both (996040d failed instance 5's verification, this instance
8's), mean base on the 7 both solved 3.10 -> 2.82 m (GNPP 2.88), on the 9 this and GNPP solved
2.92 m against GNPP's 3.36; sort_random (Panda) 10/10 both, mean base 2.82 -> 2.94 m
(instances 4, 6, 7 longer, 5 and 9 shorter), mean CPU 6.1 -> 5.7 s.
"""
from __future__ import annotations

import math
from typing import Sequence

from gnppdsl.compile.placement import ANGLES, BASE_RADIUS, RADII, Footprint, _facing, _ring_points, _yaw

RING_WEIGHT = 0.5               # plan_bases: drive (m) a ring point costs per metre beyond the innermost ring


class TravelMap:
    """Shortest drives of a disc of `radius` among the obstacles' footprints (the metric of
    `plan_bases`): each footprint grown by `radius`, as the octagon around it (a box's
    rectangle grown by `radius` on each side with its corners cut by the tangents of the
    rounded corners at 45 degrees; any other shape's circle), the distance between two points
    the straight line when it crosses no octagon's interior, else the shortest path through
    the octagons' vertices (a visibility graph; vertices inside another octagon or outside
    `lo`/`hi` are left out). Contains the disc's Minkowski sum, so a free drive is one."""

    def __init__(self, obstacles, radius: float, lo=None, hi=None):
        import numpy as np

        from gnppdsl.ir.instances import footprint_radius

        r2 = math.sqrt(2.0)
        self.planes = []                  # per octagon: normals (8, 2), offsets (8,): n.p <= b
        corners = []
        for o in obstacles:
            size = tuple(o.shape.size or ())
            if o.shape.kind == "box" and len(size) >= 2:
                t, ex, ey = _yaw(o.pose[3:7]), size[0] / 2, size[1] / 2
            else:
                t, ex, ey = 0.0, footprint_radius(o), footprint_radius(o)
            ax, ay = ex + radius, ey + radius
            cut = ex + ey + radius * r2
            local_n = np.array([[1, 0], [-1, 0], [0, 1], [0, -1],
                                [1 / r2, 1 / r2], [-1 / r2, 1 / r2], [-1 / r2, -1 / r2], [1 / r2, -1 / r2]])
            local_b = np.array([ax, ax, ay, ay] + [cut / r2] * 4)
            d = radius * (r2 - 1)
            local_v = [(sx * ax, sy * (ey + d)) for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            local_v += [(sx * (ex + d), sy * ay) for sx, sy in ((1, 1), (1, -1), (-1, 1), (-1, -1))]
            c, s = math.cos(t), math.sin(t)
            R = np.array([[c, -s], [s, c]])
            centre = np.array([float(o.pose[0]), float(o.pose[1])])
            N = local_n @ R.T
            self.planes.append((N, local_b + N @ centre))
            corners += [tuple(R @ (np.asarray(v) * (1 + 1e-6)) + centre) for v in local_v]
        K = np.asarray(corners, float).reshape(-1, 2)
        if len(K) and lo is not None and hi is not None:
            K = K[(K[:, 0] >= lo[0]) & (K[:, 0] <= hi[0]) & (K[:, 1] >= lo[1]) & (K[:, 1] <= hi[1])]
        if len(K):
            K = K[~self._inside(K)]
        self.corners = K
        D = self._direct(K, K)            # all-pairs shortest paths among the vertices
        for k in range(len(K)):
            D = np.minimum(D, D[:, k:k + 1] + D[k:k + 1, :])
        self.between = D

    def _inside(self, P):
        import numpy as np

        out = np.zeros(len(P), bool)
        for N, b in self.planes:
            out |= np.all(P @ N.T < b - 1e-9, axis=1)
        return out

    def _blocked(self, P, Q):
        """Per pair (P[i], Q[i]): does the segment cross an octagon's interior (Cyrus-Beck)?"""
        import numpy as np

        out = np.zeros(len(P), bool)
        D = Q - P
        for N, b in self.planes:
            t0, t1 = np.zeros(len(P)), np.ones(len(P))
            hit = np.ones(len(P), bool)
            for n, bk in zip(N, b):
                pk, qk = D @ n, (bk - 1e-9) - P @ n        # n.(p + t d) < b: pk t < qk
                par = np.abs(pk) < 1e-15
                hit &= ~(par & (qk <= 0))
                r = qk / np.where(par, 1.0, pk)
                t0 = np.where(~par & (pk < 0), np.maximum(t0, r), t0)
                t1 = np.where(~par & (pk > 0), np.minimum(t1, r), t1)
            out |= hit & (t1 - t0 > 1e-9)
        return out

    def _direct(self, A, B):
        """|a - b| where the segment is free, inf where it is blocked: shape (len A, len B)."""
        import numpy as np

        A, B = np.asarray(A, float).reshape(-1, 2), np.asarray(B, float).reshape(-1, 2)
        d = np.linalg.norm(A[:, None, :] - B[None, :, :], axis=2)
        if len(A) and len(B) and self.planes:
            P = np.repeat(A, len(B), axis=0)
            Q = np.tile(B, (len(A), 1))
            d = np.where(self._blocked(P, Q).reshape(len(A), len(B)), np.inf, d)
        return d

    def pushed(self, P):
        """(P', extra): each point of P inside an octagon moved to the nearest point of its
        boundary (its nearest face), repeated while it lands in another (at most 4 times); extra
        the distance moved. Why: a keyframe's base can stand closer to a table than the disc
        (the NLP keeps the base link's own clearance: the PR2's square platform facing a table
        0.35 m from it where the disc needs 0.45 m); from inside an octagon every straight
        segment was blocked and every drive infinite."""
        import numpy as np

        P = np.array(P, float).reshape(-1, 2)
        extra = np.zeros(len(P))
        for _ in range(4):
            moved = False
            for N, b in self.planes:
                gap = b[None, :] - P @ N.T                 # > 0 on the inner side of each face
                inside = np.all(gap > 1e-9, axis=1)
                if not inside.any():
                    continue
                k = gap[inside].argmin(axis=1)
                step = gap[inside, k] * (1 + 1e-6) + 1e-9
                P[inside] += step[:, None] * N[k]
                extra[inside] += step
                moved = True
            if not moved:
                break
        return P, extra

    def distances(self, A, B):
        """The drives from each point of A to each of B: shape (len A, len B); a point inside
        an octagon first drives out of it (`pushed`)."""
        import numpy as np

        A, ea = self.pushed(A)
        B, eb = self.pushed(B)
        return self._distances(A, B) + ea[:, None] + eb[None, :]

    def _distances(self, A, B):
        import numpy as np

        d = self._direct(A, B)
        if len(self.corners):
            to = (self._direct(A, self.corners)[:, :, None] + self.between[None]).min(axis=1)
            via = (to[:, :, None] + self._direct(self.corners, B)[None]).min(axis=1)
            d = np.minimum(d, via)
        return d


    def route(self, a, b) -> list:
        """The shortest drive from a to b as its corner points [a, ..., b] (the straight line
        when it is free or when no drive round the octagons joins them)."""
        import numpy as np

        a0 = np.asarray(a, float).reshape(-1)[:2]
        b0 = np.asarray(b, float).reshape(-1)[:2]
        a, b = self.pushed(a0)[0][0], self.pushed(b0)[0][0]
        ends = ([a0] if np.any(a != a0) else []), ([b0] if np.any(b != b0) else [])
        return ends[0] + self._route(a, b) + ends[1]

    def _route(self, a, b) -> list:
        import numpy as np

        K = self.corners
        if not len(K) or np.isfinite(self._direct(a, b)[0, 0]):
            return [a, b]
        tot = self._direct(a, K)[0][:, None] + self.between + self._direct(K, b)[:, 0][None, :]
        i, j = np.unravel_index(int(np.argmin(tot)), tot.shape)
        if not np.isfinite(tot[i, j]):
            return [a, b]
        if getattr(self, "_hops", None) is None:
            self._hops = self._direct(K, K)
        out, k = [a, K[i]], int(i)
        for _ in range(len(K)):           # next corner on a shortest path from k to j
            if k == j:
                break
            cand = self._hops[k] + self.between[:, j]
            cand[k] = np.inf
            k = int(np.argmin(cand))
            out.append(K[k])
        out.append(b)
        return out


def drive_waypoints(travel: TravelMap, qa, qb, n: int):
    """n trajectory rows from configuration qa to qb ([x, y, theta, ...]) whose base follows
    `travel`'s shortest drive between their (x, y), evenly by arc length; every other
    coordinate moves linearly with the share of the drive done (the straight line's rows when
    the drive is the straight line). Rows 0 and n-1 are qa and qb."""
    import numpy as np

    qa, qb = np.asarray(qa, float).reshape(-1), np.asarray(qb, float).reshape(-1)
    pts = np.asarray(travel.route(qa[:2], qb[:2]), float)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    u = np.linspace(0.0, 1.0, n)
    out = qa[None, :] + u[:, None] * (qb - qa)[None, :]
    if s[-1] > 0:
        out[:, 0] = np.interp(u * s[-1], s, pts[:, 0])
        out[:, 1] = np.interp(u * s[-1], s, pts[:, 1])
    out[0], out[-1] = qa, qb
    return out


def _ring_layer(target: Sequence[float], obstacles, lo, hi, radius: float, footprint: Footprint | None):
    """The free ring points around `target` (`_ring_points`) as ((n, 2) positions, (n,) ring
    penalties: RING_WEIGHT x the metres beyond the innermost ring), n = 0 when none is free.
    Shared by `plan_bases`' chain and `pair_drives`' pairs, so both price a point alike."""
    import numpy as np

    pts = _ring_points(target, obstacles, lo, hi, radius, footprint=footprint)
    return (np.asarray([(x, y) for x, y, _ in pts], float).reshape(-1, 2),
            np.asarray([RING_WEIGHT * (RADII[k // ANGLES] - RADII[0]) for *_, k in pts], float))


def plan_bases(targets: Sequence[Sequence[float]], home: Sequence[float], obstacles,
               lo: Sequence[float] | None = None, hi: Sequence[float] | None = None,
               radius: float = BASE_RADIUS, footprint: Footprint | None = None) -> list[list[float] | None]:
    """One base per target (the robot's picks and puts in the plan's order), each a free point
    of any ring around its target (`_ring_points`: the base's `footprint` facing the target
    when given, else the disc of `radius`), together the least drive home -> first -> ... ->
    last (`TravelMap`'s distances, for the disc; a dynamic programme over the targets' ring
    points), facing its target (`_facing`). None for a target without a free ring point (the
    chain skips it)."""
    import numpy as np

    travel = TravelMap(obstacles, radius, lo, hi)
    layers = []                           # (target index, points (n, 2), their ring penalties)
    for i, t in enumerate(targets):
        pts, pen = _ring_layer(t, obstacles, lo, hi, radius, footprint)
        if len(pts):
            layers.append((i, pts, pen))
    out: list = [None] * len(targets)
    if not layers:
        return out
    cost = travel.distances(np.asarray([home[:2]], float), layers[0][1])[0] + layers[0][2]
    back = []
    for (_, a, _), (_, b, pen) in zip(layers, layers[1:]):
        total = cost[:, None] + travel.distances(a, b) + pen[None, :]
        back.append(total.argmin(axis=0))
        cost = total.min(axis=0)
    k = int(np.argmin(cost))              # first of the least (ring order breaks ties)
    for j in range(len(layers) - 1, -1, -1):
        i, pts, _ = layers[j]
        out[i] = _facing(home, float(pts[k][0]), float(pts[k][1]), targets[i])
        if j:
            k = int(back[j - 1][k])
    return out


def pair_drives(targets, home: Sequence[float], obstacles, lo: Sequence[float] | None = None,
                hi: Sequence[float] | None = None, radius: float = BASE_RADIUS,
                footprint: Footprint | None = None, travel: TravelMap | None = None) -> dict:
    """R-LGP's base drive between consecutive picks and puts, for the planner's pair costs:
    `targets` maps an operator to its target (x, y, ...); the result maps (prev, op) to the least
    drive (m, `TravelMap`) from a free ring point of prev's target to one of op's, plus the ring
    penalty of the point reached (RING_WEIGHT, as `plan_bases`), and (None, op) to the least
    drive from home. A target without a free ring point has no entries. Per pair the two ends
    are chosen independently, so the sum over a plan is a lower bound of `plan_bases`' chain.
    Targets are compared by position: a target shared by many operators is computed once.
    `travel`: the caller's `TravelMap` of the same obstacles, radius and bounds (built here when
    None)."""
    import numpy as np

    travel = travel if travel is not None else TravelMap(obstacles, radius, lo, hi)
    points: dict = {}                     # rounded (x, y) -> (ring points (n, 2), penalties (n,))
    key_of: dict = {}
    for op, t in targets.items():
        key = (round(float(t[0]), 6), round(float(t[1]), 6))
        key_of[op] = key
        if key not in points:
            points[key] = _ring_layer(t, obstacles, lo, hi, radius, footprint)
    keys = [k for k in points if len(points[k][0])]
    home_xy = np.asarray(home[:2], float).reshape(1, 2)
    drive: dict = {}
    for a in [None] + keys:
        A = home_xy if a is None else points[a][0]
        for b in keys:
            B, pen = points[b]
            drive[(a, b)] = float((travel.distances(A, B) + pen[None, :]).min())
    out: dict = {}
    for op, b in key_of.items():
        if (None, b) not in drive:
            continue
        out[(None, op)] = drive[(None, b)]
        for prev, a in key_of.items():
            if (a, b) in drive:
                out[(prev, op)] = drive[(a, b)]
    return out


__all__ = ["TravelMap", "plan_bases", "pair_drives", "drive_waypoints", "RING_WEIGHT"]
