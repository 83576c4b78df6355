"""Keyframe pictures: files are written, bodies appear where they are, planar scenes work."""
from __future__ import annotations

import numpy as np
import pytest
from PIL import Image

from gnppdsl.errors import UserError
from gnppdsl.geometry.context import GeometryContext
from gnppdsl.geometry.render import render_keyframes
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

RED = (230, 25, 25)


def _scene3():
    objs = [SceneObject("table", SceneShape("box", (1.6, 0.8, 0.05)), (0.5, 0, -0.025, 0, 0, 0, 1), static=True,
                        color=(0.6, 0.45, 0.3, 1)),
            SceneObject("b1", SceneShape("box", (0.06, 0.06, 0.06)), (0.5, 0.1, 0.03, 0, 0, 0, 1), color=(0.9, 0.1, 0.1, 1))]
    robots = {"left": SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp")}
    return Scene("lab", 3, robots, {o.name: o for o in objs})


def _red_centroid(img: Image.Image, x0: int, x1: int):
    a = np.asarray(img.convert("RGB"), dtype=int)[:, x0:x1]
    mask = (np.abs(a - np.array(RED)) < 12).all(axis=2)
    ys, xs = np.nonzero(mask)
    return (xs.mean() + x0, ys.mean()) if len(xs) else None


def test_render_3d(tmp_path):
    scene = _scene3()
    ctx = GeometryContext(scene)
    q = ctx.robot("left").home_coords()
    states = [{"left": None}, {"b1": (0.8, -0.2, 0.03, 0, 0, 0, 1), "left": q + 0.3}]    # None: scene value
    paths = render_keyframes(scene, ctx, states, str(tmp_path / "out"), size=400)
    assert len(paths) == 2
    imgs = [Image.open(p) for p in paths]
    assert all(im.size == (800, 420) for im in imgs)
    c0, c1 = _red_centroid(imgs[0], 0, 400), _red_centroid(imgs[1], 0, 400)
    assert c0 is not None and c1 is not None
    # top view: x right, y up. b1 moved +0.3 in x and -0.3 in y
    assert c1[0] - c0[0] > 30 and c1[1] - c0[1] > 30
    # front view shows the block too
    assert _red_centroid(imgs[0], 400, 800) is not None
    assert np.asarray(imgs[0]).std() > 10      # not a blank picture


def test_render_planar(tmp_path):
    objs = [SceneObject("c1", SceneShape("circle", (0.05,)), (0,) * 6 + (1,), pose2=(0.2, 0.1, 0), color=(0.9, 0.1, 0.1, 1)),
            SceneObject("r", SceneShape("box", (0.4, 0.4)), (0,) * 6 + (1,), pose2=(-0.4, 0, 0), static=True)]
    robots = {"g": SceneRobot("g", "planar", shape=SceneShape("box", (0.05, 0.1)), home=(0, 0.4, 0))}
    scene = Scene("planar", 2, robots, {o.name: o for o in objs})
    paths = render_keyframes(scene, None, [{}, {"g": (0.2, 0.2, 0.5)}], str(tmp_path), size=300)
    im = Image.open(paths[0])
    assert im.size == (300, 320)                  # top view only
    assert _red_centroid(im, 0, 300) is not None


def test_render_bad_dir(tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    with pytest.raises(UserError, match="cannot create the directory"):
        render_keyframes(_scene3(), None, [{}], str(f / "sub"))
