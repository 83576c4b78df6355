"""`gnpp view RESULT --html FILE`: the page is self-contained and renders the animated scene.

Oracles: headless Chromium (Debian's `chromium`, network blocked by a proxy that does not exist)
takes screenshots of the page; the pixels of the problem's coloured objects must be there, and
in the planar p3 the red block b1 must be on the left at t = 0 and on the target (right) at the
end of the plan. The sampled placements of a held block are checked against pinocchio forward
kinematics of the waypoint composed with the block's relative pose (no factory, no casadi).
"""
from __future__ import annotations

import shutil
import subprocess

import numpy as np
import pytest

from gnppdsl.cli.main import main


def _chromium() -> str:
    exe = shutil.which("chromium") or shutil.which("chromium-browser")
    if exe is None:
        pytest.skip("chromium is not installed (apt-get install chromium): the HTML viewer is not rendered")
    return exe


def _screenshot(page, png, t: float, extra: str = "", bar: bool = False) -> np.ndarray:
    from PIL import Image

    cmd = [_chromium(), "--headless", "--no-sandbox", "--disable-gpu", "--enable-unsafe-swiftshader",
           "--disable-background-networking", "--proxy-server=127.0.0.1:9", "--window-size=1000,700",
           "--virtual-time-budget=8000", f"--screenshot={png}", f"{page.resolve().as_uri()}#t={t}{extra}"]
    subprocess.run(cmd, capture_output=True, timeout=180, check=True)
    img = np.asarray(Image.open(png).convert("RGB")).astype(int)
    return img if bar else img[:600]                                      # above the timeline bar


def _mask(img: np.ndarray, rgb) -> np.ndarray:
    """Pixels near a base colour whatever the shading (same hue, brightness may change)."""
    c = np.asarray(rgb, float) / max(rgb)
    px = img / np.maximum(img.max(axis=2, keepdims=True), 1)
    return (np.abs(px - c).max(axis=2) < 0.25) & (img.max(axis=2) > 80)


def test_page_is_self_contained(solved_json, tmp_path):
    data = solved_json("lab/lab1.pntc")
    page = tmp_path / "v" / "lab1.html"
    assert main(["view", data["_path"], "--html", str(page)]) == 0
    text = page.read_text()
    assert "<script src" not in text and "<link " not in text and "@import" not in text
    assert text.count("_meshfile_object") >= 20          # every Panda link, both arms
    assert main(["view", data["_path"], "--html", str(page)]) == 2   # not overwritten unasked


def test_planar_animation_renders_and_moves(solved_json, tmp_path):
    data = solved_json("planar/p3_occupied.pntc")
    page = tmp_path / "p3.html"
    assert main(["view", data["_path"], "--html", str(page)]) == 0
    end = data["steps"][-1]["time"]
    start_img = _screenshot(page, tmp_path / "a.png", 0.0)
    end_img = _screenshot(page, tmp_path / "b.png", end)
    assert len(np.unique(start_img.reshape(-1, 3), axis=0)) > 50        # not blank
    red = (217, 38, 38)                                                   # b1 (scene colour red)
    a, b = _mask(start_img, red), _mask(end_img, red)
    assert a.sum() > 200 and b.sum() > 200
    xa, xb = np.nonzero(a)[1].mean(), np.nonzero(b)[1].mean()
    assert xb - xa > 200          # b1 went from x = -0.5 to the target at x = +0.5 (right)
    assert _mask(start_img, (51, 89, 217)).sum() > 200                    # b2, blue


def test_robot_meshes_render(solved_json, tmp_path):
    data = solved_json("lab/lab1.pntc")
    page = tmp_path / "lab1.html"
    assert main(["view", data["_path"], "--html", str(page)]) == 0
    img = _screenshot(page, tmp_path / "lab1.png", 0.5)
    assert len(np.unique(img.reshape(-1, 3), axis=0)) > 500
    white = (img.min(axis=2) > 200) & (np.ptp(img, axis=2) < 20)        # the Pandas' white shells
    assert white.sum() > 2000
    assert _mask(img, (217, 38, 38)).sum() > 30                           # b1


def test_held_block_follows_the_waypoints(solved_json):
    from gnppdsl.geometry.robots import se3_to_matrix
    from gnppdsl.solve import load_and_compile
    from gnppdsl.view.samples import sample_motion

    data = solved_json("lab/lab1.pntc")
    compiled = load_and_compile([data["inputs"]["domain"], data["inputs"]["problem"]])
    s = sample_motion(data, compiled)
    st = data["steps"][1]                     # b2 held by left_arm on the way to b1
    assert "parent(b2) = left_arm" in st["state"]
    rel = se3_to_matrix(st["values"]["pose(b2)"])
    times = st["trajectory_times"]["path(left_arm)"]
    ee = compiled.problem.scene.robots["left_arm"].ee
    checked = 0
    for q, t in zip(st["trajectories"]["path(left_arm)"][1:-1], times[1:-1]):
        k = s.times.index(t)
        expected = compiled.geometry.fk_matrix("left_arm", np.asarray(q), ee) @ rel
        assert np.allclose(s.placements["objects/b2"][k], expected, atol=1e-9)
        checked += 1
    assert checked >= 10
    assert s.times == sorted(s.times) and len(s.times) == len(set(s.times))


def test_selected_conflict_is_highlighted_in_3d_and_on_the_timeline(solved_json, tmp_path):
    """p3's one conflict, {parent(b1) = target, parent(b2) = s2}: with it selected
    (`#conflict=0`) the blocks it names turn orange in the rendered scene (red b1 and blue b2
    gone), and the timeline's actions on them are orange; without it, no orange anywhere."""
    from gnppdsl.view.html import conflict_names

    data = solved_json("planar/p3_occupied.pntc")
    (conflict,) = data["conflicts"]
    assert {"b1", "b2", "target", "s2"} <= conflict_names(conflict)        # the text names them
    assert all(n in conflict["text"] for n in ("b1", "b2", "target", "s2"))
    page = tmp_path / "p3c.html"
    assert main(["view", data["_path"], "--html", str(page)]) == 0
    plain = _screenshot(page, tmp_path / "plain.png", 0.0, bar=True)
    shown = _screenshot(page, tmp_path / "conflict.png", 0.0, "&conflict=0", bar=True)
    orange = (255, 140, 0)
    scene, bar = shown[:600], shown[640:]
    assert _mask(scene, orange).sum() > 400 + _mask(plain[:600], orange).sum()   # b1, b2, target
    assert _mask(plain[640:], (240, 160, 64)).sum() < 300          # (the red cursor is near)
    for rgb in ((217, 38, 38), (51, 89, 217)):                              # b1 red, b2 blue no more
        before, after = _mask(plain[100:600], rgb).sum(), _mask(scene[100:], rgb).sum()
        assert after < before - 150, (rgb, before, after)
    assert _mask(bar, (240, 160, 64)).sum() + _mask(bar, (208, 106, 0)).sum() > 2000  # all 4 actions
