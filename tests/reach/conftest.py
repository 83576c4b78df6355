"""Fixtures shared by the reachability-graph tests: the Lab scene with a wall between the
arm's two sides (`reach_checks.lab_scene_with_wall`) and a private graph store."""
from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent))
from reach_checks import lab_scene_with_wall  # noqa: E402

ROOT = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def scene():
    return lab_scene_with_wall(ROOT)


@pytest.fixture
def store(tmp_path, monkeypatch):
    """GNPP_REACH_CACHE pointed at a fresh directory (returned)."""
    d = tmp_path / "reach"
    monkeypatch.setenv("GNPP_REACH_CACHE", str(d))
    return d
