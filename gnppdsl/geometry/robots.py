"""Robot models: a `SceneRobot` -> pinocchio model + convex collision geometry + coordinates.

Why this module exists: every other geometry module (casadi forward kinematics, signed
distance, verification, rendering, IK) needs the same reduced pinocchio model, the same convex
collision shapes and the same *planner coordinates*. Loading once and caching keeps them
consistent and cheap.

Planner coordinates vs pinocchio's q: pinocchio stores an unbounded revolute joint as
(cos, sin) and a planar joint as (x, y, cos, sin). A planner variable `q(r) : joints(r)` is
nicer as one angle per rotational degree of freedom (no unit-norm constraint needed), so a
`RobotModel` exposes coordinates of dimension `nc` with `to_pin_q` / `from_pin_q` maps. For
the bundled arms (Panda, UR) the two coincide (nc == nq).
"""
from __future__ import annotations

import functools
import math
import os
from dataclasses import dataclass, field

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.geometry.features import pose_floats
from gnppdsl.geometry.shapes import convex_from_points, shape_vertices
from gnppdsl.ir.robot_files import default_locked, resolve_model_files, robot_data_share
from gnppdsl.ir.scene_model import SceneRobot

_BIG = 1e10   # pinocchio marks "no limit" with +-DBL_MAX



# pinocchio joint short names (`JointModelRX` -> "RX", ...) mapped to our joint kinds: aligned
# joints name their axis by the last letter, unaligned ones carry the axis in the model.
_UNIT_AXES = {"X": (1.0, 0.0, 0.0), "Y": (0.0, 1.0, 0.0), "Z": (0.0, 0.0, 1.0)}
_ALIGNED_JOINTS = {"R": "revolute", "RUB": "revolute_unbounded", "P": "prismatic"}
_UNALIGNED_JOINTS = {"RevoluteUnaligned": "revolute", "RevoluteUnboundedUnaligned": "revolute_unbounded",
                     "PrismaticUnaligned": "prismatic"}


@dataclass(frozen=True)
class JointCoord:
    """How one pinocchio joint maps between planner coordinates and pinocchio's q."""

    name: str
    kind: str            # "revolute", "revolute_unbounded", "prismatic", "planar", "free", "spherical", "translation"
    axis: tuple[float, float, float] | None
    idx_q: int           # first index in pinocchio's q
    nq: int
    idx_c: int           # first index in planner coordinates
    nc: int


@dataclass
class LinkGeometry:
    """One convex collision shape rigidly attached to a link (body frame)."""

    name: str
    shape: object                 # coal.ShapeBase (convex)
    placement: np.ndarray         # 4x4, shape frame in the link frame


@dataclass
class RobotModel:
    """A loaded robot: reduced pinocchio model, convex collision geometry per link, coordinates."""

    name: str
    model: object                 # pin.Model (reduced: locked joints removed)
    geom: object                  # pin.GeometryModel (convex shapes), collision pairs = self-collision pairs
    base: np.ndarray              # 4x4 world placement of the model root (scene `base`)
    ee: str | None
    coords: list[JointCoord]
    nc: int
    lower: np.ndarray             # planner-coordinate limits (+-inf where unbounded)
    upper: np.ndarray
    links: dict[str, list[LinkGeometry]] = field(default_factory=dict)   # link frame -> shapes
    fixed_links: frozenset = frozenset()     # links attached to the world (no joint moves them)
    self_pairs: list[tuple[str, str]] = field(default_factory=list)       # link pairs checked for self-collision
    urdf: str = ""
    srdf: str | None = None

    # -- coordinates ------------------------------------------------------------------------
    def to_pin_q(self, c) -> np.ndarray:
        c = np.asarray(c, dtype=float).ravel()
        if c.size != self.nc:
            raise ValueError(f"robot {self.name}: expected {self.nc} coordinates, got {c.size}")
        q = np.zeros(self.model.nq)
        for j in self.coords:
            v = c[j.idx_c:j.idx_c + j.nc]
            if j.kind == "revolute_unbounded":
                q[j.idx_q:j.idx_q + 2] = (math.cos(v[0]), math.sin(v[0]))
            elif j.kind == "planar":
                q[j.idx_q:j.idx_q + 4] = (v[0], v[1], math.cos(v[2]), math.sin(v[2]))
            else:
                q[j.idx_q:j.idx_q + j.nq] = v
        return q

    def from_pin_q(self, q) -> np.ndarray:
        q = np.asarray(q, dtype=float).ravel()
        c = np.zeros(self.nc)
        for j in self.coords:
            v = q[j.idx_q:j.idx_q + j.nq]
            if j.kind == "revolute_unbounded":
                c[j.idx_c] = math.atan2(v[1], v[0])
            elif j.kind == "planar":
                c[j.idx_c:j.idx_c + 3] = (v[0], v[1], math.atan2(v[3], v[2]))
            else:
                c[j.idx_c:j.idx_c + j.nc] = v
        return c

    @functools.cached_property
    def angle_mask(self) -> np.ndarray:
        """Which planner coordinates are angles on the circle (continuous joints, a planar
        joint's heading): q and q + 2*pi*k are the same configuration there."""
        m = np.zeros(self.nc, dtype=bool)
        for j in self.coords:
            if j.kind == "revolute_unbounded":
                m[j.idx_c] = True
            elif j.kind == "planar":
                m[j.idx_c + 2] = True
        return m

    def coord_difference(self, q1, q2) -> np.ndarray:
        """q2 - q1 (rows broadcast), angles the short way round: wrapped into (-pi, pi]."""
        d = np.asarray(q2, dtype=float) - np.asarray(q1, dtype=float)
        m = self.angle_mask
        if m.any():
            d = d.copy()
            a = d[..., m]
            d[..., m] = a - 2 * math.pi * np.ceil((a - math.pi) / (2 * math.pi))
        return d

    def random_coords(self, rng: np.random.Generator) -> np.ndarray:
        """Uniform in the limits; unbounded angles in [-pi, pi], unbounded translations in [-1, 1]."""
        lo = self.lower.copy()
        hi = self.upper.copy()
        ang = self.angle_mask
        for k in range(self.nc):
            if not np.isfinite(lo[k]) or not np.isfinite(hi[k]):
                lo[k], hi[k] = (-math.pi, math.pi) if ang[k] else (-1.0, 1.0)
        c = rng.uniform(lo, hi)
        for j in self.coords:   # quaternion coordinates must be unit
            if j.kind in ("free", "spherical"):
                s = j.idx_c + (3 if j.kind == "free" else 0)
                qu = rng.normal(size=4)
                c[s:s + 4] = qu / np.linalg.norm(qu)
        return c

    def frame_id(self, frame: str) -> int:
        if not self.model.existFrame(frame):
            names = [f.name for f in self.model.frames]
            import difflib
            close = difflib.get_close_matches(frame, names, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise UserError(f"robot {self.name} has no frame '{frame}'{hint}")
        return self.model.getFrameId(frame)

    def planar_points(self, link: str, c) -> np.ndarray:
        """The horizontal (x, y) of every vertex of `link`'s collision shapes at coordinates `c`
        (shape (n, 2), empty when it has none), in the model's frame: with the planar joint at the
        origin and theta 0, a mobile base's outline in its own frame
        (`compile.placement.base_footprint`)."""
        import pinocchio as pin

        data = self.model.createData()
        pin.framesForwardKinematics(self.model, data, self.to_pin_q(c))
        T = data.oMf[self.frame_id(link)].homogeneous
        out = [np.zeros((0, 2))]
        for g in self.links.get(link, []):
            M = T @ g.placement
            w = shape_vertices(g.shape) @ M[:3, :3].T + M[:3, 3]
            out.append(w[:, :2])
        return np.concatenate(out)

    def planar_radius(self, link: str, c) -> float:
        """The largest horizontal distance from the model's origin of a vertex of `link`'s
        collision shapes at coordinates `c` (0 when it has none): a mobile base's footprint
        radius when `c` puts the planar joint at the origin (`compile.placement.base_radius`)."""
        P = self.planar_points(link, c)
        return float(np.hypot(P[:, 0], P[:, 1]).max()) if len(P) else 0.0

    def home_coords(self, home: tuple[float, ...] = ()) -> np.ndarray:
        """The scene's `home`, else the SRDF "default" state, else pinocchio's neutral
        configuration clipped into the limits (the Panda's neutral q4 = 0 violates its limit)."""
        if home:
            return np.asarray(home, dtype=float)
        import pinocchio as pin
        refs = self.model.referenceConfigurations
        q = np.array(refs["default"]) if "default" in refs else np.array(pin.neutral(self.model))
        return np.clip(self.from_pin_q(q), self.lower, self.upper)


def se3_to_matrix(pose) -> np.ndarray:
    """[x, y, z, qx, qy, qz, qw] -> 4x4 homogeneous matrix (quaternion normalised).

    On Python floats and one array construction: the numeric checker converts every pose of
    every distance query (lab5: 44k per solve), where numpy's per-element arithmetic and
    `np.eye` cost 16 us a call against ~3 us."""
    (r0, r1, r2), (px, py, pz) = pose_floats(pose)
    return np.array([
        [*r0, px],
        [*r1, py],
        [*r2, pz],
        [0.0, 0.0, 0.0, 1.0],
    ])


def matrix_to_se3(T) -> np.ndarray:
    """4x4 -> [x, y, z, qx, qy, qz, qw] with qw >= 0."""
    import pinocchio as pin
    T = np.asarray(T, dtype=float)
    v = pin.SE3ToXYZQUAT(pin.SE3(T[:3, :3], T[:3, 3]))
    v = np.array(v)
    if v[6] < 0:
        v[3:] = -v[3:]
    return v


def _coords_of(model) -> tuple[list[JointCoord], int, np.ndarray, np.ndarray]:
    coords: list[JointCoord] = []
    lower: list[float] = []
    upper: list[float] = []
    idx_c = 0
    lo_pin = np.array(model.lowerPositionLimit)
    hi_pin = np.array(model.upperPositionLimit)

    def lim(i):
        lo, hi = lo_pin[i], hi_pin[i]
        return (lo if abs(lo) < _BIG else -math.inf, hi if abs(hi) < _BIG else math.inf)

    for jid in range(1, model.njoints):
        jm = model.joints[jid]
        short = jm.shortname().replace("JointModel", "")
        name = model.names[jid]
        axis = None
        if short[:-1] in _ALIGNED_JOINTS and short[-1:] in _UNIT_AXES:
            kind, nc, axis = _ALIGNED_JOINTS[short[:-1]], 1, _UNIT_AXES[short[-1]]
        elif short in _UNALIGNED_JOINTS:
            kind, nc = _UNALIGNED_JOINTS[short], 1
            axis = tuple(float(a) for a in jm.extract().axis)
        elif short == "Planar":
            kind, nc = "planar", 3
        elif short == "FreeFlyer":
            kind, nc = "free", 7
        elif short == "Spherical":
            kind, nc = "spherical", 4
        elif short == "Translation":
            kind, nc = "translation", 3
        else:
            raise UserError(f"joint '{name}' has type {jm.shortname()}, which gnppdsl does not support "
                            "(supported: revolute, continuous, prismatic, planar, floating, spherical)")
        coords.append(JointCoord(name, kind, axis, jm.idx_q, jm.nq, idx_c, nc))
        if kind == "revolute_unbounded":
            lower.append(-math.inf); upper.append(math.inf)
        elif kind == "planar":
            for k in range(2):
                lo, hi = lim(jm.idx_q + k); lower.append(lo); upper.append(hi)
            lower.append(-math.inf); upper.append(math.inf)
        elif kind in ("free", "spherical"):
            for k in range(nc):
                lo, hi = lim(jm.idx_q + k)
                if kind == "free" and k >= 3 or kind == "spherical":
                    lo, hi = -1.0, 1.0
                lower.append(lo); upper.append(hi)
        else:
            for k in range(nc):
                lo, hi = lim(jm.idx_q + k); lower.append(lo); upper.append(hi)
        idx_c += nc
    return coords, idx_c, np.array(lower), np.array(upper)


def _convexify(geometry, name: str):
    """A coal collision geometry -> a convex coal shape (meshes: convex hull of the vertices)."""
    import coal
    if isinstance(geometry, coal.BVHModelBase):
        verts = np.array(geometry.vertices())
        return convex_from_points(verts, name)
    return geometry


def _merge_link(link: str, gs: list[LinkGeometry]) -> list[LinkGeometry]:
    """Several shapes on one link -> their joint convex hull (one shape).

    Why: the distance to a union is a minimum over shapes, which is non-smooth where the nearest
    shape changes (the Panda's fingers are four boxes each, and ipopt stalls on the kinks). The
    hull is conservative and one coal query instead of several."""
    if len(gs) == 1:
        return gs
    pts = []
    for g in gs:
        v = shape_vertices(g.shape)
        pts.append(v @ g.placement[:3, :3].T + g.placement[:3, 3])
    hull = convex_from_points(np.vstack(pts), link)
    return [LinkGeometry(link + "_hull", hull, np.eye(4))]


def _srdf_pairs(geom, model, srdf: str | None) -> None:
    import pinocchio as pin
    geom.addAllCollisionPairs()
    if srdf:
        pin.removeCollisionPairs(model, geom, srdf)


@functools.lru_cache(maxsize=64)
def _load_cached(name, model_name, urdf, srdf, package_dirs, base, ee, locked_items, base_joint,
                 base_limits=None) -> RobotModel:
    import pinocchio as pin
    pkg = list(package_dirs)
    if model_name:
        urdf_m, srdf_m, share = resolve_model_files(model_name)
        urdf = urdf or urdf_m
        srdf = srdf or srdf_m
        pkg.append(share)
    if not urdf:
        raise UserError(f"robot {name}: give either `model:` (example-robot-data name) or `urdf:`")
    if not os.path.isfile(urdf):
        raise UserError(f"robot {name}: URDF file not found: {urdf}")
    if not pkg:
        pkg.append(os.path.dirname(urdf))
        try:
            pkg.append(robot_data_share())
        except UserError:
            pass
    root_joint = {"planar": pin.JointModelPlanar(), "free": pin.JointModelFreeFlyer(),
                  "fixed": None, None: None}.get(base_joint, "bad")
    if root_joint == "bad":
        raise UserError(f"robot {name}: base_joint must be 'fixed', 'planar' or 'free', not '{base_joint}'")
    try:
        full = pin.buildModelFromUrdf(urdf, root_joint) if root_joint is not None else pin.buildModelFromUrdf(urdf)
        geom_full = pin.buildGeomFromUrdf(full, urdf, pin.GeometryType.COLLISION, package_dirs=pkg)
    except Exception as e:  # pinocchio raises ValueError / RuntimeError with its own text
        raise UserError(f"robot {name}: cannot load URDF {urdf}: {e}") from None
    locked = dict(locked_items) or default_locked(model_name)
    q_ref = pin.neutral(full)
    lock_ids = []
    for jname, val in locked.items():
        if not full.existJointName(jname):
            raise UserError(f"robot {name}: cannot lock unknown joint '{jname}'")
        jid = full.getJointId(jname)
        jm = full.joints[jid]
        if jm.nq == 2 and jm.nv == 1:       # a continuous joint: pinocchio stores (cos, sin)
            q_ref[jm.idx_q:jm.idx_q + 2] = (math.cos(float(val)), math.sin(float(val)))
        elif jm.nq != 1:
            raise UserError(f"robot {name}: can only lock 1-DOF joints, '{jname}' has nq={jm.nq}")
        else:
            q_ref[jm.idx_q] = float(val)
        lock_ids.append(jid)
    if lock_ids:
        model, geom = pin.buildReducedModel(full, geom_full, lock_ids, q_ref)
    else:
        model, geom = full, geom_full
    # Make every collision shape convex (BVH meshes give no usable gradient in coal).
    for go in geom.geometryObjects:
        go.geometry = _convexify(go.geometry, f"{name}/{go.name}")
    _srdf_pairs(geom, model, srdf)
    if srdf:
        try:
            pin.loadReferenceConfigurations(model, srdf, False)
        except Exception:   # states naming locked joints etc.: home falls back to neutral
            pass
    coords, nc, lower, upper = _coords_of(model)
    if base_limits is not None and coords and coords[0].kind == "planar":
        # planar base: x, y limits from the scene (`base_min`, `base_max`); theta stays free
        (lx, ly), (ux, uy) = base_limits
        lower[0:2] = (lx, ly)
        upper[0:2] = (ux, uy)
    links: dict[str, list[LinkGeometry]] = {}
    for go in geom.geometryObjects:
        fr = model.frames[go.parentFrame]
        # go.placement is relative to the parent joint; express the shape in the link (body) frame.
        local = fr.placement.inverse() * go.placement
        links.setdefault(fr.name, []).append(LinkGeometry(go.name, go.geometry, np.array(local.homogeneous)))
    links = {ln: _merge_link(ln, gs) for ln, gs in links.items()}
    self_pairs = set()
    for cp in geom.collisionPairs:
        a = model.frames[geom.geometryObjects[cp.first].parentFrame].name
        b = model.frames[geom.geometryObjects[cp.second].parentFrame].name
        if a != b:
            self_pairs.add(tuple(sorted((a, b))))
    if ee is not None and not model.existFrame(ee):
        import difflib
        close = difflib.get_close_matches(ee, [f.name for f in model.frames], n=1)
        hint = f" (did you mean '{close[0]}'?)" if close else ""
        raise UserError(f"robot {name}: end-effector frame '{ee}' not in the model{hint}")
    fixed = frozenset(ln for ln in links if model.frames[model.getFrameId(ln)].parentJoint == 0)
    return RobotModel(name=name, model=model, geom=geom, base=se3_to_matrix(base), ee=ee, coords=coords, nc=nc,
                      lower=lower, upper=upper, links=links, fixed_links=fixed, self_pairs=sorted(self_pairs),
                      urdf=urdf, srdf=srdf)


def load_robot(spec: SceneRobot) -> RobotModel:
    """Load (cached) the pinocchio model of a scene robot of kind "urdf".

    `spec.locked` joints are removed with `pin.buildReducedModel`; a Panda without `locked`
    gets its fingers locked open (0.04) so that `joints(r)` is the 7-DOF arm.
    `spec.attributes["base_joint"]` = "planar" adds a planar root joint (mobile base, coordinates
    x, y, theta first; `base_min` / `base_max` [x, y] attributes bound it), "free" a floating base.
    """
    if spec.kind != "urdf":
        raise UserError(f"robot {spec.name}: load_robot handles URDF robots, not kind '{spec.kind}'")
    bl = None
    if "base_min" in spec.attributes or "base_max" in spec.attributes:
        try:
            lo = tuple(float(v) for v in spec.attributes.get("base_min", (-math.inf, -math.inf)))
            hi = tuple(float(v) for v in spec.attributes.get("base_max", (math.inf, math.inf)))
        except (TypeError, ValueError):
            raise UserError(f"robot {spec.name}: base_min / base_max must be [x, y] numbers") from None
        if len(lo) != 2 or len(hi) != 2:
            raise UserError(f"robot {spec.name}: base_min / base_max must be [x, y]")
        bl = (lo, hi)
    return _load_cached(spec.name, spec.model, spec.urdf, spec.srdf, tuple(spec.package_dirs), tuple(spec.base),
                        spec.ee, tuple(sorted(spec.locked.items())), spec.attributes.get("base_joint"), bl)
