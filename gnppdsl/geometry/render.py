"""Pictures of keyframes: PNG images with orthographic views (top and front), no screen needed.

Why a software renderer: the machines that run `gnpp solve --render DIR` have no display and no
OpenGL; pillow is enough to draw every body as the 2-D convex hull of its projected vertices,
painted back to front. A person can then see where blocks and arms are at each step.

The views are fixed in scale across all keyframes of a plan so images can be compared.
Planar scenes get only the top view.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np



@dataclass
class _Poly:
    name: str
    label: str | None
    verts: np.ndarray          # world vertices (n x 3)
    color: tuple[int, int, int, int]
    layer: int = 0             # planar scenes: 0 static, 1 movable objects, 2 robots (drawn in this order)


def _rgba(c) -> tuple[int, int, int, int]:
    c = tuple(c) + (1.0,) * (4 - len(c))
    return tuple(int(round(255 * max(0.0, min(1.0, v)))) for v in c[:4])


def _polys(ctx, state: dict[str, Any]) -> list[_Poly]:
    from gnppdsl.geometry.verify import placed_bodies, world_vertices
    out = []
    scene = ctx.scene
    labelled = set()
    for p in placed_bodies(ctx, state):
        ent = scene.entity(p.owner)
        color = _rgba(ent.color) if ent is not None else (200, 200, 200, 255)
        label = p.owner if p.owner not in labelled else None     # a robot: at its first (root) link
        labelled.add(p.owner)
        layer = 2 if p.owner in scene.robots else (0 if p.static else 1)
        out.append(_Poly(p.name, label, world_vertices(p.body, p.T), color, layer))
    return out


def _hull_poly(pts2: np.ndarray) -> list[tuple[float, float]]:
    from gnppdsl.geometry.verify import _hull2
    h = _hull2(pts2)
    return [tuple(map(float, p)) for p in h]


class _View:
    """Orthographic view: world axes (u, v) on the image, depth axis d (larger = nearer)."""

    def __init__(self, title, u, v, d, lo, hi, size, planar=False):
        self.title, self.u, self.v, self.d = title, u, v, d
        self.planar = planar
        span = max(hi[u] - lo[u], hi[v] - lo[v], 1e-3)
        self.scale = (size - 40) / span
        self.lo, self.hi, self.size = lo, hi, size
        self.cu = (lo[u] + hi[u]) / 2
        self.cv = (lo[v] + hi[v]) / 2

    def px(self, pts: np.ndarray) -> np.ndarray:
        x = (pts[:, self.u] - self.cu) * self.scale + self.size / 2
        y = self.size / 2 - (pts[:, self.v] - self.cv) * self.scale + 10
        return np.c_[x, y]


def _draw_view(img, x0, view: _View, polys: list[_Poly], font, movable: frozenset = frozenset(),
               statics: frozenset = frozenset()):
    from PIL import ImageDraw
    layer = img.crop((x0, 0, x0 + view.size, view.size + 20))
    draw = ImageDraw.Draw(layer, "RGBA")
    draw.text((6, 4), view.title, fill=(0, 0, 0, 255), font=font)
    if view.planar:     # extrusion heights mean nothing: furniture, then objects, then robots
        order = sorted(polys, key=lambda p: p.layer)
    else:
        order = sorted(polys, key=lambda p: p.verts[:, view.d].max())   # far first
    for p in order:
        pts = view.px(p.verts)
        hull = _hull_poly(pts)
        if len(hull) < 3:
            continue
        fill = p.color[:3] + (min(p.color[3], 230),)
        outline = tuple(int(c * 0.5) for c in p.color[:3]) + (255,)
        if view.planar and p.layer == 2:    # planar robots: translucent with a strong outline
            draw.polygon(hull, fill=p.color[:3] + (120,), outline=(0, 0, 120, 255), width=2)
        else:
            draw.polygon(hull, fill=fill, outline=outline)
    # movable objects hidden under an arm stay visible: their outlines again, on top
    for p in order:
        if p.label and p.name in movable:
            hull = _hull_poly(view.px(p.verts))
            if len(hull) >= 3:
                draw.polygon(hull, outline=p.color[:3] + (255,))
    # world axes at the origin (10 cm): red = horizontal image axis, green = vertical
    o = view.px(np.zeros((1, 3)))[0]
    for axis, col in ((view.u, (220, 0, 0, 255)), (view.v, (0, 160, 0, 255))):
        e = np.zeros((1, 3))
        e[0, axis] = 0.1
        draw.line([tuple(o), tuple(view.px(e)[0])], fill=col, width=2)
    for p in order:
        if not p.label:
            continue
        px = view.px(p.verts)
        if p.layer == 2 and view.planar:  # a planar robot: label below it (it often sits on a block)
            c = px.mean(axis=0)
            draw.text((c[0] - 3 * len(p.label), px[:, 1].max() + 2), p.label, fill=(0, 0, 120, 255), font=font)
        elif p.name in movable or "/" in p.name or p.name not in statics:
            c = px.mean(axis=0)           # movable objects and robots: centred, black
            draw.text((c[0] - 3 * len(p.label), c[1] - 5), p.label, fill=(0, 0, 0, 255), font=font)
        else:                             # static furniture: small grey tag at its top-left corner
            draw.text((px[:, 0].min() + 2, px[:, 1].min() + 1), p.label, fill=(70, 70, 70, 255), font=font)
    img.paste(layer, (x0, 0))


def render_keyframes(scene, models, states: list[dict[str, Any]], out_dir: str, size: int = 560,
                     prefix: str = "keyframe", titles: list[str] | None = None,
                     what: str = "--render") -> list[str]:
    """Write one PNG per state (`{prefix}_{i:03d}.png`) into `out_dir`; return their paths.

    `models`: a `GeometryContext`, a dict robot name -> `RobotModel`, or None (load from the scene).
    `states`: dicts entity -> value as in `gnppdsl.geometry.verify` (world poses, joint coords).
    Files are written atomically, never through a symbolic link (`gnppdsl.outputs`); the
    keyframes of an earlier render into the same directory that this one does not rewrite
    are removed (`_forget_old_keyframes`). `what` names the option in error messages.
    """
    from PIL import Image, ImageDraw, ImageFont
    from gnppdsl.geometry.context import GeometryContext
    from gnppdsl.outputs import atomic_open, output_dir

    ctx = models if isinstance(models, GeometryContext) else GeometryContext(scene, models)
    directory = output_dir(out_dir, what)
    all_polys = [_polys(ctx, s) for s in states]
    pts = np.vstack([p.verts for ps in all_polys for p in ps]) if any(all_polys) else np.zeros((1, 3))
    # frame what is there in any keyframe (the scene workspace is often much larger)
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * max(hi - lo)
    lo, hi = lo - pad, hi + pad
    views = [_View("top (x right, y up)", 0, 1, 2, lo, hi, size, planar=scene.dimension == 2)]
    if scene.dimension == 3:
        views.append(_View("front (x right, z up)", 0, 2, 1, lo, hi, size))
    font = ImageFont.load_default()
    movable = frozenset(n for n, o in scene.objects.items() if not o.static)
    statics = frozenset(n for n, o in scene.objects.items() if o.static)
    paths = []
    for i, polys in enumerate(all_polys):
        img = Image.new("RGBA", (size * len(views), size + 20), (255, 255, 255, 255))
        for k, v in enumerate(views):
            _draw_view(img, k * size, v, front_polys_for_depth(polys) if v.v == 2 else polys, font, movable, statics)
        d = ImageDraw.Draw(img)
        title = titles[i] if titles and i < len(titles) else f"{scene.name}: keyframe {i}"
        d.text((6, size + 4), title, fill=(0, 0, 0), font=font)
        for k in range(1, len(views)):
            d.line([(k * size, 0), (k * size, size + 20)], fill=(180, 180, 180), width=1)
        path = os.path.join(out_dir, f"{prefix}_{i:03d}.png")
        with atomic_open(path, what, binary=True) as fh:
            img.convert("RGB").save(fh, format="PNG")
        paths.append(path)
    _forget_old_keyframes(directory, prefix, paths, what)
    return paths


MANIFEST = ".gnpp-render.json"


def _forget_old_keyframes(directory, prefix: str, paths: list[str], what: str) -> None:
    """Remove the keyframes an earlier render into `directory` wrote and this one did not
    (a 6-step plan after a 10-step one), and only those: the names come from the manifest
    the earlier render left (`.gnpp-render.json`), so a file the user put there, even one
    called keyframe_009.png, is never touched; a symbolic link listed there is left alone."""
    import json
    import stat

    from gnppdsl.inputs import InputError, read_text
    from gnppdsl.outputs import write_atomic

    manifest = directory / MANIFEST
    old: list[str] = []
    try:
        data = json.loads(read_text(manifest))
        if isinstance(data, dict) and isinstance(data.get(prefix), list):
            old = [n for n in data[prefix] if isinstance(n, str)]
    except (InputError, ValueError):
        data = {}
    new = [os.path.basename(p) for p in paths]
    for name in set(old) - set(new):
        if not re.fullmatch(rf"{re.escape(prefix)}_\d{{3,}}\.png", name):
            continue                          # only names this function writes
        try:
            if stat.S_ISREG(os.lstat(directory / name).st_mode):
                os.unlink(directory / name)
        except OSError:
            pass
    data = data if isinstance(data, dict) else {}
    data[prefix] = sorted(new)
    write_atomic(manifest, json.dumps(data, indent=1) + "\n", what)


def front_polys_for_depth(polys: list[_Poly]) -> list[_Poly]:
    """Front view looks along +y, so bodies with smaller y are nearer: flip y for the depth sort
    only (the projection uses x and z, which are unchanged)."""
    return [_Poly(p.name, p.label, p.verts * np.array([1.0, -1.0, 1.0]), p.color, p.layer) for p in polys]
