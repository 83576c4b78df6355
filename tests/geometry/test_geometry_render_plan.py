"""Pictures of a solved plan (`gnpp solve --render`): only the problem's objects, the motion into
each keyframe as a swept path, labels that do not overlap, mobile bases drawn, an animated GIF."""
from __future__ import annotations

from pathlib import Path

import numpy as np
from PIL import Image, ImageDraw, ImageFont

from gnppdsl.geometry.context import GeometryContext
from gnppdsl.geometry.render import _overlap, _place_label, render_keyframes
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
PATH_COLOUR = (200, 30, 120)


def _pixels(path, rgb, tol=40) -> np.ndarray:
    a = np.asarray(Image.open(path).convert("RGB"), dtype=int)
    return (np.abs(a - np.array(rgb)).max(axis=2) < tol)


def test_plan_pictures(tmp_path):
    from gnppdsl.solve import load_and_compile, solve_problem

    compiled = load_and_compile(str(EXAMPLES / "planar" / "p3_occupied.pntc"))
    result = solve_problem(compiled)
    from gnppdsl.solve.keyframes import render_solution

    files = render_solution(compiled, result, str(tmp_path))
    pngs = [f for f in files if f.endswith(".png")]
    assert len(pngs) == 5 and files[-1].endswith("plan.gif")
    assert not _pixels(pngs[0], PATH_COLOUR, 10).any()          # s0: nothing moved yet
    assert all(_pixels(p, PATH_COLOUR, 10).sum() > 50 for p in pngs[1:])
    gif = Image.open(files[-1])
    assert gif.n_frames == 4 * 8 + 1                              # keyframes + 7 per phase


def test_only_the_problems_objects(tmp_path):
    from gnppdsl.solve import load_and_compile, solve_problem
    from gnppdsl.solve.keyframes import render_solution

    compiled = load_and_compile(str(EXAMPLES / "lab" / "lab1.pntc"))      # b1, b2 of b1..b5
    result = solve_problem(compiled)
    files = render_solution(compiled, result, str(tmp_path), gif=False)
    scene = compiled.problem.scene
    assert "b5" in scene.objects and "b5" not in compiled.problem.objects
    orange = tuple(round(255 * c) for c in scene.objects["b5"].color[:3])    # only b5 is orange
    for f in files:
        assert not _pixels(f, orange, 25).any()
        assert _pixels(f, (217, 38, 38), 30).any()                     # b1 is drawn (red)


def test_labels_never_overlap():
    img = Image.new("RGB", (400, 400), "white")
    draw = ImageDraw.Draw(img)
    font = ImageFont.load_default()
    placed = []
    square = np.array([[190, 190], [210, 190], [210, 210], [190, 210]], float)
    for name in ("right_arm", "b4", "b5", "pad_c", "g"):     # five bodies at one place
        box = _place_label(draw, font, name, square, placed, 400)
        assert not any(_overlap(box, other) for other in placed)
        placed.append(box)


def test_mobile_base_is_drawn(tmp_path):
    robot = SceneRobot("mm", "urdf", model="panda", ee="panda_hand_tcp", base=(0, 0, 0.4, 0, 0, 0, 1),
                       attributes={"base_joint": "planar"})
    floor = SceneObject("floor", SceneShape("box", (3, 3, 0.01)), (0, 0, -0.005, 0, 0, 0, 1), static=True,
                        color=(0.9, 0.9, 0.9, 1))
    scene = Scene("mobile", 3, {"mm": robot}, {"floor": floor})
    ctx = GeometryContext(scene)
    q = ctx.robot("mm").home_coords()
    q[:3] = (0.8, 0.0, 0.0)
    (png,) = render_keyframes(scene, ctx, [{"mm": q}], str(tmp_path), size=400)
    front = _pixels(png, (70, 70, 80), 6)[:, 400:]
    ys, xs = np.nonzero(front)
    assert len(xs) > 500
    top = _pixels(png, (70, 70, 80), 6)[:, :400]
    assert top.sum() > 500                                         # the footprint seen from above
    # from the floor up to the arm's root (0.4 m): taller than wide / 2 in the front view
    assert (ys.max() - ys.min()) > 0.5 * (xs.max() - xs.min())
