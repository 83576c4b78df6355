"""Forward kinematics as casadi expressions, built from a pinocchio model.

Why hand-built: the PyPI wheel of pinocchio has no casadi bindings, and the NLP needs FK with
exact derivatives inside casadi. We chain, as pinocchio does, `jointPlacements[i]` * joint
motion(q_i) from the root, then append `frames[f].placement`. Every joint type a bundled robot
uses is covered (revolute about X/Y/Z or an unaligned axis, continuous (unbounded) revolute,
prismatic, planar and free-flyer roots); the tests compare against pinocchio to 1e-9.

Poses inside are (R 3x3, p 3x1) pairs: rotation matrices are polynomial in sin/cos of the joint
angles, so derivatives are clean. The 7-vector SE3 `[x, y, z, qx, qy, qz, qw]` of the language
is produced only at the end (`rotation_to_quat`), and consumed by `quat_to_rotation`, which is
smooth and sign-invariant, so FK -> quaternion -> rotation is exactly the identity on SO(3) with
exact derivatives (no rotation has a globally continuous quaternion, but every consumer of an
SE3 value in the builtins is invariant under q -> -q).
"""
from __future__ import annotations

import casadi as ca
import numpy as np

from gnppdsl.geometry.robots import RobotModel


def axis_rotation(axis, c, s):
    """Rodrigues' rotation about a constant unit axis, from cos and sin of the angle."""
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    K = np.array([[0, -a[2], a[1]], [a[2], 0, -a[0]], [-a[1], a[0], 0]])
    return ca.DM(np.eye(3)) + s * ca.DM(K) + (1 - c) * ca.DM(K @ K)


def quat_to_rotation(q):
    """Unit-or-not quaternion [qx, qy, qz, qw] -> rotation matrix (normalised by |q|^2: smooth
    everywhere except q = 0 and invariant under q -> -q and q -> s q)."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    n = x * x + y * y + z * z + w * w
    s = 2 / n
    return ca.vertcat(
        ca.horzcat(1 - s * (y * y + z * z), s * (x * y - z * w), s * (x * z + y * w)),
        ca.horzcat(s * (x * y + z * w), 1 - s * (x * x + z * z), s * (y * z - x * w)),
        ca.horzcat(s * (x * z - y * w), s * (y * z + x * w), 1 - s * (x * x + y * y)),
    )


def rotation_to_quat(R):
    """Rotation matrix -> quaternion [qx, qy, qz, qw] (Shepperd's method, branch by the largest
    diagonal term, so every branch divides by a number >= 1/2: well conditioned with exact
    derivatives inside a branch). The sign may flip between branches (unavoidable); consumers
    are sign-invariant."""
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    eps = 1e-12

    def branch_w():
        w = ca.sqrt(ca.fmax(1 + tr, eps)) / 2
        return ca.vertcat((R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w),
                          (R[1, 0] - R[0, 1]) / (4 * w), w)

    def branch_x():
        x = ca.sqrt(ca.fmax(1 + R[0, 0] - R[1, 1] - R[2, 2], eps)) / 2
        return ca.vertcat(x, (R[0, 1] + R[1, 0]) / (4 * x), (R[0, 2] + R[2, 0]) / (4 * x),
                          (R[2, 1] - R[1, 2]) / (4 * x))

    def branch_y():
        y = ca.sqrt(ca.fmax(1 - R[0, 0] + R[1, 1] - R[2, 2], eps)) / 2
        return ca.vertcat((R[0, 1] + R[1, 0]) / (4 * y), y, (R[1, 2] + R[2, 1]) / (4 * y),
                          (R[0, 2] - R[2, 0]) / (4 * y))

    def branch_z():
        z = ca.sqrt(ca.fmax(1 - R[0, 0] - R[1, 1] + R[2, 2], eps)) / 2
        return ca.vertcat((R[0, 2] + R[2, 0]) / (4 * z), (R[1, 2] + R[2, 1]) / (4 * z), z,
                          (R[1, 0] - R[0, 1]) / (4 * z))

    d0, d1, d2 = R[0, 0], R[1, 1], R[2, 2]
    use_w = ca.logic_and(tr >= d0, ca.logic_and(tr >= d1, tr >= d2))
    use_x = ca.logic_and(d0 >= d1, d0 >= d2)
    use_y = d1 >= d2
    return ca.if_else(use_w, branch_w(), ca.if_else(use_x, branch_x(), ca.if_else(use_y, branch_y(), branch_z())))


def rotation_to_quat_numeric(R) -> np.ndarray:
    """numpy twin of `rotation_to_quat` (same branches, same signs), so the numeric checker and
    the casadi path report the same quaternion for the same rotation."""
    R = np.asarray(R, dtype=float)
    tr = R[0, 0] + R[1, 1] + R[2, 2]
    d0, d1, d2 = R[0, 0], R[1, 1], R[2, 2]
    eps = 1e-12
    if tr >= d0 and tr >= d1 and tr >= d2:
        w = np.sqrt(max(1 + tr, eps)) / 2
        return np.array([(R[2, 1] - R[1, 2]) / (4 * w), (R[0, 2] - R[2, 0]) / (4 * w), (R[1, 0] - R[0, 1]) / (4 * w), w])
    if d0 >= d1 and d0 >= d2:
        x = np.sqrt(max(1 + d0 - d1 - d2, eps)) / 2
        return np.array([x, (R[0, 1] + R[1, 0]) / (4 * x), (R[0, 2] + R[2, 0]) / (4 * x), (R[2, 1] - R[1, 2]) / (4 * x)])
    if d1 >= d2:
        y = np.sqrt(max(1 - d0 + d1 - d2, eps)) / 2
        return np.array([(R[0, 1] + R[1, 0]) / (4 * y), y, (R[1, 2] + R[2, 1]) / (4 * y), (R[0, 2] - R[2, 0]) / (4 * y)])
    z = np.sqrt(max(1 - d0 - d1 + d2, eps)) / 2
    return np.array([(R[0, 2] + R[2, 0]) / (4 * z), (R[1, 2] + R[2, 1]) / (4 * z), z, (R[1, 0] - R[0, 1]) / (4 * z)])


def se3_vec_to_rp(v):
    """[x, y, z, qx, qy, qz, qw] -> (R, p)."""
    return quat_to_rotation(v[3:7]), v[0:3]


def rp_to_se3_vec(R, p):
    return ca.vertcat(p, rotation_to_quat(R))


def _const(M: np.ndarray):
    M = np.asarray(M, dtype=float)
    return ca.DM(M[:3, :3]), ca.DM(M[:3, 3])


def _compose(a, b):
    Ra, pa = a
    Rb, pb = b
    return ca.mtimes(Ra, Rb), pa + ca.mtimes(Ra, pb)


def joint_motion(jc, c):
    """The joint transform for planner coordinates `c` (a casadi vector of length jc.nc)."""
    if jc.kind in ("revolute", "revolute_unbounded"):
        return axis_rotation(jc.axis, ca.cos(c[0]), ca.sin(c[0])), ca.DM.zeros(3, 1)
    if jc.kind == "prismatic":
        return ca.DM(np.eye(3)), c[0] * ca.DM(np.asarray(jc.axis, dtype=float) / np.linalg.norm(jc.axis))
    if jc.kind == "planar":
        return axis_rotation((0, 0, 1), ca.cos(c[2]), ca.sin(c[2])), ca.vertcat(c[0], c[1], 0)
    if jc.kind == "translation":
        return ca.DM(np.eye(3)), c[0:3]
    if jc.kind == "free":
        return quat_to_rotation(c[3:7]), c[0:3]
    if jc.kind == "spherical":
        return quat_to_rotation(c[0:4]), ca.DM.zeros(3, 1)
    raise ValueError(f"unsupported joint kind {jc.kind}")


def fk_rp(robot: RobotModel, c, frame: str, base=None):
    """World pose (R, p) of `frame` for planner coordinates `c` (casadi SX/MX vector).

    `base`: None -> the robot's scene base placement; else a casadi/np 7-vector SE3 or an (R, p) pair.
    """
    model = robot.model
    fid = robot.frame_id(frame)
    target_joint = model.frames[fid].parentJoint
    # Joints on the chain from the root to the target joint (pinocchio: parents[j] < j).
    chain = []
    j = target_joint
    while j > 0:
        chain.append(j)
        j = model.parents[j]
    chain.reverse()
    by_joint = {jc_idx + 1: jc for jc_idx, jc in enumerate(robot.coords)}   # joint id -> coords
    if base is None:
        M = _const(robot.base)
    elif isinstance(base, tuple):
        M = base
    else:
        M = se3_vec_to_rp(base)
    for jid in chain:
        jc = by_joint[jid]
        M = _compose(M, _const(model.jointPlacements[jid].homogeneous))
        M = _compose(M, joint_motion(jc, c[jc.idx_c:jc.idx_c + jc.nc]))
    return _compose(M, _const(model.frames[fid].placement.homogeneous))


class FrameChain:
    """World poses (R, p) of several frames of one robot at one (joints, base), sharing the
    joint prefix: every joint transform is composed once, however many frames hang below it
    (the same operations, in the same order, as `fk_rp` for each frame). Why: a body that
    keeps links 5, 6, 7 and the hand of an arm clear recomputed joints 1-5 four times, and
    their second derivatives too. Lives as long as the caller's expression building."""

    def __init__(self, robot: RobotModel, c, base):
        self.robot, self.c = robot, c
        M0 = _const(robot.base) if base is None else base if isinstance(base, tuple) \
            else se3_vec_to_rp(base)
        self._after = {0: M0}               # joint id -> pose after that joint (0: the base)
        self._by_joint = {i + 1: jc for i, jc in enumerate(robot.coords)}

    def _joint(self, jid: int):
        M = self._after.get(jid)
        if M is None:
            jc = self._by_joint[jid]
            R, p = self._joint(self.robot.model.parents[jid])
            M = self._after[jid] = tuple(_joint_step(self.robot, jid)(R, p, self.c[jc.idx_c:jc.idx_c + jc.nc]))
        return M

    def frame(self, frame: str):
        R, p = self._joint(self.robot.model.frames[self.robot.frame_id(frame)].parentJoint)
        return tuple(_frame_step(self.robot, frame)(R, p))


def _joint_step(robot: RobotModel, jid: int) -> ca.Function:
    """Cached (R, p, joint coordinates) -> pose after joint `jid` (its placement, then its
    motion): one call per joint keeps `FrameChain` cheap to build from Python."""
    def build():
        jc = {i + 1: j for i, j in enumerate(robot.coords)}[jid]
        R, p, c = ca.SX.sym("R", 3, 3), ca.SX.sym("p", 3), ca.SX.sym("c", jc.nc)
        M = _compose((R, p), _const(robot.model.jointPlacements[jid].homogeneous))
        M = _compose(M, joint_motion(jc, c))
        return ca.Function(fn_name("joint", robot.name, str(jid)), [R, p, c], list(M))
    return _cached(robot, ("joint_step", jid), build)


def _frame_step(robot: RobotModel, frame: str) -> ca.Function:
    """Cached (R, p) of a frame's parent joint -> (R, p) of the frame."""
    def build():
        R, p = ca.SX.sym("R", 3, 3), ca.SX.sym("p", 3)
        M = _compose((R, p), _const(robot.model.frames[robot.frame_id(frame)].placement.homogeneous))
        return ca.Function(fn_name("frame", robot.name, frame), [R, p], list(M))
    return _cached(robot, ("frame_step", frame), build)


def fk_expression(robot: RobotModel, c, frame: str, base=None):
    """World SE3 7-vector [x, y, z, qx, qy, qz, qw] of `frame` as a casadi expression."""
    R, p = fk_rp(robot, c, frame, base)
    return rp_to_se3_vec(R, p)


def fn_name(*parts: str) -> str:
    """A valid casadi Function name (letters, digits, single underscores) from free text."""
    import re
    s = re.sub(r"[^A-Za-z0-9]+", "_", "_".join(parts)).strip("_")
    return "f_" + s if s else "f"


def _cached(robot: RobotModel, key, build):
    cache = robot.__dict__.setdefault("_casadi_cache", {})
    if key not in cache:
        cache[key] = build()
    return cache[key]


def fk_function(robot: RobotModel, frame: str, with_base: bool = True) -> ca.Function:
    """A cached casadi Function q (, base) -> SE3 7-vector; callable on SX, MX or numbers."""
    def build():
        c = ca.SX.sym("q", robot.nc)
        if with_base:
            b = ca.SX.sym("base", 7)
            return ca.Function(fn_name("fk", robot.name, frame), [c, b], [fk_expression(robot, c, frame, b)],
                               ["q", "base"], ["pose"])
        return ca.Function(fn_name("fk", robot.name, frame), [c], [fk_expression(robot, c, frame)], ["q"], ["pose"])
    return _cached(robot, ("fk", frame, with_base), build)


def fk_rp_function(robot: RobotModel, frame: str) -> ca.Function:
    """Cached casadi Function (q, base 7-vector) -> (R 3x3, p 3) of a frame: the matrix form,
    used by the signed distance so no quaternion round trip is needed for links."""
    def build():
        c = ca.SX.sym("q", robot.nc)
        b = ca.SX.sym("base", 7)
        R, p = fk_rp(robot, c, frame, b)
        return ca.Function(fn_name("fkrp", robot.name, frame), [c, b], [R, p], ["q", "base"], ["R", "p"])
    return _cached(robot, ("fkrp", frame), build)
