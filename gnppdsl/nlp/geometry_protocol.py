"""The protocol through which the nlp layer reaches the geometry primitives.

Why a protocol: resolved factor bodies call `fk`, `sdist`, `sdist2` (and `link` to name a robot
link as a collision body), but forward kinematics and collision distances need robot models and
shapes that live in `gnppdsl.geometry` (pinocchio, coal). The nlp layer sits *above* the data it
needs for those, so the geometry implementation is injected: `lowering` calls the symbolic
methods while a body is lowered to casadi (one Function per body structure, `body_compiler`), and the independent numpy
evaluator (`gnppdsl.nlp.evaluate`) calls the numeric methods to re-check solutions.

Layouts (see `gnppdsl.ir.builtins`): SE2 `[x, y, theta]`; SE3 `[x, y, z, qx, qy, qz, qw]`.

Symbolic types: the nlp layer passes casadi `SX` arguments when it can (fast, fully expanded
derivatives) and `MX` arguments when `needs_mx(primitive)` is True for any primitive used in a
body (e.g. a coal distance wrapped in a `casadi.Callback`, which only exists as an MX node). An
implementation whose primitive returns plain casadi expressions must accept both SX and MX.
All vector arguments are casadi column vectors; results are column vectors (7x1 for `fk`, 1x1
for distances).

Optional: `structure_key(name) -> hashable`. Names with equal keys (e.g. blocks of one size,
two arms of one model) must give identical symbolic `fk`/`sdist`/`sdist2` for equal arguments;
the nlp layer then compiles one Function for bodies that differ only in such names. Without it,
every object and robot name is structural.

Optional, for cheaper derivatives (SX bodies): `sdist_parts(body_a, body_b, planar) ->
(callback, to_rp, model)` splits a distance at its stop gradient (see `GeometryContext`), and
`fk_rp(robot, q, frame, base) -> (R, p)` gives a frame without the quaternion; the nlp layer
then differentiates `model` with the callback's output held constant.
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Protocol, runtime_checkable

import numpy as np


@dataclass(frozen=True)
class Body:
    """A collision body of `sdist`/`sdist2`: a scene object, or a link of a robot.

    `Body("b1")` is the object b1 (or a planar robot's own shape when `b1` names a robot);
    `Body("panda", link="panda_hand")` is a link, written `link(panda, "panda_hand")` in bodies.
    """

    name: str
    link: str | None = None

    def __str__(self) -> str:
        return self.name if self.link is None else f"link({self.name}, {self.link!r})"

    @staticmethod
    def of(e: Any) -> "Body | None":
        """The body a resolved expression names: an object `b1`, or `link(robot, "name")`;
        None for anything else (the caller reports it in its own error type). One reading of
        the body syntax for the casadi compiler, the numpy evaluator and the tests' oracle."""
        from gnppdsl.ir.expr import Call, Obj, Str

        if isinstance(e, Obj):
            return Body(e.name)
        if isinstance(e, Call) and e.fn == "link" and len(e.args) == 2 \
                and isinstance(e.args[0], Obj) and isinstance(e.args[1], Str):
            return Body(e.args[0].name, link=e.args[1].value)
        return None


@runtime_checkable
class Geometry(Protocol):
    """What `gnppdsl.geometry` provides to the nlp layer (symbolic and numeric paths)."""

    def needs_mx(self, primitive: str) -> bool:
        """True if the symbolic `primitive` ("fk", "sdist", "sdist2") only works on MX."""
        ...

    # -- symbolic (casadi SX or MX) --------------------------------------------------------
    def fk(self, robot: str, q: Any, frame: str, base: Any) -> Any:
        """World SE3 pose (7x1) of `frame` of `robot` at joints `q`, robot base pose `base`."""
        ...

    def sdist(self, body_a: Body, pose_a: Any, body_b: Body, pose_b: Any) -> Any:
        """Signed distance (1x1, negative when penetrating) between two bodies at SE3 poses."""
        ...

    def sdist2(self, body_a: Body, pose_a: Any, body_b: Body, pose_b: Any) -> Any:
        """Planar signed distance (1x1) between two bodies at SE2 poses (shapes extruded in z)."""
        ...

    # -- numeric (numpy), used by the independent checker --------------------------------
    def fk_numeric(self, robot: str, q: np.ndarray, frame: str, base: np.ndarray) -> np.ndarray:
        ...

    def sdist_numeric(self, body_a: Body, pose_a: np.ndarray, body_b: Body,
                      pose_b: np.ndarray) -> float:
        ...

    def sdist2_numeric(self, body_a: Body, pose_a: np.ndarray, body_b: Body,
                       pose_b: np.ndarray) -> float:
        ...


GEOMETRY_PRIMITIVES = ("fk", "sdist", "sdist2")
"""Builtins delegated to the injected `Geometry` (plus `link`, which only names a body)."""

DISTANCE_PRIMITIVES = frozenset({"sdist", "sdist2"})
"""The signed-distance queries among them (`SolverOptions.distance_curvature`)."""
