"""The builtin functions of the expression language, with their signatures.

This table is the single contract between the type checker (which resolves overloaded surface
syntax such as `a * b`, `inv(p)`, `pos(p)` to one of these monomorphic names) and the nlp layer
(which implements each of them in casadi, `gnppdsl.nlp.lowering`). A test checks that every
name here has a casadi implementation.

Value spaces and their vector layout (fixed, documented in docs/reference.md):
- `R`        scalar
- `R[n]`     vector of n reals
- `SE2`      [x, y, theta]
- `SE3`      [x, y, z, qx, qy, qz, qw]   (pinocchio's XYZQUAT order)
- `quat`     [qx, qy, qz, qw]
- `joints`   R[nq] of a robot (dimension and limits from its model)
Trajectories of `waypoints W` over a space of dimension d are stored as W*d reals; `waypoint`
extracts one point.

Geometry primitives (`fk`, `sdist`) are implemented by `gnppdsl.geometry` and reached from the
nlp layer; in resolved bodies their object arguments are `Obj` / `Str` constants.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Space:
    """A value space. `dim` is the vector length; `kind` says how to interpret it."""

    kind: str          # "R", "SE2", "SE3", "quat", "joints", "object", "string", "int"
    dim: int = 1
    robot: str | None = None   # for "joints": the robot parameter/object it belongs to

    def __str__(self) -> str:
        if self.kind == "R":
            return "R" if self.dim == 1 else f"R[{self.dim}]"
        if self.kind == "joints":
            return f"joints({self.robot})"
        return self.kind


SCALAR = Space("R", 1)
SE2 = Space("SE2", 3)
SE3 = Space("SE3", 7)
QUAT = Space("quat", 4)


def R(n: int) -> Space:
    return Space("R", n)


@dataclass(frozen=True)
class Builtin:
    name: str
    arity: int               # -1: variadic
    doc: str


_B = [
    # arithmetic (elementwise on equal-length vectors; scalar broadcasts)
    Builtin("add", 2, "a + b"),
    Builtin("sub", 2, "a - b"),
    Builtin("mul", 2, "a * b elementwise or scalar * vector"),
    Builtin("div", 2, "a / b"),
    Builtin("neg", 1, "-a"),
    Builtin("pow", 2, "a ^ b (b a constant)"),
    Builtin("sqrt", 1, "square root"),
    Builtin("sin", 1, "sine"),
    Builtin("cos", 1, "cosine"),
    Builtin("atan2", 2, "atan2(y, x)"),
    Builtin("abs", 1, "absolute value (piecewise differentiable)"),
    Builtin("exp", 1, "exponential"),
    Builtin("min", 2, "minimum (piecewise differentiable)"),
    Builtin("max", 2, "maximum (piecewise differentiable)"),
    # vectors
    Builtin("norm", 1, "Euclidean norm of R[n]"),
    Builtin("sqnorm", 1, "squared Euclidean norm of R[n]"),
    Builtin("dot", 2, "dot product of R[n], R[n]"),
    Builtin("cross", 2, "cross product of R[3], R[3]"),
    Builtin("sum", 1, "sum of the components of R[n]"),
    Builtin("concat", -1, "concatenation of vectors / scalars"),
    # SE2 poses [x, y, theta]
    Builtin("se2", 3, "SE2 from x, y, theta"),
    Builtin("compose_se2", 2, "a * b for SE2"),
    Builtin("inv_se2", 1, "inverse SE2 pose"),
    Builtin("pos_se2", 1, "translation R[2] of an SE2 pose"),
    Builtin("angle_se2", 1, "rotation angle of an SE2 pose"),
    Builtin("apply_se2", 2, "SE2 pose applied to a point R[2]"),
    Builtin("angle_diff", 2, "wrapped difference of two angles, in (-pi, pi] (smooth: atan2(sin, cos))"),
    # SE3 poses [x, y, z, qx, qy, qz, qw]
    Builtin("se3", 2, "SE3 from position R[3] and quaternion"),
    Builtin("compose_se3", 2, "a * b for SE3"),
    Builtin("inv_se3", 1, "inverse SE3 pose"),
    Builtin("pos_se3", 1, "translation R[3] of an SE3 pose"),
    Builtin("rot_se3", 1, "rotation quaternion of an SE3 pose"),
    Builtin("apply_se3", 2, "SE3 pose applied to a point R[3]"),
    Builtin("axis_se3", 2, "i-th axis (column of the rotation matrix, i constant 0..2) of a pose"),
    # quaternions [qx, qy, qz, qw]
    Builtin("quat_mul", 2, "Hamilton product"),
    Builtin("quat_conj", 1, "conjugate"),
    Builtin("quat_rotate", 2, "rotate R[3] by a unit quaternion"),
    Builtin("quat_dist", 2, "1 - <q1, q2>^2: zero iff the rotations are equal"),
    Builtin("quat_axis", 2, "i-th axis (column of the rotation matrix) of a quaternion"),
    # trajectories
    Builtin("waypoint", 2, "waypoint(traj, k): k-th point (constant k, negative from the end)"),
    # geometry primitives (implemented in gnppdsl.geometry)
    Builtin("fk", 4, "fk(robot Obj, q joints, frame Str, base SE3) -> SE3 world pose of a frame"),
    Builtin("sdist", 4,
            "sdist(bodyA, poseA SE3, bodyB, poseB SE3) -> signed distance between two shapes; "
            "a body is Obj(object) or Call('link', (Obj(robot), Str(link)))"),
    Builtin("sdist2", 4,
            "sdist2(bodyA, poseA SE2, bodyB, poseB SE2): planar signed distance (shapes extruded in z)"),
    Builtin("link", 2, "link(robot Obj, name Str): a robot link as a collision body"),
]

BUILTINS: dict[str, Builtin] = {b.name: b for b in _B}
