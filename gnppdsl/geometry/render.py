"""Pictures of keyframes: PNG images with orthographic views (top and front), no screen needed.

Why a software renderer: the machines that run `gnpp solve --render DIR` have no display and no
OpenGL; pillow is enough to draw every body as the 2-D convex hull of its projected vertices,
painted back to front. A person can then see where blocks and arms are at each step.

The views are fixed in scale across all keyframes of a plan so images can be compared.
Planar scenes get only the top view. What else a picture shows:
- only the problem's entities (`entities`; scene furniture always), not every object of a scene
  shared by several problems;
- a mobile base (a URDF robot on a planar root joint) as a box from the floor to the arm's root,
  so the arm does not float;
- the motion that led to the keyframe (`motions`): faint outlines of the robots and moved objects
  at intermediate waypoints, and the swept path of each moving body's centre as a line;
- labels placed greedily where they do not overlap each other (centre, then around the body).
`render_animation` writes the whole motion as an animated GIF with the same views.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass
from typing import Any

import numpy as np

from gnppdsl.errors import UserError



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


def _polys(ctx, state: dict[str, Any], entities: frozenset | None = None) -> list[_Poly]:
    from gnppdsl.geometry.verify import placed_bodies, world_vertices
    out = []
    scene = ctx.scene
    labelled = set()
    for p in placed_bodies(ctx, state):
        if entities is not None and p.owner not in entities:
            continue
        ent = scene.entity(p.owner)
        color = _rgba(ent.color) if ent is not None else (200, 200, 200, 255)
        label = p.owner if p.owner not in labelled else None     # a robot: at its first (root) link
        labelled.add(p.owner)
        layer = 2 if p.owner in scene.robots else (0 if p.static else 1)
        out.append(_Poly(p.name, label, world_vertices(p.body, p.T), color, layer))
    out += _mobile_bases(ctx, state, entities)
    return out


BASE_FOOTPRINT = (0.5, 0.5)     # m, a mobile base without a scene `base_size`


def mobile_base(model, spec, q, base=None) -> tuple[tuple[float, float, float], np.ndarray] | None:
    """The box drawn for a mobile base: a URDF robot (`RobotModel` `model`, `SceneRobot` `spec`)
    whose root joint is planar (x, y, theta first) stands on a box from the floor to its root,
    footprint `base_size` (scene attribute) or BASE_FOOTPRINT. Returns (size, world 4x4 of the
    box centre), None for other robots. Why drawn at all: the URDF has no base body, so without
    it the arm floats in the pictures and the viewer."""
    from gnppdsl.geometry.robots import se3_to_matrix
    if not model.coords or model.coords[0].kind != "planar":
        return None
    x, y, th = np.asarray(q, float)[:3]
    B = model.base if base is None else se3_to_matrix(base)
    c, s_ = np.cos(th), np.sin(th)
    J = np.eye(4)
    J[:2, :2] = [[c, -s_], [s_, c]]
    J[:2, 3] = (x, y)
    T = B @ J
    sx, sy = (tuple(spec.attributes.get("base_size", BASE_FOOTPRINT)) + BASE_FOOTPRINT)[:2]
    h = max(float(T[2, 3]), 0.05)
    C = T.copy()
    C[2, 3] -= h / 2
    return (float(sx), float(sy), h), C


def _mobile_bases(ctx, state: dict[str, Any], entities: frozenset | None) -> list[_Poly]:
    """A box under every mobile base (`mobile_base`)."""
    from gnppdsl.geometry.verify import robot_q_base, state_value
    out = []
    for name, spec in ctx.scene.robots.items():
        if spec.kind != "urdf" or (entities is not None and name not in entities):
            continue
        q, base = robot_q_base(ctx, name, state_value(ctx, state, name))
        box = mobile_base(ctx.robot(name), spec, q, base)
        if box is None:
            continue
        (sx, sy, h), C = box
        corners = np.array([[u * sx / 2, v * sy / 2, w * h / 2, 1.0] for u in (-1, 1) for v in (-1, 1) for w in (-1, 1)])
        out.append(_Poly(f"{name}/mobile_base", None, (C @ corners.T).T[:, :3], (70, 70, 80, 255), 2))
    return out


def _hull_poly(pts2: np.ndarray) -> list[tuple[float, float]]:
    from gnppdsl.geometry.verify import convex_hull_2d
    h = convex_hull_2d(pts2)
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
    placed: list[tuple[float, float, float, float]] = []
    for p in sorted(order, key=lambda p: (p.name not in movable, p.layer)):    # objects first
        if not p.label:
            continue
        px = view.px(p.verts)
        colour = (0, 0, 120, 255) if p.layer == 2 and view.planar else \
            (0, 0, 0, 255) if (p.name in movable or "/" in p.name or p.name not in statics) else (70, 70, 70, 255)
        box = _place_label(draw, font, p.label, px, placed, view.size)
        draw.text(box[:2], p.label, fill=colour, font=font)
        placed.append(box)
    img.paste(layer, (x0, 0))


def _place_label(draw, font, text: str, px: np.ndarray, placed: list, size: int) -> tuple:
    """The first candidate box for `text` (centre of the body, then above, below, right, left
    of its outline, then further out) that overlaps no label placed before; the centre if
    none is free. Returns (x, y, x1, y1)."""
    l, t, r, b = draw.textbbox((0, 0), text, font=font)
    w, h = r - l + 2, b - t + 2
    cx, cy = px.mean(axis=0)
    x0, y0 = px.min(axis=0)
    x1, y1 = px.max(axis=0)
    candidates = [(cx - w / 2, cy - h / 2), (cx - w / 2, y0 - h - 1), (cx - w / 2, y1 + 1),
                  (x1 + 2, cy - h / 2), (x0 - w - 2, cy - h / 2)]
    for k in range(1, 4):
        candidates += [(cx - w / 2, y0 - (k + 1) * h), (cx - w / 2, y1 + k * h), (x1 + 2 + k * w / 2, cy - h / 2)]
    for x, y in candidates:
        box = (x, y, x + w, y + h)
        inside = 0 <= box[0] and box[2] <= size and 0 <= box[1] and box[3] <= size + 20
        if inside and not any(_overlap(box, o) for o in placed):
            return box
    x, y = candidates[0]
    return (x, y, x + w, y + h)


def _overlap(a: tuple, b: tuple) -> bool:
    return a[0] < b[2] and b[0] < a[2] and a[1] < b[3] and b[1] < a[3]


def _draw_motion(img, x0, view: _View, ghosts: list[list[_Poly]], path_points: dict[str, np.ndarray]):
    """Faint outlines of the bodies at intermediate waypoints and the swept path of each moving
    body's centre, under the keyframe's bodies."""
    from PIL import ImageDraw
    layer = img.crop((x0, 0, x0 + view.size, view.size + 20))
    draw = ImageDraw.Draw(layer, "RGBA")
    for polys in ghosts:
        for p in polys:
            hull = _hull_poly(view.px(p.verts))
            if len(hull) >= 3:
                draw.polygon(hull, outline=p.color[:3] + (70,))
    for name, pts in path_points.items():
        if len(pts) < 2:
            continue
        xy = [tuple(map(float, q)) for q in view.px(pts)]
        draw.line(xy, fill=(200, 30, 120, 220), width=2)
        r = 2
        for q in xy[1:-1]:
            draw.ellipse((q[0] - r, q[1] - r, q[0] + r, q[1] + r), fill=(200, 30, 120, 160))
    img.paste(layer, (x0, 0))


def _moving(polys_seq: list[list[_Poly]]) -> dict[str, np.ndarray]:
    """Centres of the bodies that move along a sequence of states (robot: its last body, the
    hand; objects: themselves)."""
    track: dict[str, list[np.ndarray]] = {}
    for polys in polys_seq:
        last: dict[str, _Poly] = {}
        for p in polys:
            if p.name.endswith("/mobile_base"):
                track.setdefault(p.name, []).append(p.verts.mean(axis=0))
                continue
            last[p.name.split("/", 1)[0] if "/" in p.name else p.name] = p
        for owner, p in last.items():
            track.setdefault(owner, []).append(p.verts.mean(axis=0))
    return {k: np.array(v) for k, v in track.items()
            if len(v) > 1 and np.ptp(np.array(v), axis=0).max() > 1e-3}


def render_keyframes(scene, models, states: list[dict[str, Any]], out_dir: str, size: int = 560,
                     prefix: str = "keyframe", titles: list[str] | None = None,
                     entities: frozenset | set | None = None,
                     motions: list[list[dict[str, Any]]] | None = None,
                     what: str = "--render") -> list[str]:
    """Write one PNG per state (`{prefix}_{i:03d}.png`) into `out_dir`; return their paths.

    `models`: a `GeometryContext`, a dict robot name -> `RobotModel`, or None (load from the scene).
    `states`: dicts entity -> value as in `gnppdsl.geometry.verify` (world poses, joint coords).
    `entities`: draw only these (and static furniture); None: everything in the scene.
    `motions[i]`: states between keyframe i-1 and i (waypoints), drawn as outlines and paths.
    Files are written atomically, never through a symbolic link (`gnppdsl.outputs`); the
    keyframes of an earlier render into the same directory that this one does not rewrite
    are removed (`_forget_old_keyframes`). `what` names the option in error messages.
    """
    from PIL import Image, ImageDraw, ImageFont
    from gnppdsl.geometry.context import GeometryContext
    from gnppdsl.outputs import atomic_open, output_dir

    ctx = models if isinstance(models, GeometryContext) else GeometryContext(scene, models)
    directory = output_dir(out_dir, what)
    keep = None if entities is None else frozenset(entities) | frozenset(
        n for n, o in scene.objects.items() if o.static)
    all_polys = [_polys(ctx, s, keep) for s in states]
    motion_polys = [[_polys(ctx, s, keep) for s in (motions[i] if motions and i < len(motions) else [])]
                    for i in range(len(states))]
    views, movable, statics = _views(scene, all_polys + [ps for seq in motion_polys for ps in seq], size)
    font = ImageFont.load_default()
    paths = []
    for i, polys in enumerate(all_polys):
        img = Image.new("RGBA", (size * len(views), size + 20), (255, 255, 255, 255))
        ghosts = [[p for p in ps if p.layer > 0 or p.name in movable] for ps in motion_polys[i]][::3]
        track = _moving(([all_polys[i - 1]] if i > 0 else []) + motion_polys[i] + [polys]) if motion_polys[i] else {}
        for k, v in enumerate(views):
            if ghosts or track:
                _draw_motion(img, k * size, v, ghosts, track)
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


def _views(scene, polys: list[list[_Poly]], size: int) -> tuple[list[_View], frozenset, frozenset]:
    """The views framing every body drawn in any of the pictures (one scale for all, so they
    compare; the scene workspace is often much larger), and the movable / static object names."""
    every = [p.verts for ps in polys for p in ps]
    pts = np.vstack(every) if every else np.zeros((1, 3))
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    pad = 0.05 * max(hi - lo)
    lo, hi = lo - pad, hi + pad
    views = [_View("top (x right, y up)", 0, 1, 2, lo, hi, size, planar=scene.dimension == 2)]
    if scene.dimension == 3:
        views.append(_View("front (x right, z up)", 0, 2, 1, lo, hi, size))
    movable = frozenset(n for n, o in scene.objects.items() if not o.static)
    statics = frozenset(n for n, o in scene.objects.items() if o.static)
    return views, movable, statics


def front_polys_for_depth(polys: list[_Poly]) -> list[_Poly]:
    """Front view looks along +y, so bodies with smaller y are nearer: flip y for the depth sort
    only (the projection uses x and z, which are unchanged)."""
    return [_Poly(p.name, p.label, p.verts * np.array([1.0, -1.0, 1.0]), p.color, p.layer) for p in polys]


def render_animation(scene, models, frames: list[dict[str, Any]], path: str, size: int = 400,
                     durations: list[float] | None = None, titles: list[str] | None = None,
                     entities: frozenset | set | None = None) -> str:
    """The states `frames` (keyframes and waypoints, in time order) as an animated GIF with the
    views of `render_keyframes`; `durations[k]`: seconds frame k stays (default 0.1)."""
    from PIL import Image, ImageDraw, ImageFont
    from gnppdsl.geometry.context import GeometryContext
    ctx = models if isinstance(models, GeometryContext) else GeometryContext(scene, models)
    keep = None if entities is None else frozenset(entities) | frozenset(
        n for n, o in scene.objects.items() if o.static)
    all_polys = [_polys(ctx, s, keep) for s in frames]
    views, movable, statics = _views(scene, all_polys, size)
    font = ImageFont.load_default()
    images = []
    for k, polys in enumerate(all_polys):
        img = Image.new("RGBA", (size * len(views), size + 20), (255, 255, 255, 255))
        for j, v in enumerate(views):
            _draw_view(img, j * size, v, front_polys_for_depth(polys) if v.v == 2 else polys, font, movable, statics)
        if titles and k < len(titles):
            ImageDraw.Draw(img).text((6, size + 4), titles[k], fill=(0, 0, 0), font=font)
        images.append(img.convert("RGB").convert("P", palette=Image.Palette.ADAPTIVE))
    ms = [int(1000 * (d if d else 0.1)) for d in (durations or [0.1] * len(images))]
    from gnppdsl.outputs import atomic_open

    try:
        os.makedirs(os.path.dirname(path) or ".", exist_ok=True)
    except OSError as e:
        raise UserError(f"cannot write {path}: {e}") from None
    with atomic_open(path, "animation", binary=True) as fh:       # never through a symbolic link
        images[0].save(fh, format="GIF", save_all=True, append_images=images[1:], duration=ms, loop=0)
    return path
