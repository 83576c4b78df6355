"""Load and validate a scene YAML file into `gnppdsl.ir.scene_model.Scene` (schema: docs/scene.md).

Why validate here, by hand, on YAML *nodes*: every mistake must be reported at the file:line:col
of the offending key or value (nodes carry marks; plain dicts do not), unknown keys get a
did-you-mean, and all poses are resolved to the world frame once (`parent:` chains), so the
factory, the geometry layer and the renderer never re-read YAML. Only `yaml` and `math` are
imported: `gnpp check` stays fast.
"""
from __future__ import annotations

import functools

import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from gnppdsl.inputs import ROBOT_SUFFIXES
from gnppdsl.ir.expr import Span
from gnppdsl.ir.instances import range_error
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape
from gnppdsl.lang.diagnostics import Reporter, did_you_mean, read_source

TOP_KEYS = ("include", "name", "dimension", "workspace", "robots", "objects", "ignore_collisions")
ROBOT_KEYS = ("kind", "model", "urdf", "srdf", "package_dirs", "base", "base_joint", "ee", "locked",
              "links", "home", "held_pose", "shape", "color")
BASE_JOINTS = ("fixed", "planar", "free")
OBJECT_KEYS = ("shape", "size", "pose", "static", "color", "parent", "file", "scale")
SHAPES = ("box", "cylinder", "sphere", "circle", "mesh")

COLORS: dict[str, tuple[float, float, float, float]] = {
    "red": (0.85, 0.15, 0.15, 1.0), "green": (0.2, 0.7, 0.25, 1.0), "blue": (0.2, 0.35, 0.85, 1.0),
    "yellow": (0.95, 0.85, 0.2, 1.0), "orange": (0.95, 0.55, 0.1, 1.0), "purple": (0.55, 0.3, 0.75, 1.0),
    "cyan": (0.2, 0.8, 0.85, 1.0), "magenta": (0.85, 0.2, 0.75, 1.0), "pink": (0.95, 0.6, 0.7, 1.0),
    "brown": (0.55, 0.35, 0.2, 1.0), "grey": (0.6, 0.6, 0.6, 1.0), "gray": (0.6, 0.6, 0.6, 1.0),
    "black": (0.1, 0.1, 0.1, 1.0), "white": (0.95, 0.95, 0.95, 1.0), "wood": (0.7, 0.5, 0.3, 1.0),
}

IDENTITY = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)


class _Bad(Exception):
    """Raised after a diagnostic has been reported, to skip the rest of an entry."""


@dataclass
class _Part:
    """The entries of one scene file and of everything it includes, before pose resolution."""

    loaders: list = field(default_factory=list)     # the _Loader of each file (diagnostics)
    name: str | None = None
    dim: int | None = None
    workspace: tuple | None = None
    robots: dict = field(default_factory=dict)
    raw: dict = field(default_factory=dict)         # object name -> entry (see `_Loader.obj`)
    where: dict = field(default_factory=dict)       # name -> "file:line:col" of its definition
    ignore: list = field(default_factory=list)      # (loader, pair node)


# ----------------------------------------------------------------------------------------
# pose math (pure python; quaternions [qx, qy, qz, qw])
# ----------------------------------------------------------------------------------------
def quat_from_rpy(r: float, p: float, y: float) -> tuple[float, float, float, float]:
    """R = Rz(y) Ry(p) Rx(r) (URDF convention)."""
    cr, sr = math.cos(r / 2), math.sin(r / 2)
    cp, sp = math.cos(p / 2), math.sin(p / 2)
    cy, sy = math.cos(y / 2), math.sin(y / 2)
    return (sr * cp * cy - cr * sp * sy, cr * sp * cy + sr * cp * sy,
            cr * cp * sy - sr * sp * cy, cr * cp * cy + sr * sp * sy)


def quat_mul(a, b):
    ax, ay, az, aw = a
    bx, by, bz, bw = b
    return (aw * bx + ax * bw + ay * bz - az * by, aw * by - ax * bz + ay * bw + az * bx,
            aw * bz + ax * by - ay * bx + az * bw, aw * bw - ax * bx - ay * by - az * bz)


def quat_rotate(q, v):
    x, y, z = quat_mul(quat_mul(q, (v[0], v[1], v[2], 0.0)), (-q[0], -q[1], -q[2], q[3]))[:3]
    return (x, y, z)


def compose(a, b):
    """SE3 a * b, poses as [x, y, z, qx, qy, qz, qw]."""
    t = quat_rotate(a[3:], b[:3])
    q = quat_mul(a[3:], b[3:])
    n = math.sqrt(sum(c * c for c in q)) or 1.0
    return (a[0] + t[0], a[1] + t[1], a[2] + t[2]) + tuple(c / n for c in q)


def se2_to_se3(p) -> tuple[float, ...]:
    x, y, th = p
    return (x, y, 0.0, 0.0, 0.0, math.sin(th / 2), math.cos(th / 2))


def compose_se2(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    th = a[2] + b[2]
    th = math.atan2(math.sin(th), math.cos(th))
    return (a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], th)


def _finite(v) -> bool:
    try:
        return math.isfinite(float(v))
    except OverflowError:               # a 400-digit YAML integer
        return False


def _looks_numeric(text: str) -> bool:
    """A YAML string a user meant as a number (`1e300`, which YAML 1.1 reads as text)."""
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def _short(text: str, n: int = 80) -> str:
    """A path as quoted in a message (a 10,000-character name is cut)."""
    return text if len(text) <= n else f"{text[:n]}... ({len(text):,} characters)"


@functools.lru_cache(maxsize=32)
def _urdf_names(urdf: str) -> tuple | None:
    """(links with collision geometry, joints that move, (name, type) of each joint that moves,
    every link and joint name: the frames of pinocchio's model) of a URDF file, from its XML."""
    import xml.etree.ElementTree as ET

    from gnppdsl.inputs import ROBOT_SUFFIXES, InputError, read_text

    try:                   # through `inputs`: a FIFO or an oversized file is refused, not read
        root = ET.fromstring(read_text(urdf, ROBOT_SUFFIXES, "robot model"))
    except (InputError, ET.ParseError):
        return None        # load_robot reports an unreadable URDF
    # the robot's own <joint>s and <link>s only: a <transmission> or <gazebo> block names joints
    # too (the PR2's caster wheels), which pinocchio's model does not have
    moving = tuple((j.get("name"), j.get("type")) for j in root.findall("joint") if j.get("type") != "fixed")
    return (frozenset(ln.get("name") for ln in root.findall("link") if ln.find("collision") is not None),
            frozenset(n for n, _ in moving), moving,
            frozenset(x.get("name") for x in root.findall("link") + root.findall("joint")))


def _urdf_of(model: str | None, urdf: str | None):
    if urdf is None and model is not None:
        from gnppdsl.errors import UserError
        from gnppdsl.ir.robot_files import resolve_model_files

        try:
            urdf = resolve_model_files(model)[0]
        except UserError:
            return None
    return _urdf_names(urdf) if urdf else None


def urdf_collision_links(model: str | None, urdf: str | None) -> frozenset[str] | None:
    """The links of a robot's URDF that have collision geometry, read from the XML (None when
    the file cannot be found or read: loading the robot reports that)."""
    names = _urdf_of(model, urdf)
    return None if names is None else names[0]


def urdf_frames(model: str | None, urdf: str | None) -> frozenset[str] | None:
    """Every frame `fk(r, q, NAME)` may name: the URDF's links and joints (pinocchio makes a
    frame of each), read from the XML."""
    names = _urdf_of(model, urdf)
    return None if names is None else names[3]


def urdf_joints(model: str | None, urdf: str | None) -> frozenset[str] | None:
    """The joints of a robot's URDF that move (not `fixed`): what `locked:` may name."""
    names = _urdf_of(model, urdf)
    return None if names is None else names[1]


# coordinates of a configuration per URDF joint type (a continuous joint is one angle, as the
# geometry layer's JointCoord keeps it) and per scene `base_joint`
_JOINT_COORDS = {"revolute": 1, "continuous": 1, "prismatic": 1, "planar": 3, "floating": 7}
_BASE_COORDS = {"fixed": 0, "planar": 3, "free": 7}


def configuration_size(model: str | None, urdf: str | None, base_joint: str | None,
                       locked: dict[str, float]) -> tuple[int, str] | None:
    """How many numbers a robot's configuration (and so its `home`) has, with a description of
    where they come from; None when the URDF cannot be read (loading the robot reports that).

    Counted from the URDF's text, as `links:` and `locked:` are checked, so that `gnpp check`
    finds a `home` of the wrong length without pinocchio (the solve met it as an unlocated
    "constraint sides have lengths 10 and 9")."""
    from gnppdsl.ir.robot_files import default_locked

    names = _urdf_of(model, urdf)
    if names is None:
        return None
    locked = locked or default_locked(model)
    free = [(n, t) for n, t in names[2] if n not in locked]
    joints = sum(_JOINT_COORDS.get(t, 1) for _, t in free)
    base = _BASE_COORDS.get(base_joint or "fixed", 0)
    parts = ([f"{base_joint} base {base}"] if base else []) + [f"{len(free)} joints that move"]
    if locked:
        parts.append(f"{len(locked)} locked")
    return base + joints, ", ".join(parts)


# ----------------------------------------------------------------------------------------
# the loader
# ----------------------------------------------------------------------------------------
class _Loader:
    def __init__(self, path: str, reporter: Reporter) -> None:
        self.path = path
        self.dir = Path(path).parent
        self.r = reporter
        self.ok = True
        self.attr_spans: dict[tuple[str, str], Span] = {}

    # ---- diagnostics
    def span(self, node) -> Span:
        s, e = node.start_mark, node.end_mark
        return Span(self.path, s.line + 1, s.column + 1, e.line + 1 if e else None,
                    e.column + 1 if e else None)

    def error(self, node, msg: str, kind: str = "scene", hint: str | None = None) -> None:
        self.ok = False
        self.r.error(self.span(node) if node is not None else Span(self.path, 1, 1), msg, kind, hint)

    def fail(self, node, msg: str, kind: str = "scene", hint: str | None = None):
        self.error(node, msg, kind, hint)
        raise _Bad

    # ---- node helpers
    def mapping(self, node, what: str) -> dict[str, tuple[Any, Any]]:
        """{key: (key_node, value_node)}; duplicate keys are errors."""
        import yaml

        if not isinstance(node, yaml.MappingNode):
            self.fail(node, f"{what} must be a mapping (`key: value` lines or {{...}})")
        out: dict[str, tuple[Any, Any]] = {}
        for k, v in node.value:
            if not isinstance(k, yaml.ScalarNode):
                self.error(k, "keys must be plain names")
                continue
            if k.value in out:
                self.error(k, f"'{k.value}' appears twice in {what}", "duplicate")
                continue
            out[k.value] = (k, v)
        return out

    def scalar(self, node):
        import yaml

        if not isinstance(node, yaml.ScalarNode):
            return None
        from yaml.constructor import SafeConstructor

        try:
            return SafeConstructor().construct_object(node)
        except Exception:  # noqa: BLE001 - malformed scalar (bad timestamp etc.)
            return node.value

    def number(self, node, what: str) -> float:
        v = self.scalar(node)
        if isinstance(v, bool) or not isinstance(v, (int, float)):
            self.fail(node, f"{what} must be a number")
        if not _finite(v):
            self.fail(node, f"{what} must be a finite number, not {node.value[:24]}", "number",
                      "NaN and infinity have no place in a scene")
        return float(v)

    def numbers(self, node, what: str, n: int | tuple[int, ...] | None = None) -> tuple[float, ...]:
        import yaml

        if not isinstance(node, yaml.SequenceNode):
            self.fail(node, f"{what} must be a list of numbers" + (f" ({n} of them)" if isinstance(n, int) else ""))
        vals = tuple(self.number(x, f"each item of {what}") for x in node.value)
        ns = (n,) if isinstance(n, int) else n
        if ns is not None and len(vals) not in ns:
            self.fail(node, f"{what} must have {' or '.join(map(str, ns))} numbers, got {len(vals)}")
        return vals

    def string(self, node, what: str) -> str:
        v = self.scalar(node)
        if not isinstance(v, str) or not v:
            self.fail(node, f"{what} must be a name or a path")
        return v

    def boolean(self, node, what: str) -> bool:
        v = self.scalar(node)
        if not isinstance(v, bool):
            self.fail(node, f"{what} must be true or false")
        return v

    def file(self, node, what: str, suffixes: tuple[str, ...] | None = None, directory: bool = False) -> str:
        """A path named by the scene, relative to the scene file: a regular file (or a
        directory) that exists, with one of `suffixes` if given; never opened here, so a
        wrong path is refused without reading it (`gnppdsl.inputs`)."""
        import os
        import stat as st

        from gnppdsl.inputs import MAX_INPUT_BYTES, describe_os_error

        rel = self.string(node, what)
        if suffixes is not None and Path(rel).suffix.lower() not in suffixes:
            self.fail(node, f"{what} must be a {' or '.join(suffixes)} file", "bad-file")
        try:
            p = (self.dir / rel).resolve()
            mode = os.stat(p)
        except (OSError, ValueError, RuntimeError) as exc:
            reason = describe_os_error(exc) if not isinstance(exc, RuntimeError) else "a symbolic link loop"
            if reason == "no such file":
                self.fail(node, f"{what} not found: {_short(rel)}", "missing-file",
                          f"paths are relative to {self.dir}")
            self.fail(node, f"{what} {_short(rel)}: {reason}", "bad-file")
        if directory and not st.S_ISDIR(mode.st_mode):
            self.fail(node, f"{what} {_short(rel)} is not a directory", "bad-file")
        if not directory and not st.S_ISREG(mode.st_mode):
            self.fail(node, f"{what} {_short(rel)} is not a regular file", "bad-file",
                      "devices, FIFOs and directories are not read")
        if not directory and suffixes is not None and mode.st_size > MAX_INPUT_BYTES:
            self.fail(node, f"{what} {_short(rel)} is larger than {MAX_INPUT_BYTES:,} bytes", "bad-file")
        return str(p)

    def unknown_key(self, key_node, key: str, known: tuple[str, ...], what: str) -> None:
        self.error(key_node, f"unknown key '{key}' in {what}", "unknown-key",
                   did_you_mean(key, known) or "keys: " + ", ".join(known))

    def extra(self, key_node, key: str, val_node, known: tuple[str, ...], what: str, entity: str) -> Any:
        """An extra attribute: a number or a list of numbers; anything else is an unknown key.
        (Attribute names are checked against the domain's `scene` declarations by the problem
        resolver, using the key positions recorded in `attr_spans`.)"""
        import yaml

        if isinstance(val_node, yaml.SequenceNode):
            try:
                vals = self.numbers(val_node, f"attribute '{key}'")
            except _Bad:
                return None
            self.attr_spans[(entity, key)] = self.span(key_node)
            return vals
        v = self.scalar(val_node)
        if isinstance(v, (int, float)) and not isinstance(v, bool):
            if not _finite(v):
                self.error(val_node, f"attribute '{key}' must be a finite number, not {val_node.value[:24]}",
                           "number", "NaN and infinity have no place in a scene")
                return None
            self.attr_spans[(entity, key)] = self.span(key_node)
            return float(v)
        if isinstance(v, str) and _looks_numeric(v):
            self.error(val_node, f"attribute '{key}' must be a number, but YAML reads {v!r} as text",
                       "number", "YAML 1.1 needs a dot in an exponent number: write 1.0e300")
            return None
        self.unknown_key(key_node, key, known, what)
        return None

    # ---- values
    def color(self, node) -> tuple[float, float, float, float]:
        import yaml

        if isinstance(node, yaml.SequenceNode):
            c = self.numbers(node, "a color", (3, 4))
            if any(not 0 <= x <= 1 for x in c):
                self.fail(node, "color components are between 0 and 1")
            return tuple(c) + ((1.0,) if len(c) == 3 else ())
        name = self.scalar(node)
        if not isinstance(name, str) or name not in COLORS:
            self.fail(node, f"unknown color '{name}'", "scene",
                      did_you_mean(str(name), COLORS) or "use a name (" + ", ".join(sorted(COLORS))
                      + ") or [r, g, b, a] in 0..1")
        return COLORS[name]

    def pose(self, node, dim: int) -> tuple[float, ...]:
        """SE3 pose (3-D) or SE2 pose [x, y, theta] (planar)."""
        import yaml

        if isinstance(node, yaml.SequenceNode):
            if dim == 2:
                return self.numbers(node, "a planar pose [x, y, theta]", 3)
            v = self.numbers(node, "a pose ([x, y, z] or [x, y, z, qx, qy, qz, qw])", (3, 7))
            if len(v) == 3:
                return v + (0.0, 0.0, 0.0, 1.0)
            return v[:3] + self.unit_quat(node, v[3:])
        m = self.mapping(node, "a pose")
        if dim == 2:
            self.fail(node, "a planar pose is a list [x, y, theta]")
        for k, (kn, _) in m.items():
            if k not in ("xyz", "rpy", "quat"):
                self.unknown_key(kn, k, ("xyz", "rpy", "quat"), "a pose")
        xyz = self.numbers(m["xyz"][1], "xyz", 3) if "xyz" in m else (0.0, 0.0, 0.0)
        if "rpy" in m and "quat" in m:
            self.fail(m["quat"][0], "give either rpy or quat, not both")
        if "rpy" in m:
            q = quat_from_rpy(*self.numbers(m["rpy"][1], "rpy", 3))
        elif "quat" in m:
            q = self.unit_quat(m["quat"][1], self.numbers(m["quat"][1], "quat [qx, qy, qz, qw]", 4))
        else:
            q = (0.0, 0.0, 0.0, 1.0)
        return tuple(xyz) + tuple(q)

    def unit_quat(self, node, q) -> tuple[float, ...]:
        n = math.sqrt(sum(c * c for c in q))
        if n < 1e-9:
            self.fail(node, "a quaternion must not be zero")
        return tuple(c / n for c in q)

    def shape(self, node, fields: dict, dim: int) -> SceneShape:
        """`shape: box` + `size`, `shape: {circle: r}`, `shape: mesh` + `file`, ..."""
        import yaml

        if isinstance(node, yaml.MappingNode):
            m = self.mapping(node, "a shape")
            if len(m) != 1:
                self.fail(node, "a shape mapping has one entry, e.g. {circle: 0.05} or {box: [sx, sy, sz]}")
            (kind, (kn, vn)), = m.items()
            if kind not in SHAPES or kind == "mesh":
                self.fail(kn, f"unknown shape '{kind}'", "scene",
                          did_you_mean(kind, SHAPES) or "shapes: box, cylinder, sphere, circle, mesh")
            return self._shape(kind, vn, vn, dim)
        kind = self.scalar(node)
        if kind not in SHAPES:
            self.fail(node, f"unknown shape '{kind}'", "scene",
                      did_you_mean(str(kind), SHAPES) or "shapes: " + ", ".join(SHAPES))
        if kind == "mesh":
            if "file" not in fields:
                self.fail(node, "a mesh needs `file: path/to/mesh.stl`")
            f = self.file(fields["file"][1], "mesh file")
            scale = self.numbers(fields["scale"][1], "scale", 3) if "scale" in fields else (1.0, 1.0, 1.0)
            return SceneShape("mesh", scale, f)
        size = fields.get("size") or fields.get("radius")
        if size is None:
            self.fail(node, f"a {kind} needs `size:`" + (" (or `radius:`)" if kind in ("sphere", "circle") else ""))
        return self._shape(kind, size[1], size[1], dim)

    def _shape(self, kind: str, vnode, where, dim: int) -> SceneShape:
        import yaml

        if kind in ("sphere", "circle"):
            if isinstance(vnode, yaml.SequenceNode):
                (r,) = self.numbers(vnode, f"{kind} size [radius]", 1)
            else:
                r = self.number(vnode, f"{kind} radius")
            size: tuple[float, ...] = (r,)
        elif kind == "box":
            size = self.numbers(vnode, "box size [sx, sy, sz]", (2, 3) if dim == 2 else 3)
            if len(size) == 2:
                size = size + (0.1,)
        else:
            size = self.numbers(vnode, "cylinder size [radius, length]", 2)
        if any(s <= 0 for s in size):
            self.fail(where, "shape sizes must be positive")
        return SceneShape(kind, tuple(size))

    # ---- entries
    def robot(self, name: str, knode, node, dim: int) -> SceneRobot | None:
        m = self.mapping(node, f"robot '{name}'")
        attrs = {}
        for k, (kn, vn) in m.items():
            if k not in ROBOT_KEYS:
                v = self.extra(kn, k, vn, ROBOT_KEYS, f"robot '{name}'", name)
                if v is not None:
                    attrs[k] = v
        kind = "urdf"
        if "kind" in m:
            kind = self.string(m["kind"][1], "kind")
            if kind not in ("planar", "urdf"):
                self.fail(m["kind"][1], f"unknown robot kind '{kind}'", "scene",
                          did_you_mean(kind, ("planar", "urdf")) or "kinds: planar, urdf")
        if "base_joint" in m:
            bj = self.string(m["base_joint"][1], "base_joint")
            if bj not in BASE_JOINTS:
                self.fail(m["base_joint"][1], f"unknown base joint '{bj}'", "scene",
                          did_you_mean(bj, BASE_JOINTS) or "one of: fixed, planar, free")
            attrs["base_joint"] = bj
        src = str(self.span(knode))
        color = self.color(m["color"][1]) if "color" in m else (0.9, 0.9, 0.9, 1.0)
        if kind == "planar":
            for k in ("model", "urdf", "srdf", "package_dirs", "locked", "ee", "base", "base_joint", "links"):
                if k in m:
                    self.error(m[k][0], f"'{k}' does not apply to a planar robot", "scene")
            home = self.numbers(m["home"][1], "home [x, y, theta]", 3) if "home" in m else (0.0, 0.0, 0.0)
            held = self.pose(m["held_pose"][1], 2) if "held_pose" in m else None
            shape = self.shape(m["shape"][1], m, 2) if "shape" in m else None
            return SceneRobot(name, "planar", home=home, held_pose=held, shape=shape, color=color,
                              attributes=attrs, source=src)
        if ("model" in m) == ("urdf" in m):
            self.fail(knode, f"robot '{name}' needs exactly one of `model:` (example-robot-data name) "
                      "or `urdf:` (a file)")
        model = self.string(m["model"][1], "model") if "model" in m else None
        urdf = self.file(m["urdf"][1], "URDF file", ROBOT_SUFFIXES) if "urdf" in m else None
        srdf = self.file(m["srdf"][1], "SRDF file", ROBOT_SUFFIXES) if "srdf" in m else None
        pdirs = ()
        if "package_dirs" in m:
            import yaml

            pn = m["package_dirs"][1]
            if not isinstance(pn, yaml.SequenceNode):
                self.fail(pn, "package_dirs must be a list of directories")
            pdirs = tuple(self.file(x, "package directory", directory=True) for x in pn.value)
        base = self.pose(m["base"][1], 3) if "base" in m else IDENTITY
        ee = self.string(m["ee"][1], "ee") if "ee" in m else None
        locked = {}
        if "locked" in m:
            joints = urdf_joints(model, urdf)      # from the URDF's text, as `links:` are checked
            for k, (kn, vn) in self.mapping(m["locked"][1], "locked").items():
                if joints is not None and k not in joints:
                    self.error(kn, f"robot '{name}' has no joint '{k}' that moves (locked)", "unknown-joint",
                               did_you_mean(str(k), sorted(joints)) or f"{len(joints)} joints move")
                    continue
                locked[k] = self.number(vn, f"locked joint '{k}'")
        links = self.links(name, m["links"][1], model, urdf) if "links" in m else {}
        home = self.numbers(m["home"][1], "home") if "home" in m else ()
        if home:
            size = configuration_size(model, urdf, attrs.get("base_joint"), locked)
            if size is not None and len(home) != size[0]:
                self.error(m["home"][1], f"robot '{name}': home has {len(home)} values, its configuration "
                           f"has {size[0]} ({size[1]})", "scene",
                           "one value per coordinate: the base's first, then one per joint that moves and is not locked")
        held = self.pose(m["held_pose"][1], 3) if "held_pose" in m else None
        shape = self.shape(m["shape"][1], m, 3) if "shape" in m else None
        return SceneRobot(name, "urdf", model=model, urdf=urdf, srdf=srdf, package_dirs=pdirs, base=base,
                          ee=ee, locked=locked, links=links, home=home, held_pose=held, shape=shape,
                          color=color, attributes=attrs, source=src)

    def links(self, name: str, node, model: str | None, urdf: str | None) -> dict[str, str]:
        """`links: {hand: panda_hand, ...}`: role names a domain writes in `link(r, "hand")`,
        each naming a link of the robot's URDF that has collision geometry. Checked against the
        URDF's text (no pinocchio: `gnpp check` stays fast); a name the URDF lacks is reported
        at its value, with the closest link name."""
        out: dict[str, str] = {}
        known = urdf_collision_links(model, urdf)
        for role, (kn, vn) in self.mapping(node, f"links of robot '{name}'").items():
            try:
                ln = self.string(vn, f"link of role '{role}'")
            except _Bad:
                continue
            if known is not None and ln not in known:
                self.error(vn, f"robot '{name}' has no link '{ln}' with collision geometry "
                           f"(role '{role}')", "unknown-link",
                           did_you_mean(ln, sorted(known)) or f"{len(known)} links have collision geometry")
                continue
            out[role] = ln
        return out

    def obj(self, name: str, knode, node, dim: int) -> dict:
        m = self.mapping(node, f"object '{name}'")
        attrs = {}
        for k, (kn, vn) in m.items():
            if k not in OBJECT_KEYS:
                v = self.extra(kn, k, vn, OBJECT_KEYS, f"object '{name}'", name)
                problem = range_error(k, v) if v is not None and k.startswith("random_") else None
                if problem:
                    self.error(vn, problem, "number", "docs/scene.md, \"Randomised instances\"")
                elif v is not None:
                    attrs[k] = v
        if "file" in m and not ("shape" in m and self.scalar(m["shape"][1]) == "mesh"):
            self.error(m["file"][0], "`file:` is only used with `shape: mesh`")
        shape = self.shape(m["shape"][1], m, dim) if "shape" in m else SceneShape("none")
        if "size" in m and shape.kind in ("none", "mesh"):
            self.error(m["size"][0], "`size:` needs a `shape:` (box, cylinder, sphere, circle)")
        pose = self.pose(m["pose"][1], dim) if "pose" in m else ((0.0, 0.0, 0.0) if dim == 2 else IDENTITY)
        parent = None
        if "parent" in m:
            parent = (self.string(m["parent"][1], "parent"), m["parent"][1])
        return dict(name=name, shape=shape, rel=pose, parent=parent,
                    color=self.color(m["color"][1]) if "color" in m else (0.6, 0.6, 0.6, 1.0),
                    static=self.boolean(m["static"][1], "static") if "static" in m else False,
                    attributes=attrs, source=str(self.span(knode)), loader=self)

    # ---- the file
    def compose(self, text: str):
        """The YAML node tree of `text` (None after reporting invalid YAML or an empty file)."""
        import yaml

        try:
            root = yaml.compose(text, Loader=getattr(yaml, "CSafeLoader", yaml.SafeLoader))
        except yaml.MarkedYAMLError as exc:
            mark = exc.problem_mark or exc.context_mark
            span = Span(self.path, mark.line + 1, mark.column + 1) if mark else Span(self.path, 1, 1)
            self.r.error(span, f"invalid YAML: {exc.problem or exc.context}", "yaml")
            return None
        except yaml.YAMLError as exc:
            self.r.error(Span(self.path, 1, 1), f"invalid YAML: {exc}", "yaml")
            return None
        if root is None:
            self.r.error(Span(self.path, 1, 1), "the scene file is empty", "scene")
            return None
        return root

    def load(self, text: str) -> Scene | None:
        part = self.part(text, (str(Path(self.path).resolve()),))
        if part is None:
            return None
        dim = part.dim if part.dim is not None else 3
        objects = self.resolve_poses(part.raw, part.robots, dim)
        ignore: set[frozenset[str]] = set()
        for owner, pair in part.ignore:
            names = []
            for x in pair.value:
                n = owner.scalar(x)
                if n not in part.robots and n not in part.raw:
                    owner.error(x, f"unknown robot or object '{n}'", "unknown-name",
                                did_you_mean(str(n), list(part.robots) + list(part.raw)))
                names.append(str(n))
            ignore.add(frozenset(names))
        if not all(x.ok for x in part.loaders):
            return None
        name = part.name if part.name is not None else Path(self.path).stem
        return Scene(name, dim, part.robots, objects, frozenset(ignore), part.workspace, self.path)

    def part(self, text: str, chain: tuple[str, ...]) -> "_Part | None":
        """One file's entries merged after those of the files it includes (`include:`, paths
        relative to this file, depth first, in order). Poses are resolved later, over the
        merged entries, so an object may rest on a parent from another file."""
        import yaml

        root = self.compose(text)
        if root is None:
            return None
        try:
            top = self.mapping(root, "the scene")
        except _Bad:
            return None
        for k, (kn, _) in top.items():
            if k not in TOP_KEYS:
                self.unknown_key(kn, k, TOP_KEYS, "the scene")
        out = _Part(loaders=[self])
        if "include" in top:
            self.include(top["include"][1], chain, out)
        try:
            if "name" in top:
                out.name = str(self.scalar(top["name"][1]))
            if "dimension" in top:
                d = self.scalar(top["dimension"][1])
                if d not in (2, 3) or isinstance(d, bool):
                    self.fail(top["dimension"][1], "dimension is 2 (planar) or 3")
                if out.dim is not None and out.dim != d:
                    self.fail(top["dimension"][1], f"dimension {d} differs from the included "
                              f"scenes' ({out.dim})", "include")
                out.dim = d
        except _Bad:
            pass
        dim = out.dim if out.dim is not None else 3
        if "workspace" in top:
            try:
                wn = top["workspace"][1]
                if not isinstance(wn, yaml.SequenceNode) or len(wn.value) != 2:
                    self.fail(wn, "workspace is [[lower...], [upper...]]")
                lo = self.numbers(wn.value[0], "workspace lower bound", dim)
                hi = self.numbers(wn.value[1], "workspace upper bound", dim)
                if any(a > b for a, b in zip(lo, hi)):
                    self.fail(wn, "workspace lower bounds must not exceed the upper bounds")
                out.workspace = (lo, hi)
            except _Bad:
                pass
        if "robots" in top:
            try:
                for rname, (kn, vn) in self.mapping(top["robots"][1], "robots").items():
                    if self.taken(out, rname, kn):
                        continue
                    try:
                        rb = self.robot(rname, kn, vn, dim)
                        if rb is not None:
                            out.robots[rname] = rb
                            out.where[rname] = str(self.span(kn))
                    except _Bad:
                        pass
            except _Bad:
                pass
        if "objects" in top:
            try:
                for oname, (kn, vn) in self.mapping(top["objects"][1], "objects").items():
                    if self.taken(out, oname, kn):
                        continue
                    try:
                        out.raw[oname] = self.obj(oname, kn, vn, dim)
                        out.where[oname] = str(self.span(kn))
                    except _Bad:
                        pass
            except _Bad:
                pass
        if "ignore_collisions" in top:
            node = top["ignore_collisions"][1]
            try:
                if not isinstance(node, yaml.SequenceNode):
                    self.fail(node, "ignore_collisions is a list of pairs [a, b]")
                for pair in node.value:
                    if not isinstance(pair, yaml.SequenceNode) or len(pair.value) != 2:
                        self.error(pair, "each entry of ignore_collisions is a pair [a, b]")
                        continue
                    out.ignore.append((self, pair))
            except _Bad:
                pass
        return out

    def taken(self, out: "_Part", name: str, knode) -> bool:
        """Report a robot or object name already defined (here or in an included scene)."""
        if name not in out.robots and name not in out.raw:
            return False
        what = "a robot" if name in out.robots else "an object"
        self.error(knode, f"'{name}' is already {what}", "duplicate", f"defined at {out.where[name]}")
        return True

    def include(self, node, chain: tuple[str, ...], out: "_Part") -> None:
        """Merge the scenes named by `include:` (one path or a list) into `out`: a missing file,
        a cycle (a scene including itself, directly or not) and a second definition of a name are
        reported at the offending entry."""
        import yaml

        items = node.value if isinstance(node, yaml.SequenceNode) else [node]
        for item in items:
            try:
                rel = self.string(item, "include")
            except _Bad:
                continue
            path = (self.dir / rel).resolve()
            if str(path) in chain:
                cycle = " -> ".join(Path(c).name for c in chain + (str(path),))
                self.error(item, f"scene include cycle: {cycle}", "cycle",
                           "a scene cannot include itself, directly or through other scenes")
                continue
            try:
                text = path.read_text(encoding="utf-8")
            except FileNotFoundError:
                self.error(item, f"included scene not found: {rel}", "missing-file",
                           f"paths are relative to {self.dir}")
                continue
            except (OSError, UnicodeDecodeError) as exc:
                self.error(item, f"cannot read included scene {rel}: {exc}", "unreadable-file")
                continue
            self.r.sources.add(str(path), text)
            child = _Loader(str(path), self.r)
            child.attr_spans = self.attr_spans
            sub = child.part(text, chain + (str(path),))
            out.loaders.append(child)
            if sub is None:
                self.ok = False
                continue
            out.loaders.extend(x for x in sub.loaders if x is not child)
            if sub.dim is not None:
                if out.dim is not None and out.dim != sub.dim:
                    self.error(item, f"{rel} has dimension {sub.dim}, an earlier include "
                               f"{out.dim}", "include")
                    continue
                out.dim = sub.dim
            for n in list(sub.robots) + list(sub.raw):
                if n in out.robots or n in out.raw:
                    self.error(item, f"'{n}' is defined both in {rel} ({sub.where[n]}) and at "
                               f"{out.where[n]}", "duplicate")
            out.robots.update((k, v) for k, v in sub.robots.items() if k not in out.raw)
            out.raw.update((k, v) for k, v in sub.raw.items() if k not in out.robots)
            out.where.update({k: v for k, v in sub.where.items() if k not in out.where})
            out.ignore.extend(sub.ignore)
            out.name = out.name if out.name is not None else sub.name
            out.workspace = out.workspace if out.workspace is not None else sub.workspace

    def resolve_poses(self, raw: dict[str, dict], robots: dict, dim: int) -> dict[str, SceneObject]:
        """World poses: compose along `parent:` chains (planar: SE2, then lifted to SE3)."""
        world: dict[str, tuple[float, ...]] = {}
        out: dict[str, SceneObject] = {}

        def get(name: str, chain: list[str]):
            if name in world:
                return world[name]
            entry = raw[name]
            rel = entry["rel"]
            if entry["parent"] is None:
                w = rel
            else:
                pname, pnode = entry["parent"]
                owner = entry.get("loader", self)
                if pname in chain:
                    owner.fail(pnode, f"parent chain of '{name}' is a cycle: {' -> '.join(chain + [pname])}",
                              "cycle")
                if pname in raw:
                    pw = get(pname, chain + [pname])
                elif pname in robots:
                    rb = robots[pname]
                    pw = rb.home if dim == 2 and rb.kind == "planar" else rb.base
                    if dim == 2 and len(pw) != 3:
                        pw = (0.0, 0.0, 0.0)
                else:
                    owner.fail(pnode, f"unknown parent '{pname}'", "unknown-name",
                              did_you_mean(pname, list(raw) + list(robots)))
                w = compose_se2(pw, rel) if dim == 2 else compose(pw, rel)
            world[name] = w
            return w

        for name, entry in raw.items():
            try:
                w = get(name, [name])
            except _Bad:
                continue
            pose = se2_to_se3(w) if dim == 2 else tuple(w)
            out[name] = SceneObject(name, entry["shape"], tuple(pose), tuple(w) if dim == 2 else None,
                                    entry["parent"][0] if entry["parent"] else None, entry["color"],
                                    entry["static"], entry["attributes"], entry["source"])
        return out


def load_scene(path: str | Path, reporter: Reporter, ref: Span | None = None) -> Scene | None:
    """Load a scene; problems go to `reporter` (a missing file is reported at `ref`, the
    problem's `scene "..."` line). Returns None if anything is wrong."""
    return load_scene_with_spans(path, reporter, ref)[0]


def load_scene_with_spans(path: str | Path, reporter: Reporter, ref: Span | None = None
                          ) -> tuple[Scene | None, dict[tuple[str, str], Span]]:
    """`load_scene` plus the positions of extra attribute keys, {(entity, key): span}."""
    from gnppdsl.inputs import SCENE_SUFFIXES

    p = str(path)
    text = read_source(reporter, p, ref, SCENE_SUFFIXES, "scene file")
    if text is None:
        return None, {}
    loader = _Loader(p, reporter)
    return loader.load(text), loader.attr_spans


def load_scene_file(path: str | Path) -> Scene:
    """Load a scene or raise `DiagnosticError` (for callers outside a check run)."""
    r = Reporter()
    scene = load_scene(path, r)
    r.raise_if_errors()
    assert scene is not None
    return scene
