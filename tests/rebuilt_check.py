"""A second verifier of Lab, Workshop and mobile solutions that imports nothing from gnppdsl (issue 25).

Why: `gnppdsl.solve.verify_solution` already recomputes a solution with pinocchio and coal
instead of the solver's casadi factors, but it still reads the scene through the project's
loader (`GeometryContext`, `geometry.robots`: the same URDF reduction, base placement, convex
hulls and link filters the factors were built from), so a bug there confirms itself. This
module rebuilds the constraints from the files alone: the `--json` result (steps, symbolic
states, numbers, world poses, trajectories), the scene YAML (read with `yaml.safe_load`,
`include:` followed), the problem's `goal { ... }` line (a regular expression) and the robots'
URDF from example-robot-data, loaded with `pin.buildModelFromUrdf` / `pin.buildGeomFromUrdf`.
It checks, at every keyframe and every trajectory waypoint:

- joint limits of the URDF (a mobile base: its `base_min`/`base_max` box);
- the kinematic tree: world poses rebuilt from the `parent(o)` facts and relative `pose(o)`
  values (a robot's frame: FK of its end effector), the result's own `world` poses compared;
- grasp: the end effector of FK(q(r)) lies inside the held object's box, and a held object
  follows the end effector along the motion;
- placement: an object whose parent is a scene body or object rests on it (bottom on top,
  centre over the top face); one whose parent is an object a robot holds (a block on the
  Workshop's stick) touches that object and rests on a static body, and follows it along the
  motion;
- collisions: every robot link's URDF collision mesh against every object and static body
  (`coal.collide` on the meshes themselves, a touch deeper than 0.1 mm on hulls of its own:
  the solver's tolerance, `CONTACT_TOLERANCE`; a fixed base's
  unmoving links against static bodies excepted: the arm is mounted on the table), the two
  arms' links against each other, and object pairs by signed distance (boxes), a held object with its
  robot and the pairs of `ignore_collisions` excepted;
- self-collisions: each robot's link meshes against each other, the pairs pinocchio builds for
  links on different joints (`addAllCollisionPairs`) minus those the robot's SRDF disables
  (`removeCollisionPairs`: adjacent links and pairs that never or always touch, e.g. the fingers
  with the hand); a robot model without an SRDF keeps only the pairs of links at least two
  joints apart in the tree (adjacent links touch at their joint by construction);
- goal: every `f(x) = y` fact of the problem's goal holds in the final symbolic state.

Conventions read from the scene format (docs/scene.md): poses `{xyz, rpy | quat (x y z w)}`,
box `size` full extents, a robot's `base` its world placement, `locked` joints fixed,
`base_joint: planar` a base moving by (x, y, theta) before the fixed `base` offset.
"""
from __future__ import annotations

import json
import re
import sys
from dataclasses import dataclass, field
from pathlib import Path

import coal
import numpy as np
import pinocchio as pin
import yaml

# model -> (URDF, SRDF or None), relative to example-robot-data's robots directory
MODELS = {"panda": ("panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf"),
          "pr2": ("pr2_description/urdf/pr2.urdf", "pr2_description/srdf/pr2.srdf")}
_FACT = re.compile(r"(\w+)\(([\w, ]+)\)\s*=\s*(\w+)")


def _share() -> Path:
    """example-robot-data's share directory (a cmeel package beside pinocchio)."""
    for p in [Path(pin.__file__).parents[4] / "share", *(Path(s) / "cmeel.prefix" / "share" for s in sys.path)]:
        if (p / "example-robot-data" / "robots").is_dir():
            return p / "example-robot-data" / "robots"
    raise FileNotFoundError("example-robot-data")


def _pose(spec: dict | None) -> pin.SE3:
    spec = spec or {}
    R = np.eye(3)
    if "rpy" in spec:
        R = pin.rpy.rpyToMatrix(*map(float, spec["rpy"]))
    elif "quat" in spec:
        q = np.asarray(spec["quat"], float)
        R = pin.Quaternion(q[3], q[0], q[1], q[2]).normalized().toRotationMatrix()
    return pin.SE3(R, np.asarray(spec.get("xyz", [0, 0, 0]), float))


def _se3(v) -> pin.SE3:
    """x y z qx qy qz qw (the result's world poses)."""
    v = np.asarray(v, float)
    return pin.SE3(pin.Quaternion(v[6], v[3], v[4], v[5]).normalized().toRotationMatrix(), v[:3])


def load_scene(path: Path) -> dict:
    data = yaml.safe_load(path.read_text())
    inc = data.pop("include", None)
    if inc:
        base: dict = {}
        for one in ([inc] if isinstance(inc, str) else inc):      # one file or a list, in order
            sub = load_scene(path.parent / one)
            for key in ("robots", "objects"):
                base.setdefault(key, {}).update(sub.pop(key, {}) or {})
            base["ignore_collisions"] = list(base.get("ignore_collisions", [])) + list(sub.pop("ignore_collisions", []))
            base.update({k: v for k, v in sub.items() if k not in base})
        for key in ("robots", "objects"):
            base.setdefault(key, {}).update(data.pop(key, {}) or {})
        base["ignore_collisions"] = list(base.get("ignore_collisions", [])) + list(data.pop("ignore_collisions", []))
        base.update(data)
        return base
    return data


@dataclass
class _Robot:
    name: str
    model: pin.Model
    data: pin.Data
    geom: pin.GeometryModel
    gdata: pin.GeometryData
    base: pin.SE3
    ee: int
    joints: list[str]                  # the result's coordinate names, in order
    planar: bool
    spec: dict
    self_pairs: list[tuple[int, int]] = field(default_factory=list)    # geometry indices checked against each other

    def q_full(self, q) -> np.ndarray:
        full = pin.neutral(self.model)
        arm = list(q)[3:] if self.planar else list(q)
        names = self.joints[3:] if self.planar else self.joints
        for j, v in [*(self.spec.get("locked") or {}).items(), *zip(names, arm)]:
            jm = self.model.joints[self.model.getJointId(j)]
            if jm.nq == 2:                  # a continuous joint (the PR2's rolls): cos, sin of its angle
                full[jm.idx_q:jm.idx_q + 2] = np.cos(float(v)), np.sin(float(v))
            else:
                full[jm.idx_q] = float(v)
        return full

    def base_at(self, q) -> pin.SE3:
        if not self.planar:
            return self.base
        x, y, th = (float(v) for v in list(q)[:3])
        return pin.SE3(pin.rpy.rpyToMatrix(0, 0, th), np.array([x, y, 0.0])) * self.base

    def place(self, q) -> pin.SE3:
        """FK: updates the link geometry placements; returns the end effector's world pose."""
        full = self.q_full(q)
        pin.framesForwardKinematics(self.model, self.data, full)
        pin.updateGeometryPlacements(self.model, self.data, self.geom, self.gdata)
        return self.base_at(q) * self.data.oMf[self.ee]

    def limit_violations(self, q, tol: float = 1e-4) -> list[str]:
        out = []
        arm = list(q)[3:] if self.planar else list(q)
        names = self.joints[3:] if self.planar else self.joints
        for j, v in zip(names, arm):
            if self.model.joints[self.model.getJointId(j)].nq != 1:
                continue                        # a continuous joint has no limits
            i = self.model.joints[self.model.getJointId(j)].idx_q
            lo, hi = self.model.lowerPositionLimit[i], self.model.upperPositionLimit[i]
            if not lo - tol <= v <= hi + tol:
                out.append(f"{self.name}.{j} = {v:.4f} outside [{lo:.4f}, {hi:.4f}]")
        if self.planar:
            lo, hi = self.spec.get("base_min"), self.spec.get("base_max")
            for k in range(2):
                if lo is not None and hi is not None and not lo[k] - tol <= q[k] <= hi[k] + tol:
                    out.append(f"{self.name} base coordinate {k} = {q[k]:.4f} outside [{lo[k]}, {hi[k]}]")
        return out


def _robot(name: str, spec: dict, joints: list[str]) -> _Robot:
    urdf_rel, srdf_rel = MODELS[spec["model"]]
    root = _share()
    urdf = str(root / urdf_rel)
    model = pin.buildModelFromUrdf(urdf)
    geom = pin.buildGeomFromUrdf(model, urdf, pin.GeometryType.COLLISION, package_dirs=[str(root.parents[1])])
    return _Robot(name, model, model.createData(), geom, pin.GeometryData(geom), _pose(spec.get("base")),
                  model.getFrameId(spec["ee"]), joints, spec.get("base_joint") == "planar", spec,
                  _self_pairs(model, geom, root / srdf_rel if srdf_rel else None))


def _self_pairs(model: pin.Model, geom: pin.GeometryModel, srdf: Path | None) -> list[tuple[int, int]]:
    """The link-mesh pairs of one robot checked against each other: pinocchio's pairs of
    geometries on different joints, minus the SRDF's `disable_collisions` (or, without an SRDF,
    minus the pairs whose joints are the same or parent and child)."""
    geom.addAllCollisionPairs()
    if srdf is not None:
        pin.removeCollisionPairs(model, geom, str(srdf))
        return [(cp.first, cp.second) for cp in geom.collisionPairs]
    out = []
    for cp in geom.collisionPairs:
        ja, jb = geom.geometryObjects[cp.first].parentJoint, geom.geometryObjects[cp.second].parentJoint
        if ja != jb and model.parents[ja] != jb and model.parents[jb] != ja:
            out.append((cp.first, cp.second))
    return out


@dataclass
class _Body:
    name: str
    half: np.ndarray
    shape: coal.CollisionGeometry
    static: bool


def _body(name: str, spec: dict) -> _Body:
    if spec.get("shape") != "box":
        raise NotImplementedError(f"{name}: shape {spec.get('shape')} (Lab and mobile use boxes)")
    size = np.asarray(spec["size"], float)
    return _Body(name, size / 2, coal.Box(*size), bool(spec.get("static")))


def _tf(T: pin.SE3) -> coal.Transform3s:
    return coal.Transform3s(T.rotation, T.translation)


def _facts(text: str) -> dict[str, str]:
    return {f"{f}({a.replace(' ', '')})": v for f, a, v in _FACT.findall(text)}


def _goal(problem: Path) -> dict[str, str]:
    m = re.search(r"^goal\s*\{([^}]*)\}", problem.read_text(), re.M)
    return _facts(m.group(1)) if m else {}


@dataclass
class Report:
    keyframes: int = 0
    waypoints: int = 0
    failures: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        return not self.failures

    def __str__(self) -> str:
        return f"{self.keyframes} keyframes, {self.waypoints} waypoints: " + ("ok" if self.ok else "; ".join(self.failures[:10]))


def check(result: dict, problem: Path | None = None, margin: float = 1e-3, place_tol: float = 2e-3) -> Report:
    """Re-check a solved `--json` result against constraints rebuilt from its files (the
    problem file: `problem`, else the result's `inputs`; its scene from its `scene` line)."""
    problem = Path(problem or result["inputs"]["problem"])
    m = re.search(r'^scene\s+"([^"]+)"', problem.read_text(), re.M)
    scene = load_scene(problem.parent / m.group(1))
    robots = {r: _robot(r, scene["robots"][r], info["joints"] if not scene["robots"][r].get("base_joint")
                        else result["coordinates"][info["configuration"]])
              for r, info in result["robots"].items()}
    bodies = {n: _body(n, s) for n, s in scene.get("objects", {}).items()}
    ignore = {frozenset(p) for p in scene.get("ignore_collisions", [])}
    rep = Report()
    steps = result["steps"]
    for i, st in enumerate(steps):
        facts = _facts(st["state"])
        qs = {r: st["values"][result["robots"][r]["configuration"]] for r in robots}
        held = {facts[f"holding({r})"]: r for r in robots if facts.get(f"holding({r})", "none") != "none"}
        ee = {r: robots[r].place(qs[r]) for r in robots}
        world = _kinematic_tree(rep, f"s{i}", scene, bodies, facts, st, ee)
        rep.keyframes += 1
        _state(rep, f"s{i}", robots, bodies, world, qs, held, ignore, margin)
        for o, r in held.items():                       # grasp: the ee point inside the held box
            local = world[o].actInv(ee[r].translation)
            if np.any(np.abs(local) > bodies[o].half + 1e-3):
                rep.failures.append(f"s{i}: {r}'s end effector is not inside {o} (local {np.round(local, 4)})")
        for o, b in bodies.items():                     # placement on a body or an object
            p = facts.get(f"parent({o})")
            if b.static or p is None or p in robots or p not in bodies:
                continue
            if p in held:                               # riding on a held tool (a pushed block)
                _riding(rep, f"s{i}", o, world, bodies, p, place_tol)
                continue
            _resting(rep, f"s{i}", o, world[o], bodies[o], p, world[p], bodies[p], place_tol)
        rel = {o: _se3(st["values"][f"pose({o})"]) for o in held}      # held: relative to the ee
        # riding on a held object (a block on the stick's end): relative to that object
        riders = {o: (facts[f"parent({o})"], _se3(st["values"][f"pose({o})"])) for o in bodies
                  if facts.get(f"parent({o})") in held and f"pose({o})" in st["values"]}
        paths = {next(x for x in robots if result["robots"][x]["trajectory"] == key): path
                 for key, path in (st.get("trajectories") or {}).items() if path}
        # robots moving in the same phase move together: waypoint k of each at once (their
        # paths are sampled alike); otherwise each alone, the others at the keyframe
        together = len({len(p) for p in paths.values()}) == 1
        groups = [list(paths)] if together else [[r] for r in paths]
        for group in groups:
            for k in range(1, len(paths[group[0]]) - 1):
                rep.waypoints += 1
                qw = dict(qs, **{r: paths[r][k] for r in group})
                T = {r: robots[r].place(qw[r]) for r in robots}
                ww = dict(world)
                for o, r2 in held.items():
                    ww[o] = T[r2] * rel[o]
                for o, (p, r_o) in riders.items():
                    ww[o] = ww[p] * r_o
                _state(rep, f"s{i}->s{i + 1} waypoint {k}", robots, bodies, ww, qw, held, ignore, margin)
    final = _facts(steps[-1]["state"])
    for var, val in _goal(problem).items():
        if final.get(var) != val:
            rep.failures.append(f"goal {var} = {val} not in the final state ({final.get(var)})")
    return rep


def _kinematic_tree(rep: Report, where: str, scene, bodies, facts, st, ee) -> dict[str, pin.SE3]:
    """World poses rebuilt from the state's `parent(o)` facts and the relative `pose(o)`
    values (a robot's frame: its end effector by FK; a static body: its scene pose); the
    result's own `world` poses are compared with them."""
    world: dict[str, pin.SE3] = {n: _pose(scene["objects"][n].get("pose")) for n, b in bodies.items() if b.static}

    def get(o: str, depth: int = 0) -> pin.SE3:
        if o in world:
            return world[o]
        if o in ee:
            return ee[o]
        p, rel = facts.get(f"parent({o})"), st["values"].get(f"pose({o})")
        if p is None or rel is None or depth > len(bodies):
            world[o] = _pose(scene["objects"][o].get("pose"))
        else:
            world[o] = get(p, depth + 1) * _se3(rel)
        return world[o]

    for o in bodies:
        get(o)
    for o, v in (st.get("world") or {}).items():
        d = np.linalg.norm(pin.log6(world[o].actInv(_se3(v))).vector) if o in world else np.inf
        if d > 1e-4:
            rep.failures.append(f"{where}: the result's world pose of {o} is {d:.2e} off its rebuilt pose")
    return world


CONTACT_TOLERANCE = 1e-4
"""Penetration (m) a robot link may have into anything: the constraint tolerance the solver's
results are documented with (docs/reference.md, "Tolerances of the verification"), 0.1 mm.
Not 0: a collision constraint active at a solution sits at distance 0 up to the solver's 1e-6,
and where a link's mesh coincides with its convex hull (a finger pad) `coal.collide` reports
that touch."""

_HULLS: dict[int, tuple] = {}


def _hull(geometry):
    """The convex hull of a mesh (built once per geometry; a primitive shape is its own)."""
    if not isinstance(geometry, coal.BVHModelBase):
        return geometry
    if id(geometry) not in _HULLS:
        geometry.buildConvexHull(True, "Qt")
        _HULLS[id(geometry)] = (geometry, geometry.convex)     # the geometry kept: ids stay unique
    return _HULLS[id(geometry)][1]


def _collides(g1, T1, g2, T2) -> bool:
    """The meshes touch and go more than CONTACT_TOLERANCE into each other. coal's negative
    security margin is refused for meshes, and the depths of a mesh's triangle contacts are not
    the bodies' penetration, so a touch is measured on the convex hulls: a penetration of the
    meshes never exceeds that of their hulls (a translation separating the hulls separates
    what they contain), so a hull depth within the tolerance clears the meshes."""
    if not coal.collide(g1, T1, g2, T2, coal.CollisionRequest(), coal.CollisionResult()):
        return False
    d = coal.distance(_hull(g1), T1, _hull(g2), T2, coal.DistanceRequest(), coal.DistanceResult())
    return d < -CONTACT_TOLERANCE


def _state(rep: Report, where: str, robots, bodies, world, qs, held, ignore, margin) -> None:
    """Limits and collisions of one configuration (robots already placed by `place`)."""
    for r, rb in robots.items():
        rep.failures.extend(f"{where}: {v}" for v in rb.limit_violations(qs[r]))
    for r, rb in robots.items():
        B = rb.base_at(qs[r])
        links = [(rb.geom.geometryObjects[g], B * rb.gdata.oMg[g]) for g in range(rb.geom.ngeoms)]
        for n, b in bodies.items():
            if held.get(n) == r or frozenset((n, r)) in ignore:
                continue
            for go, T in links:
                if b.static and go.parentJoint == 0 and not rb.planar:
                    continue                  # a link no joint moves (the base on its table)
                if _collides(go.geometry, _tf(T), b.shape, _tf(world[n])):
                    rep.failures.append(f"{where}: {r}/{go.name} collides with {n}")
        for ga, gb in rb.self_pairs:              # the SRDF-filtered pairs of its own links
            go_a, go_b = rb.geom.geometryObjects[ga], rb.geom.geometryObjects[gb]
            if _collides(go_a.geometry, _tf(rb.gdata.oMg[ga]), go_b.geometry, _tf(rb.gdata.oMg[gb])):
                rep.failures.append(f"{where}: {r}/{go_a.name} collides with {r}/{go_b.name} (self-collision)")
        for r2, rb2 in robots.items():
            if r2 <= r:
                continue
            B2 = rb2.base_at(qs[r2])
            for go, T in links:
                for g2 in range(rb2.geom.ngeoms):
                    go2 = rb2.geom.geometryObjects[g2]
                    if _collides(go.geometry, _tf(T), go2.geometry, _tf(B2 * rb2.gdata.oMg[g2])):
                        rep.failures.append(f"{where}: {r}/{go.name} collides with {r2}/{go2.name}")
    names = sorted(bodies)
    for a_i, a in enumerate(names):
        for b in names[a_i + 1:]:
            if frozenset((a, b)) in ignore or (bodies[a].static and bodies[b].static):
                continue
            res = coal.DistanceResult()
            d = coal.distance(bodies[a].shape, _tf(world[a]), bodies[b].shape, _tf(world[b]),
                              coal.DistanceRequest(), res)
            if d < -margin:
                rep.failures.append(f"{where}: {a} and {b} overlap by {-d * 1000:.1f} mm")


def _riding(rep, where, o, world, bodies, tool, tol) -> None:
    """An object whose parent is an object a robot holds (a block pushed by the stick's end)
    touches that object and rests on a static body (it slides on the table)."""
    d = coal.distance(bodies[o].shape, _tf(world[o]), bodies[tool].shape, _tf(world[tool]),
                      coal.DistanceRequest(), coal.DistanceResult())
    if d > tol:
        rep.failures.append(f"{where}: {o} rides on {tool} {d * 1000:.1f} mm away from it")
    for s, b in bodies.items():
        probe = Report()
        if b.static:
            _resting(probe, where, o, world[o], bodies[o], s, world[s], b, tol)
            if not probe.failures:
                return
    rep.failures.append(f"{where}: {o} rides on {tool} but rests on no static body")


def _resting(rep, where, o, To, bo, p, Tp, bp, tol) -> None:
    up = Tp.rotation[:, 2]
    if abs(float(To.rotation[:, 2] @ up)) < 1 - 1e-3 and abs(float(To.rotation[:, 0] @ up)) < 1 - 1e-3 \
            and abs(float(To.rotation[:, 1] @ up)) < 1 - 1e-3:
        rep.failures.append(f"{where}: {o} is tilted on {p}")
        return
    # o's extent along the support's normal: the box's half extents projected
    h_o = float(np.abs(To.rotation.T @ up) @ bo.half)
    local = Tp.actInv(To.translation)
    gap = local[2] - h_o - bp.half[2]
    inside = bool(np.all(np.abs(local[:2]) <= bp.half[:2] + 1e-6))
    if abs(gap) > tol or not inside:
        rep.failures.append(f"{where}: {o} does not rest on {p} (gap {gap * 1000:.1f} mm, centre over top {inside})")


def main(argv: list[str]) -> int:
    rep = check(json.loads(Path(argv[0]).read_text()))
    print(rep)
    return 0 if rep.ok else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
