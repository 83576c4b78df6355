"""The bundled example scenes load into the geometry layer and their initial states are sane."""
from __future__ import annotations

import os

import numpy as np
import pytest

from gnppdsl.geometry import verify
from gnppdsl.geometry.context import GeometryContext

ROOT = os.path.join(os.path.dirname(__file__), "..", "..", "examples")
SCENES = ["lab/lab.yaml", "mobile/sorting.yaml", "planar/p3_occupied.yaml"]


@pytest.mark.parametrize("rel", SCENES)
def test_example_scene_initial_state(rel):
    path = os.path.join(ROOT, rel)
    from gnppdsl.ir.scene import load_scene_file
    scene = load_scene_file(path)
    ctx = GeometryContext(scene)
    for name, spec in scene.robots.items():
        if spec.kind == "urdf":
            q = ctx.robot(name).home_coords(spec.home)
            assert verify.joint_limit_violations(ctx, name, q) == [], name
    movable = [n for n, o in scene.objects.items() if not o.static and o.shape.kind != "none"]
    statics = [n for n, o in scene.objects.items() if o.static]
    # blocks rest on some static support (3-D) or start where the scene puts them (planar)
    if scene.dimension == 3:
        for b in movable:
            assert any(verify.resting_on(ctx, b, scene.objects[b].pose, s).ok for s in statics), b
    ignore = [(b, s) for b in movable for s in statics]
    rep = verify.check_state(ctx, {}, margin=0.0, ignore=ignore)
    assert rep.ok, f"{rel}:\n{rep}"
    assert all(np.isfinite(p.distance) for p in rep.distances)
