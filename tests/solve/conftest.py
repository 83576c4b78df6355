"""Fixtures shared by the solve tests."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.solve import feasibility_check


@pytest.fixture
def zigzag_starts(monkeypatch):
    """Straight-line starts of the toy's paths already satisfy their phases (no phase NLP
    would run): the interpolation is replaced by a zigzag that breaks the step bound, so the
    phases are solved by their NLPs."""
    real = feasibility_check.interpolate_trajectories

    def zigzag(trajs, values, neighbours=lambda v: ()):
        out = real(trajs, values, neighbours)
        for v, x in out.items():
            pts = x.reshape(v.waypoints, v.point_dim).copy()
            pts[1:-1] += 0.4 * (-1.0) ** np.arange(1, v.waypoints - 1)[:, None]
            out[v] = pts.reshape(-1)
        return out

    monkeypatch.setattr(feasibility_check, "interpolate_trajectories", zigzag)
