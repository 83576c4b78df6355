"""A solved plan as one self-contained HTML page: a 3-D scene in the browser, animated.

Why meshcat (PyPI `meshcat` 0.3.2): it ships a built three.js viewer (`viewer/dist/main.min.js`,
scene tree, orbit controls, an animation mixer with play / pause / time scrubbing, mesh loaders
for the URDF's Collada / STL / OBJ files) and a Python data model for objects, materials and
animation clips (`meshcat.geometry`, `meshcat.animation`) whose `lower()` gives the commands the
viewer executes. We use both without meshcat's server: the commands go into the page as JSON
and `viewer.handle_command` runs them on load, so the page needs no network, no server and no
other file (viser 1.1 needs its client built from source or served by its Python process;
meshcat's own `static_html` needs a running zmq server). What meshcat has no widget for is
added here in plain DOM: the timeline of the plan's actions, step to previous / next keyframe,
the conflicts learned and a legend. A conflict clicked in the list (or `#conflict=K` in the
page's address) is shown in 3-D: the bodies it names (`conflict_names`: its partial states'
variables and values, its factors' arguments) tinted orange, the other objects faded, and the
final plan's actions on those bodies orange on the timeline; clicking it again restores the
colours (each material cloned once and its colour kept, so the restore is exact).

Size: meshes are inlined once per file (two Pandas share them), gzip-compressed and base64
encoded, and inflated in the browser with `DecompressionStream` (11 MB of Panda Collada files
-> about 2.5 MB of page).
"""
from __future__ import annotations

import base64
import gzip
import html
import json
import re
import uuid
from pathlib import Path
from typing import Any

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.view.samples import Samples, VisualBody, sample_motion

ROOT = "/gnpp"


def _viewer_js() -> str:
    try:
        import meshcat
    except ImportError:
        raise UserError("the viewer needs the `meshcat` package: pip install 'gnppdsl[view]' "
                        "(or pip install meshcat)") from None
    path = Path(meshcat.__file__).parent / "viewer" / "dist" / "main.min.js"
    if not path.is_file():
        raise UserError(f"meshcat's viewer bundle is missing: {path}")
    return path.read_text()


def _col(m: np.ndarray) -> list[float]:
    """A 4x4 as three.js wants it (column-major)."""
    return [float(x) for x in np.asarray(m, float).T.flatten()]


def _hex(color) -> int:
    r, g, b = (int(round(255 * max(0.0, min(1.0, c)))) for c in color[:3])
    return (r << 16) + (g << 8) + b


def _rot_x90() -> np.ndarray:
    """three.js cylinders are along y; ours along z."""
    return np.array([[1, 0, 0, 0], [0, 0, -1, 0], [0, 1, 0, 0], [0, 0, 0, 1]], float)


class _Meshes:
    """Each mesh file once: gzip + base64 text, referenced by index from the commands."""

    def __init__(self) -> None:
        self.files: list[str] = []
        self.blobs: list[dict[str, str]] = []

    def ref(self, path: str) -> int:
        if path not in self.files:
            raw = Path(path).read_bytes()
            fmt = Path(path).suffix.lower().lstrip(".")
            self.files.append(path)
            self.blobs.append({"format": fmt, "gz": base64.b64encode(gzip.compress(raw, 9)).decode()})
        return self.files.index(path)


def _object(b: VisualBody, meshes: _Meshes) -> dict[str, Any]:
    """The meshcat `set_object` payload of one body (three.js JSON, meshcat's extensions)."""
    import meshcat.geometry as mg

    color = b.color or (0.7, 0.7, 0.7, 1.0)
    material = mg.MeshPhongMaterial(color=_hex(color), transparent=color[3] < 1.0, opacity=float(color[3]))
    if b.kind == "mesh":
        idx = meshes.ref(b.mesh_file)
        scale = np.diag([*b.scale, 1.0])
        if b.color is None:        # the Collada file's own materials (the URDF's look)
            return {"metadata": {"version": 4.5, "type": "Object"}, "geometries": [], "materials": [],
                    "object": {"uuid": str(uuid.uuid1()), "type": "_meshfile_object",
                               "format": meshes.blobs[idx]["format"], "data": {"$mesh": idx},
                               "resources": {}, "matrix": _col(scale)}}
        geom = {"uuid": str(uuid.uuid1()), "type": "_meshfile_geometry",
                "format": meshes.blobs[idx]["format"], "data": {"$mesh": idx}}
        obj = mg.Mesh(mg.Box([1, 1, 1]), material).lower()
        obj["geometries"] = [geom]
        obj["object"]["geometry"] = geom["uuid"]
        obj["object"]["matrix"] = _col(scale)
        return obj
    if b.kind == "box":
        obj = mg.Mesh(mg.Box(list(b.size[:3]) if len(b.size) >= 3 else [*b.size[:2], 0.01]), material).lower()
    elif b.kind == "sphere":
        obj = mg.Mesh(mg.Sphere(b.size[0]), material).lower()
    elif b.kind == "cylinder":
        obj = mg.Mesh(mg.Cylinder(b.size[1], b.size[0]), material).lower()
        obj["object"]["matrix"] = _col(_rot_x90())
    else:
        raise UserError(f"{b.owner}: cannot draw a {b.kind}")
    return obj


def _label(text: str, size: float) -> dict[str, Any]:
    """A text sprite (meshcat's `_text` canvas texture on a three.js Sprite: always faces the camera)."""
    tex, mat, obj = (str(uuid.uuid1()) for _ in range(3))
    scale = np.diag([size, size, size, 1.0])
    return {"metadata": {"version": 4.5, "type": "Object"},
            "textures": [{"uuid": tex, "type": "_text", "text": text, "font_size": 56,
                          "font_face": "sans-serif"}],
            "images": [], "geometries": [],
            "materials": [{"uuid": mat, "type": "SpriteMaterial", "map": tex, "transparent": True,
                           "depthTest": False}],
            "object": {"uuid": obj, "type": "Sprite", "material": mat, "matrix": _col(scale)}}


def _commands(samples: Samples, result: dict[str, Any], scene: Any, meshes: _Meshes) -> list[dict]:
    import meshcat.animation as ma
    from meshcat.commands import SetAnimation
    from meshcat.path import Path as MPath

    cmds: list[dict] = []
    anim = ma.Animation(default_framerate=1)          # frame numbers are seconds
    extent = np.array([b[:3, 3] for ps in samples.placements.values() for b in ps])
    span = float(np.ptp(extent, axis=0).max()) if len(extent) else 1.0
    labelled: set[str] = set()
    for b in samples.bodies:
        path = f"{ROOT}/{b.path}"
        cmds.append({"type": "set_object", "path": path, "object": _object(b, meshes)})
        placements = samples.placements.get(b.path, [])
        if not placements:
            continue
        if b.static or len(placements) == 1:
            cmds.append({"type": "set_transform", "path": path, "matrix": _col(placements[0])})
        else:
            cmds.append({"type": "set_transform", "path": path, "matrix": _col(placements[0])})
            mpath = MPath(tuple(p for p in path.split("/") if p))
            for t, T in zip(samples.times, placements):
                anim.at_frame(_Vis(mpath), t).set_transform(T)
        if b.owner not in labelled:       # the owner's first body: an object, a robot's root link
            labelled.add(b.owner)
            offset = np.eye(4)
            offset[2, 3] = 0.05 if samples.planar else 0.12
            if b.path.startswith("robots/") and not samples.planar:
                offset[2, 3] = -0.05      # under the arm's base, on the table edge
            cmds.append({"type": "set_object", "path": f"{path}/label", "object": _label(b.owner, min(max(0.12 * span, 0.1), 0.6))})
            cmds.append({"type": "set_transform", "path": f"{path}/label", "matrix": _col(offset)})
    low = SetAnimation(anim, play=True, repetitions=1).lower()
    cmds.append(low)
    return cmds


class _Vis:
    """The minimum of `meshcat.Visualizer` that `Animation.at_frame` reads (its `path`)."""

    def __init__(self, path) -> None:
        self.path = path


_NAME = re.compile(r"[A-Za-z_]\w*")


def conflict_names(conflict: dict[str, Any]) -> set[str]:
    """Every name a learned conflict mentions: the variables and values of its partial states
    (`parent(b1) = target`) and the arguments of its factors (`apart(a=b1, b=b2) -> ...`); the
    viewer keeps those that are bodies of the scene (objects, robots)."""
    names: set[str] = set()
    for state in conflict.get("named", []):
        for var, value in state:
            names.update(_NAME.findall(f"{var} {value}"))
    for f in conflict.get("factors", []):
        names.update(re.findall(r"=\s*([A-Za-z_]\w*)", f.partition("->")[0]))
    return names


def page_data(result: dict[str, Any], samples: Samples) -> dict[str, Any]:
    """What the page's own widgets show: actions on the time axis, keyframes, conflicts."""
    steps = result["steps"]
    actions = [{"name": st["action"], "start": steps[i - 1]["time"], "end": st["time"]}
               for i, st in enumerate(steps) if i > 0]
    owners: dict[str, list[str]] = {}
    for b in samples.bodies:
        owners.setdefault(b.owner, []).append(f"{ROOT}/{b.path}")
    plan_args = [set(_NAME.findall(a.partition("(")[2])) for a in result["plan"]]
    conflicts = []
    for c in result.get("conflicts", []):
        names = sorted(conflict_names(c) & set(owners))
        conflicts.append({"text": c["text"], "source": c["source"], "relaxation": c.get("relaxation", ""),
                          "plan": c.get("plan_index", 0), "at": c.get("at_step", 0), "objects": names,
                          "paths": [p for n in names for p in owners[n]],
                          "actions": [i for i, args in enumerate(plan_args) if args & set(names)]})
    extent = np.array([b[:3, 3] for ps in samples.placements.values() for b in ps]) if samples.placements \
        else np.zeros((1, 3))
    lo, hi = extent.min(axis=0), extent.max(axis=0)
    s = result.get("stats", {})
    title = (f"{result['problem']} ({result['domain']}) &middot; {html.escape(str(result.get('algorithm_name', '')))} "
             f"&middot; {len(result['plan'])} actions, {s.get('plans', '?')} plans tried, "
             f"{s.get('conflicts', '?')} conflicts, {s.get('nlp_solves', '?')} NLPs")
    legend = []
    for b in samples.bodies:
        if b.path.startswith("objects/") and not b.static:
            legend.append({"name": b.owner, "color": "#%06x" % _hex(b.color or (0.7, 0.7, 0.7))})
    scene_objects = [p for b in samples.bodies if b.path.startswith("objects/") for p in [f"{ROOT}/{b.path}"]]
    return {"title": title, "actions": actions, "keyframes": samples.keyframe_times, "objects": scene_objects,
            "duration": samples.times[-1] if samples.times else 0.0, "conflicts": conflicts,
            "lo": lo.tolist(), "hi": hi.tolist(), "planar": samples.planar, "legend": legend}


def render_page(result: dict[str, Any], compiled: Any) -> str:
    """The HTML text of the viewer for a solved, annotated result (JSON dict)."""
    samples = sample_motion(result, compiled)
    meshes = _Meshes()
    cmds = _commands(samples, result, compiled.problem.scene, meshes)
    data = page_data(result, samples)
    js = _viewer_js()
    return _TEMPLATE.format(
        title=html.escape(result["problem"]),
        viewer_js=js.replace("</script", "<\\/script"),
        meshes=json.dumps(meshes.blobs),
        commands=json.dumps(cmds).replace("</", "<\\/"),
        data=json.dumps(data).replace("</", "<\\/"),
    )


def write_html(result: dict[str, Any], compiled: Any, path: str | Path) -> Path:
    """Write the page (`gnppdsl.outputs.write_atomic`: never through a symbolic link, never half
    written; its directory created) and return its path."""
    from gnppdsl.outputs import write_atomic

    p = Path(path)
    p.parent.mkdir(parents=True, exist_ok=True)
    return write_atomic(p, render_page(result, compiled), "--html")


_TEMPLATE = """<!DOCTYPE html>
<html lang="en">
<head>
<meta charset="utf-8">
<title>gnpp view: {title}</title>
<style>
  body {{ margin: 0; font: 13px sans-serif; overflow: hidden; }}
  #meshcat-pane {{ width: 100vw; height: 100vh; overflow: hidden; }}
  #gnpp-title {{ position: fixed; top: 8px; left: 10px; background: rgba(255,255,255,.85); padding: 4px 8px; border-radius: 4px; }}
  #gnpp-side {{ position: fixed; top: 40px; left: 10px; max-width: 32vw; max-height: 60vh; overflow: auto;
               background: rgba(255,255,255,.85); padding: 4px 8px; border-radius: 4px; }}
  #gnpp-side h3 {{ margin: 4px 0; font-size: 13px; }}
  #gnpp-side li {{ font-family: monospace; font-size: 11px; margin: 2px 0; }}
  .gnpp-swatch {{ display: inline-block; width: 10px; height: 10px; margin-right: 4px; border: 1px solid #444; }}
  #gnpp-bar {{ position: fixed; left: 0; right: 0; bottom: 0; background: rgba(255,255,255,.92); padding: 6px 10px; }}
  #gnpp-buttons button {{ font-size: 14px; min-width: 34px; }}
  #gnpp-track {{ position: relative; height: 34px; margin-top: 6px; background: #eee; cursor: pointer; }}
  .gnpp-act {{ position: absolute; top: 0; bottom: 0; border-right: 1px solid #fff; overflow: hidden;
              white-space: nowrap; font-size: 11px; padding: 2px 3px; box-sizing: border-box; background: #c9d7f0; }}
  .gnpp-act.now {{ background: #7fa3e0; color: #fff; }}
  .gnpp-act.conflict {{ background: #f0a040; }}
  .gnpp-act.conflict.now {{ background: #d06a00; }}
  #gnpp-side li.gnpp-conflict {{ cursor: pointer; }}
  #gnpp-side li.gnpp-conflict.sel {{ background: #f0a040; }}
  #gnpp-cursor {{ position: absolute; top: -3px; bottom: -3px; width: 2px; background: #d22; }}
</style>
</head>
<body>
<div id="meshcat-pane"></div>
<div id="gnpp-title"></div>
<div id="gnpp-side"></div>
<div id="gnpp-bar">
  <span id="gnpp-buttons">
    <button id="gnpp-prev" title="previous keyframe (left arrow)">|&#x25C0;</button>
    <button id="gnpp-play" title="play / pause (space)">&#x25B6;</button>
    <button id="gnpp-next" title="next keyframe (right arrow)">&#x25B6;|</button>
  </span>
  <span id="gnpp-time"></span> &middot; <span id="gnpp-action"></span>
  <div id="gnpp-track"><div id="gnpp-cursor"></div></div>
</div>
<script>{viewer_js}</script>
<script>
const GNPP_MESHES = {meshes};
const GNPP_COMMANDS = {commands};
const GNPP = {data};
var viewer = new MeshCat.Viewer(document.getElementById("meshcat-pane"));

async function gnppInflate(b64) {{
  const bytes = Uint8Array.from(atob(b64), c => c.charCodeAt(0));
  const stream = new Blob([bytes]).stream().pipeThrough(new DecompressionStream("gzip"));
  return new Uint8Array(await new Response(stream).arrayBuffer());
}}

function gnppSubstitute(node, meshes) {{
  if (Array.isArray(node)) {{ return node.map(x => gnppSubstitute(x, meshes)); }}
  if (node !== null && typeof node === "object") {{
    if (node["$mesh"] !== undefined) {{ return meshes[node["$mesh"]]; }}
    const out = {{}};
    for (const k in node) {{ out[k] = gnppSubstitute(node[k], meshes); }}
    return out;
  }}
  return node;
}}

function gnppNow() {{
  const a = viewer.animator.actions;
  return a.length ? a[0].time : 0;
}}
function gnppSeek(t) {{
  viewer.animator.pause();
  viewer.animator.seek(t);
  viewer.animator.display_progress(t);
  gnppShow();
}}
function gnppStep(dir) {{
  const now = gnppNow(), eps = 1e-6;
  const ks = GNPP.keyframes;
  let t = dir > 0 ? ks.find(k => k > now + eps) : [...ks].reverse().find(k => k < now - eps);
  if (t === undefined) {{ t = dir > 0 ? GNPP.duration : 0; }}
  gnppSeek(t);
}}
function gnppToggle() {{
  const an = viewer.animator;
  if (an.playing) {{ an.pause(); }}
  else {{
    if (gnppNow() >= GNPP.duration - 1e-6) {{ an.reset(); }}
    an.play();
  }}
}}
function gnppShow() {{
  const t = gnppNow(), d = Math.max(GNPP.duration, 1e-9);
  document.getElementById("gnpp-cursor").style.left = (100 * t / d) + "%";
  document.getElementById("gnpp-time").textContent = t.toFixed(2) + " / " + GNPP.duration.toFixed(2) + " s";
  let label = "initial state";
  document.querySelectorAll(".gnpp-act").forEach((el, i) => {{
    const a = GNPP.actions[i];
    const on = t >= a.start - 1e-9 && t <= a.end + 1e-9 && (t < a.end - 1e-9 || i === GNPP.actions.length - 1);
    el.classList.toggle("now", on);
    if (on) {{ label = (i + 1) + ". " + a.name; }}
  }});
  document.getElementById("gnpp-action").textContent = label;
  document.getElementById("gnpp-play").innerHTML = viewer.animator.playing ? "||" : "&#x25B6;";
}}

// a learned conflict selected: its bodies tinted orange in the scene, the other objects faded,
// the plan's actions on those bodies orange on the timeline; -1 restores the scene's colours
GNPP.selected = -1;
function gnppTint(path, mode) {{
  const node = viewer.scene_tree.find(path.split("/").filter(p => p.length > 0));
  node.object.traverse(o => {{
    if (!o.material || Array.isArray(o.material)) {{ return; }}
    if (!o.userData.gnppOrig) {{
      o.material = o.material.clone();        // meshes may share a material with another body
      o.userData.gnppOrig = {{color: o.material.color ? o.material.color.clone() : null,
                              opacity: o.material.opacity, transparent: o.material.transparent}};
    }}
    const g = o.userData.gnppOrig, m = o.material;
    if (g.color) {{ m.color.copy(g.color); }}
    m.opacity = g.opacity; m.transparent = g.transparent;
    if (mode === "hot" && m.color) {{ m.color.setRGB(1.0, 0.55, 0.0); }}
    else if (mode === "faded") {{ m.opacity = 0.2; m.transparent = true; }}
    m.needsUpdate = true;
  }});
}}
function gnppSelect(k) {{
  GNPP.selected = k;
  const c = k >= 0 ? GNPP.conflicts[k] : null;
  const hot = new Set(c ? c.paths : []);
  for (const p of GNPP.objects) {{ gnppTint(p, hot.has(p) ? "hot" : (c ? "faded" : "normal")); }}
  for (const p of hot) {{ if (!GNPP.objects.includes(p)) {{ gnppTint(p, "hot"); }} }}
  if (!c) {{ for (const x of GNPP.conflicts) {{ for (const p of x.paths) {{ gnppTint(p, "normal"); }} }} }}
  document.querySelectorAll(".gnpp-act").forEach((el, i) => el.classList.toggle("conflict", !!c && c.actions.includes(i)));
  document.querySelectorAll("li.gnpp-conflict").forEach(li => li.classList.toggle("sel", +li.dataset.k === k));
  viewer.set_dirty();
}}

function gnppWidgets() {{
  document.getElementById("gnpp-title").innerHTML = GNPP.title;
  const side = document.getElementById("gnpp-side");
  let h = "<h3>objects</h3>" + GNPP.legend.map(o =>
    `<span class="gnpp-swatch" style="background:${{o.color}}"></span>${{o.name}}`).join(" &nbsp; ");
  h += `<h3>conflicts learned (${{GNPP.conflicts.length}})</h3><ol>`;
  GNPP.conflicts.forEach((c, k) => {{
    const where = c.relaxation ? " [" + c.relaxation + "]" : "";
    h += `<li class="gnpp-conflict" data-k="${{k}}" title="plan ${{c.plan}}, step ${{c.at}}; click: show ${{c.objects.join(", ")}}">` +
         `#${{c.plan}} ${{c.source}}${{where}}: ${{c.text.replace(/</g, "&lt;")}}</li>`;
  }});
  side.innerHTML = h + "</ol>";
  side.querySelectorAll("li.gnpp-conflict").forEach(li => {{
    li.onclick = () => gnppSelect(+li.dataset.k === GNPP.selected ? -1 : +li.dataset.k);
  }});
  const track = document.getElementById("gnpp-track");
  const d = Math.max(GNPP.duration, 1e-9);
  GNPP.actions.forEach((a, i) => {{
    const el = document.createElement("div");
    el.className = "gnpp-act";
    el.style.left = (100 * a.start / d) + "%";
    el.style.width = (100 * (a.end - a.start) / d) + "%";
    el.textContent = (i + 1) + ". " + a.name;
    el.title = el.textContent;
    track.appendChild(el);
  }});
  track.addEventListener("click", ev => {{
    const r = track.getBoundingClientRect();
    gnppSeek(d * (ev.clientX - r.left) / r.width);
  }});
  document.getElementById("gnpp-prev").onclick = () => gnppStep(-1);
  document.getElementById("gnpp-next").onclick = () => gnppStep(1);
  document.getElementById("gnpp-play").onclick = gnppToggle;
  document.addEventListener("keydown", ev => {{
    if (ev.key === " ") {{ gnppToggle(); ev.preventDefault(); }}
    else if (ev.key === "ArrowRight") {{ gnppStep(1); }}
    else if (ev.key === "ArrowLeft") {{ gnppStep(-1); }}
  }});
  (function loop() {{ gnppShow(); requestAnimationFrame(loop); }})();
}}

function gnppCamera() {{
  // world z up; meshcat's camera lives in a frame rotated by +90 deg about x: (x, y, z) -> (x, z, -y)
  const lo = GNPP.lo, hi = GNPP.hi;
  const c = [0, 1, 2].map(k => (lo[k] + hi[k]) / 2);
  const span = Math.max(hi[0] - lo[0], hi[1] - lo[1], hi[2] - lo[2], 0.2);
  const eye = GNPP.planar ? [c[0], c[1] - 0.02 * span, c[2] + 1.3 * span]
                          : [c[0] + 0.1 * span, c[1] - 1.0 * span, c[2] + 0.6 * span];
  viewer.camera.position.set(eye[0], eye[2], -eye[1]);
  viewer.controls.target.set(c[0], c[2], -c[1]);
  viewer.controls.update();
  viewer.set_dirty();
}}

(async function () {{
  const meshes = [];
  for (const m of GNPP_MESHES) {{
    const bytes = await gnppInflate(m.gz);
    meshes.push(m.format === "stl" ? bytes : new TextDecoder().decode(bytes));
  }}
  for (const cmd of GNPP_COMMANDS) {{
    viewer.handle_command(gnppSubstitute(cmd, meshes));
  }}
  viewer.animator.pause();
  gnppCamera();
  gnppWidgets();
  const m = /t=([0-9.]+)/.exec(location.hash);
  gnppSeek(m ? parseFloat(m[1]) : 0);
  const sel = /conflict=([0-9]+)/.exec(location.hash);      // #t=2&conflict=0: a conflict shown
  if (sel && +sel[1] < GNPP.conflicts.length) {{ gnppSelect(+sel[1]); }}
  document.title = document.title + " (ready)";
}})();
</script>
</body>
</html>
"""
