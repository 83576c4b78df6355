"""R-LGP's trajectory starts when the graph's path is a detour for the base (`solve.rlgp`:
`_detour`, `_drive`; `reach.drives`: `TravelMap.pushed`, `TravelMap.route`, `drive_waypoints`).

pick_place3_pr2 instance 12 (seed 0): the graph path from the red tray's base (-1.33, -0.81) to
red1's pick (-0.69, 0.80), north-west of the central table, drove 10.99 m round its east end,
and the plan drove 8.25 m (plain GNPP 1.86 m); started on the base's shortest drive, through the
gap west of the table, 1.64 m."""
from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace as NS

import numpy as np
import pytest

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"
RED_TRAY_BASE, RED1_PICK = (-1.33, -0.81), (-0.69, 0.80)


def _table(x=0.0, y=0.0, sx=1.2, sy=0.9):
    return NS(pose=[x, y, 0.25, 0.0, 0.0, 0.0, 1.0], shape=NS(kind="box", size=(sx, sy, 0.5)))


def _pr2_room():
    """The PR2 setting's tables (sorting_pr2_setting.yaml) and its base's disc (0.45 m)."""
    from gnppdsl.reach.drives import TravelMap

    tables = [_table(), _table(-1.8, 0.0, 0.5, 0.5), _table(1.8, 0.0, 0.5, 0.5)]
    return TravelMap(tables, 0.45, (-2.2, -1.6), (2.2, 1.6))


def _inside_table(p, t=_table(), grow=0.0):
    return abs(p[0] - t.pose[0]) < t.shape.size[0] / 2 + grow and abs(p[1] - t.pose[1]) < t.shape.size[1] / 2 + grow


def test_a_base_closer_to_a_table_than_its_disc_still_has_a_drive():
    """red1's pick base of instance 12 stands inside the central table's footprint grown by the
    PR2's disc (the NLP keeps the square platform's clearance, not the disc's): its drive from
    the red tray's base is finite, leaves the octagon, and is no shorter than the straight line
    (the base had every drive from it infinite, so no detour was ever seen)."""
    m = _pr2_room()
    a, b = np.array([RED_TRAY_BASE]), np.array([RED1_PICK])
    assert m._inside(b)[0] and not m._inside(m.pushed(b)[0])[0]
    d = m.distances(a, b)[0, 0]
    assert np.isfinite(d) and d >= np.linalg.norm(a - b) - 1e-9
    assert d == pytest.approx(m.distances(b, a)[0, 0])


def test_drive_waypoints_go_round_the_table_by_the_short_side():
    """`drive_waypoints`: the base of every row keeps out of the central table (west of it, the
    short side), the rows start and end at the two configurations, the other coordinates move
    monotonically from one to the other."""
    from gnppdsl.reach.drives import drive_waypoints

    m = _pr2_room()
    qa = np.r_[RED_TRAY_BASE, 2.2, 0.1, -0.3]
    qb = np.r_[RED1_PICK, 0.45, 0.5, 0.3]
    W = drive_waypoints(m, qa, qb, 20)
    assert W.shape == (20, 5) and np.allclose(W[0], qa) and np.allclose(W[-1], qb)
    assert all(not _inside_table(p, grow=0.3) for p in W[:, :2])
    assert W[:, 0].max() < -0.6                     # never east of the table's west edge
    along = np.linalg.norm(np.diff(W[:, :2], axis=0), axis=1).sum()
    assert along == pytest.approx(m.distances(qa[None, :2], qb[None, :2])[0, 0], rel=0.05)
    for j in (2, 3, 4):
        assert np.all(np.diff(W[:, j]) * np.sign(qb[j] - qa[j]) >= -1e-12)
    # a free straight line stays the straight line
    S = drive_waypoints(m, np.r_[-1.0, -1.2, 0, 0, 0], np.r_[1.0, -1.2, 1, 1, 1], 5)
    assert np.allclose(S, np.linspace([-1.0, -1.2, 0, 0, 0], [1.0, -1.2, 1, 1, 1], 5))


def test_rlgp_replaces_a_graph_path_round_the_far_side():
    """`ReachabilityCosts._detour` on pick_place3_pr2: a path from the red tray's base round the
    table's east end to the pick north-west of it is a detour, the drive west of the table is
    not; `_drive` gives the trajectory start along that drive."""
    from gnppdsl.solve.compiled import load_and_compile
    from gnppdsl.solve.rlgp import ReachabilityCosts

    c = load_and_compile([str(MOBILE / "pick_place3_pr2.pntc")], instance=12)
    costs = ReachabilityCosts()
    costs.compiled = c
    around = np.array([RED_TRAY_BASE, (0.0, -1.1), (1.2, -0.9), (1.25, 0.9), (0.0, 1.1), RED1_PICK])
    rows = np.c_[around, np.zeros((len(around), 8))]
    assert costs._detour("mm", rows)
    W = costs._drive("mm", rows[0], rows[-1], 20).reshape(20, -1)
    assert not costs._detour("mm", W)
    assert W[:, 0].max() < -0.6 and np.allclose(W[0], rows[0]) and np.allclose(W[-1], rows[-1])
