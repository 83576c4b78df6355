"""`GeometryContext`: the scene's robots and shapes behind the nlp layer's geometry protocol.

Why structural typing: the protocol (`gnppdsl.nlp.geometry_protocol.Geometry`) lives in the nlp
layer, which sits above geometry; importing it here would invert the layering. This class has
the protocol's methods (`needs_mx`, `fk`, `sdist`, `sdist2` and their `_numeric` twins) and
accepts any body object with `.name` and `.link` attributes (the nlp `Body`), a plain object
name, or a tuple `("link", robot, link_name)`.

Symbolic results are casadi expressions valid for SX and MX arguments (casadi embeds the coal
callback as a call node in SX too). Numeric results go straight through pinocchio and coal.
"""
from __future__ import annotations

from typing import Any

import casadi as ca
import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.geometry.distance import (ConvexBody, WitnessCallback, se2_to_matrix, se2_to_rp, signed_distance,
                                       signed_distance_at,
                                       signed_distance_expr)
from gnppdsl.geometry.features import N_OUT, model_expression
from gnppdsl.geometry.kinematics import FrameChain, fk_function, fk_rp_function, fn_name, quat_to_rotation
from gnppdsl.geometry.robots import RobotModel, load_robot, se3_to_matrix
from gnppdsl.geometry.shapes import coal_shape
from gnppdsl.ir.scene_model import Scene


def body_key(body: Any) -> tuple[str, str | None]:
    """Normalise a body designation to (name, link or None)."""
    if isinstance(body, str):
        return body, None
    if isinstance(body, tuple):
        if len(body) == 3 and body[0] == "link":
            return str(body[1]), str(body[2])
        if len(body) == 2:
            return str(body[0]), (None if body[1] is None else str(body[1]))
    if hasattr(body, "name"):
        return str(body.name), getattr(body, "link", None)
    raise TypeError(f"not a collision body: {body!r}")


class GeometryContext:
    """Geometry of one scene: robot models, convex bodies, cached casadi functions."""

    def __init__(self, scene: Scene, models: dict[str, RobotModel] | None = None, far_field: float | None = None):
        """`far_field` (metres, default off): symbolic `sdist`/`sdist2` of bodies whose bounding
        spheres are farther apart than this return the bounding-sphere distance instead of
        querying coal (a smooth lower bound; sound for `sdist >= m` with m < far_field, several
        times cheaper for the many far pairs of a large NLP). Numeric distances stay exact."""
        self.scene = scene
        self.far_field = far_field
        self.models: dict[str, RobotModel] = dict(models or {})
        for name, spec in scene.robots.items():
            if spec.kind == "urdf" and name not in self.models:
                self.models[name] = load_robot(spec)
        self._bodies: dict[tuple, ConvexBody] = {}
        self._callbacks: dict[tuple, WitnessCallback] = {}
        self._sdist_fn: dict[tuple, Any] = {}     # per body pair: Function; ("parts", planar): (input, model)
        self._fk_memo: dict[tuple, np.ndarray] = {}     # numeric fk_matrix by exact inputs
        self._pin_data: dict[str, Any] = {}             # one pinocchio Data per robot
        self._fk_last: dict[str, list] = {}             # fk_matrix's own Data per robot: [data,
                                                        # the q its frames are placed at, frame ids]
        self.verify_memo: dict[tuple, Any] = {}         # gnppdsl.geometry.verify's, by exact inputs
        self.native: Any = None                         # geometry.native library, once used

    # -- robots -------------------------------------------------------------------------------
    def robot(self, name: str) -> RobotModel:
        if name not in self.models:
            spec = self.scene.robots.get(name)
            if spec is None:
                raise UserError(f"unknown robot '{name}'")
            raise UserError(f"robot '{name}' is of kind '{spec.kind}' and has no kinematic model")
        return self.models[name]

    def robot_dims(self, name: str) -> tuple[int, np.ndarray, np.ndarray]:
        """(number of planner coordinates, lower limits, upper limits) of `joints(name)`."""
        r = self.robot(name)
        return r.nc, r.lower.copy(), r.upper.copy()

    def links(self, name: str) -> list[str]:
        """Links of a robot that carry collision geometry (valid `link(r, "...")` bodies)."""
        return list(self.robot(name).links)

    def self_collision_pairs(self, name: str) -> list[tuple[str, str]]:
        """Link pairs checked for self-collision (all pairs minus SRDF-disabled ones)."""
        return list(self.robot(name).self_pairs)

    def base(self, name: str) -> np.ndarray:
        """The scene base pose (SE3 7-vector) of a robot."""
        return np.asarray(self.scene.robots[name].base, dtype=float)

    # -- bodies -------------------------------------------------------------------------------
    def body(self, body: Any, planar: bool = False) -> ConvexBody:
        name, link = body_key(body)
        key = (name, link, planar)
        if key in self._bodies:
            return self._bodies[key]
        if link is not None:
            if planar:
                raise UserError(f"link({name}, {link!r}): robot links have no planar (sdist2) shape")
            r = self.robot(name)
            if link not in r.links:
                import difflib
                close = difflib.get_close_matches(link, list(r.links), n=1)
                hint = f" (did you mean '{close[0]}'?)" if close else ""
                raise UserError(f"robot {name} has no link '{link}' with collision geometry{hint}")
            gs = r.links[link]
            cb = ConvexBody(f"{name}/{link}", [g.shape for g in gs], [g.placement for g in gs])
        else:
            ent = self.scene.entity(name)
            if ent is None:
                raise UserError(f"unknown collision body '{name}'")
            shape = ent.shape
            if shape is None:
                raise UserError(f"'{name}' is a robot with a kinematic model: name one of its links, "
                                f"e.g. link({name}, \"{next(iter(self.robot(name).links), '...')}\")")
            s = coal_shape(shape, planar)
            if s is None:
                raise UserError(f"'{name}' has shape 'none' and cannot collide")
            cb = ConvexBody(name, [s], [np.eye(4)])
        self._bodies[key] = cb
        return cb

    def _callback(self, a: Any, b: Any, planar: bool) -> WitnessCallback:
        ka, kb = body_key(a), body_key(b)
        key = (ka, kb, planar)
        if key not in self._callbacks:
            name = fn_name("sdist2" if planar else "sdist", ka[0], ka[1] or "", kb[0], kb[1] or "")
            self._callbacks[key] = WitnessCallback(name, self.body(a, planar), self.body(b, planar), planar=planar,
                                                   far_field=self.far_field)
        return self._callbacks[key]

    def structure_key(self, name: str) -> tuple:
        """What the symbolic geometry of a body or robot named `name` depends on, beyond its
        pose: a robot's model (URDF/SRDF, locked joints, base joint; not its name, base pose or
        home), an object's shape. Two names with equal keys give the same `fk`, `sdist` and
        `sdist2` expressions for equal pose arguments, so the nlp layer compiles a body once for
        e.g. all same-sized blocks, or both arms of the same model (the base pose is a lifted
        parameter of `fk`). Unknown names key to themselves (structural, as before)."""
        r = self.scene.robots.get(name)
        if r is not None:
            return ("robot", r.kind, r.model, r.urdf, r.srdf, tuple(r.package_dirs),
                    tuple(sorted(r.locked.items())), r.attributes.get("base_joint"),
                    repr(r.attributes.get("base_min")), repr(r.attributes.get("base_max")), r.shape)
        o = self.scene.objects.get(name)
        if o is not None:
            return ("object", o.shape)
        return ("name", name)

    def persist_key(self, name: str) -> str:
        """A digest of everything the symbolic geometry of `name` depends on, for keys that
        outlive the process (`gnppdsl.nlp.function_store`): `structure_key`, the far field,
        and for a robot the URDF and SRDF contents, its reduced pinocchio model (serialized),
        coordinates and root placement. Why more than `structure_key`: that names the robot's
        files, and a file edited between two processes must give another key."""
        import hashlib

        from gnppdsl.inputs import file_digest as digest

        parts = [repr(self.structure_key(name)), repr(self.far_field)]
        spec = self.scene.robots.get(name)
        if spec is not None:
            parts += [digest(spec.urdf), digest(spec.srdf)]
            r = self.models.get(name)
            if r is not None:
                parts += [hashlib.sha256(r.model.saveToString().encode()).hexdigest(),
                          repr(r.coords), np.asarray(r.base, float).tobytes().hex(), repr(r.nc)]
        return hashlib.sha256("\n".join(parts).encode()).hexdigest()

    # -- protocol: symbolic ---------------------------------------------------------------------
    def needs_mx(self, primitive: str) -> bool:
        """Nothing needs MX: casadi embeds the coal callback in SX graphs as a call node."""
        return False

    def fk(self, robot: str, q: Any, frame: str, base: Any) -> Any:
        r = self.robot(robot)
        if q.shape[0] != r.nc:
            raise UserError(f"fk({robot}): expected {r.nc} joint coordinates, got {q.shape[0]}")
        return fk_function(r, frame, with_base=True)(q, base)

    def _sdist_function(self, a: Any, b: Any, planar: bool) -> ca.Function:
        """Cached Function (poseA, poseB) -> d, so bodies share one graph per body pair."""
        key = (body_key(a), body_key(b), planar)
        if key not in self._sdist_fn:
            cb = self._callback(a, b, planar)
            n = 3 if planar else 7
            xa, xb = ca.SX.sym("pa", n), ca.SX.sym("pb", n)
            if planar:
                (RA, pA), (RB, pB) = se2_to_rp(xa), se2_to_rp(xb)
            else:
                RA, pA, RB, pB = quat_to_rotation(xa[3:7]), xa[0:3], quat_to_rotation(xb[3:7]), xb[0:3]
            d = signed_distance_expr(cb, RA, pA, RB, pB)
            self._sdist_fn[key] = ca.Function(cb.name(), [xa, xb], [d], ["pose_a", "pose_b"], ["d"])
        return self._sdist_fn[key]

    def sdist_parts(self, body_a: Any, body_b: Any, planar: bool = False
                    ) -> tuple[ca.Function, ca.Function, ca.Function]:
        """`sdist` (planar: `sdist2`) split at its stop gradient: (callback, to_rp, model) with
        to_rp(pose) -> (R, p) the world rotation and position of a pose, callback(x) -> o the
        local contact model (numbers, zero derivative) for x = [vec(RA), pA, vec(RB), pB]
        (column-major), and model(RA, pA, RB, pB, o) -> d, so that

            sdist(a, pose_a, b, pose_b) == model(RA, pA, RB, pB, callback(x))

        with o held constant under differentiation. Why: differentiating through the callback
        call node costs its dense zero Jacobian in every derivative graph; a caller that
        differentiates `model` with o as a plain symbol and substitutes o afterwards gets the
        same derivatives with Hessians about half the size. With (R, p) straight from `fk_rp`
        a link's pose also skips the rotation -> quaternion -> rotation round trip (another
        half). `to_rp` and `model` do not depend on the bodies (cached per planar flag)."""
        key = ("parts", planar)
        if key not in self._sdist_fn:
            v = ca.SX.sym("pose", 3 if planar else 7)
            R, p = se2_to_rp(v) if planar else (quat_to_rotation(v[3:7]), v[0:3])
            RA, RB = ca.SX.sym("RA", 3, 3), ca.SX.sym("RB", 3, 3)
            pA, pB, o = ca.SX.sym("pA", 3), ca.SX.sym("pB", 3), ca.SX.sym("o", N_OUT)
            sfx = "2" if planar else ""
            self._sdist_fn[key] = (
                ca.Function("pose_rp" + sfx, [v], [R, p]),
                ca.Function("sdist_model" + sfx, [RA, pA, RB, pB, o],
                            [model_expression(o, RA, pA, RB, pB)]))
        to_rp, model = self._sdist_fn[key]
        return self._callback(body_a, body_b, planar), to_rp, model

    def witness_fast(self, a: Any, b: Any, planar: bool = False) -> Any:
        """The stop-gradient distance query of a body pair for evaluation only: the native twin
        of its `WitnessCallback` (`sdist_parts`' first part) when the library is built and
        handles the pair (`geometry.native`: the same numbers, no Python per query), else the
        callback itself. Not differentiable: casadi cannot differentiate through the external
        function (the callback declares zero derivatives), so it serves Functions that are only
        evaluated, such as the stop-gradient values under compiled derivatives."""
        cb = self._callback(a, b, planar)
        if self.far_field is None:
            from gnppdsl.geometry import native
            lib = native.load()
            if lib is not None:
                fn = lib.function(cb.name(), cb.body_a, cb.body_b, planar)
                if fn is not None:
                    self.native = lib
                    return fn
        return cb

    def fk_chain(self, robot: str, q: Any, base: Any) -> FrameChain:
        """`chain.frame(name) -> (R, p)`: `fk_rp` of several frames at one (q, base) with the
        joint prefix shared (build-time helper; keep it only while building one expression)."""
        r = self.robot(robot)
        if q.shape[0] != r.nc:
            raise UserError(f"fk({robot}): expected {r.nc} joint coordinates, got {q.shape[0]}")
        return FrameChain(r, q, base)

    def fk_rp(self, robot: str, q: Any, frame: str, base: Any) -> tuple[Any, Any]:
        """`fk` as (R 3x3, p 3x1), without converting the rotation to a quaternion."""
        r = self.robot(robot)
        if q.shape[0] != r.nc:
            raise UserError(f"fk({robot}): expected {r.nc} joint coordinates, got {q.shape[0]}")
        return tuple(fk_rp_function(r, frame)(q, base))

    def sdist(self, body_a: Any, pose_a: Any, body_b: Any, pose_b: Any) -> Any:
        return self._sdist_function(body_a, body_b, False)(pose_a, pose_b)

    def sdist2(self, body_a: Any, pose_a: Any, body_b: Any, pose_b: Any) -> Any:
        return self._sdist_function(body_a, body_b, True)(pose_a, pose_b)

    # -- protocol: numeric (pinocchio + coal directly) --------------------------------------------
    def fk_numeric(self, robot: str, q: np.ndarray, frame: str, base: np.ndarray) -> np.ndarray:
        """Pinocchio forward kinematics; the quaternion uses the same branch (and sign) convention
        as the casadi `fk`, so both paths give the same 7-vector."""
        from gnppdsl.geometry.kinematics import rotation_to_quat_numeric
        T = self.fk_matrix(robot, q, frame, base)
        return np.r_[T[:3, 3], rotation_to_quat_numeric(T[:3, :3])]

    def forget_evaluations(self) -> None:
        """Empty the memos of evaluated values (numeric forward kinematics, the distance
        callbacks' answers), keeping the compiled Functions. Why: the memos exist for the
        repeated evaluations inside one solve; a solve that found its answers in an earlier
        solve's memo would be timed for work it did not do (lab1 is deterministic across seeds:
        seeds 1-9 would find every coal query answered)."""
        self._fk_memo.clear()
        for last in self._fk_last.values():
            last[1] = None
        self.verify_memo.clear()
        for cb in self._callbacks.values():
            cb.forget()
        if self.native is not None:
            self.native.forget()

    def fk_matrix(self, robot: str, q: np.ndarray, frame: str, base: np.ndarray | None = None) -> np.ndarray:
        """4x4 world placement of a frame computed by pinocchio (not casadi).

        Memoised by the exact input bytes (a pure function of them): the numeric checker
        evaluates every factor at one solution, so the same (robot, q, frame, base) comes back
        for each factor reading it (lab2: 9360 calls per solve). One pinocchio Data per robot of
        this method's own (`link_placements` places the other), which remembers the q its frames
        were last placed at: a miss at that q reads the frame without running forward kinematics
        again (the same numbers: pinocchio places every frame of the model at once). Why: the
        checker asks one waypoint's q for each collision link in turn (`path_clear` of an arm,
        link1..hand), and every one ran the whole kinematics (lab5_paper: 20616 calls, 1.9 s)."""
        import pinocchio as pin
        qa = np.asarray(q, dtype=float)
        at = (qa.tobytes(), qa.shape)
        key = (robot, frame, at,
               None if base is None else (np.asarray(base, dtype=float).tobytes(), np.shape(base)))
        hit = self._fk_memo.get(key)
        if hit is not None:
            return hit.copy()
        r = self.robot(robot)
        last = self._fk_last.get(robot)
        if last is None:
            last = self._fk_last[robot] = [r.model.createData(), None, {}]
        data, placed_at, ids = last
        if placed_at != at:
            last[1] = None                    # (to_pin_q may raise: then nothing is placed)
            pin.framesForwardKinematics(r.model, data, r.to_pin_q(qa))
            last[1] = at
        fid = ids.get(frame)
        if fid is None:
            fid = ids[frame] = r.frame_id(frame)
        B = r.base if base is None else se3_to_matrix(base)
        T = B @ np.array(data.oMf[fid].homogeneous)
        if len(self._fk_memo) >= 20000:
            self._fk_memo.pop(next(iter(self._fk_memo)))     # oldest first
        self._fk_memo[key] = T
        return T.copy()

    def sdist_numeric(self, body_a: Any, pose_a: np.ndarray, body_b: Any, pose_b: np.ndarray) -> float:
        return signed_distance_at(self.body(body_a), pose_a, self.body(body_b), pose_b)

    def sdist2_numeric(self, body_a: Any, pose_a: np.ndarray, body_b: Any, pose_b: np.ndarray) -> float:
        Ta, Tb = se2_to_matrix(pose_a), se2_to_matrix(pose_b)
        return signed_distance(self.body(body_a, True), Ta[:3, :3], Ta[:3, 3], self.body(body_b, True),
                               Tb[:3, :3], Tb[:3, 3])
