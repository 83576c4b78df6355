"""Resolved (stage-2) factor bodies -> casadi Functions, one per body structure.

Why one Function per *structure*: a graph-NLP holds many instances of few templates (paper 000,
Sec. VIII: fewer than 20 constraint types). Numeric constants that only scale values (radii,
tolerances, fixed poses) are lifted into a parameter vector `p`, so e.g. every `no_overlap`
instance shares one compiled Function and differs only in `p`. Constants that change the
*shape* of the computation stay in the cache key: exponents of `pow`, waypoint and axis
indices, `Index` positions, frame names of geometry primitives, object and robot names (by
the geometry's `structure_key` when it has one: same-shaped blocks and same-model arms share a
Function), and the slot signatures (dimension, waypoints) of the factor's variables.

Derivatives (`BodyCompiler.jacobian`, `.hessian`) are built once per compiled body; bodies
whose constraints repeat per waypoint (`forall k ... path[k]`) differentiate one representative
per repeated form (`row_groups`).

A compiled body is `f(x_0, ..., x_{m-1}, p) -> h`, `h` the stacked constraint rows, each row
of kind "eq" (h = 0) or "ineq" (h <= 0). `lhs == rhs` gives rows lhs - rhs (eq), `lhs <= rhs`
rows lhs - rhs (ineq) and `lhs >= rhs` rows rhs - lhs (ineq).

Functions are built from SX (fully expanded, fastest) unless the injected geometry says a used
primitive needs MX (a `casadi.Callback`); either kind can be called on MX symbols during
assembly (`gnppdsl.nlp.feasibility`).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Callable, Iterable, Iterator

import casadi as ca
import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.errors import UserError
from gnppdsl.ir.builtins import BUILTINS
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Str, Vec
from gnppdsl.nlp.geometry_protocol import GEOMETRY_PRIMITIVES, Body, Geometry

NORM_EPS = 1e-18
"""Added under the square root of `norm` so its gradient exists at 0 (value bias <= 1e-9)."""


class BodyError(UserError):
    """A resolved body the nlp layer cannot turn into casadi (wrong arity, bad constant...)."""

    def __init__(self, message: str, node: Any = None):
        span = getattr(node, "span", None)
        super().__init__(f"{span}: {message}" if span is not None else message)


@dataclass(frozen=True)
class _Param:
    """Placeholder for the k-th lifted numeric constant (cache keys only)."""

    index: int


@dataclass(frozen=True)
class _Point:
    """Placeholder for the k-th distinct waypoint a constraint reads (row-group keys only)."""

    index: int


@dataclass(frozen=True)
class SlotSignature:
    dim: int
    waypoints: int

    @staticmethod
    def of(v: VarInstance) -> "SlotSignature":
        return SlotSignature(v.dim, v.waypoints)

    @property
    def point_dim(self) -> int:
        return self.dim // self.waypoints if self.waypoints else self.dim


@dataclass(frozen=True)
class GroupMember:
    """Where one block of a row group sits in its body: its first row, the (slot,
    waypoint) behind each `_Point` of the group key, the body slots it reads whole (in the
    representative's slot order) and the body parameters behind the representative's."""

    row0: int
    points: tuple[tuple[int, int], ...]
    slots: tuple[int, ...]
    params: tuple[int, ...]


@dataclass(frozen=True)
class RowGroup:
    """Blocks of constraints of one body that are identical up to the waypoints they read
    (and the values of their lifted constants): e.g. the 18 copies of `sdist(..) with q =
    path[k]` of a `forall k` template. `key` = (block's constraints with `_Point`s, renumbered
    slots and parameters, point dims, whole-slot signatures, parameter count) defines one
    representative function (points..., slots..., p) -> rows, differentiated once for all
    members (see `row_groups` for the blocks)."""

    key: tuple
    n_rows: int
    members: tuple[GroupMember, ...]


@dataclass(frozen=True)
class CompiledBody:
    """One casadi Function for a body structure, with the kind of each output row."""

    function: ca.Function
    kinds: tuple[str, ...]          # "eq" | "ineq", one per row of h
    n_params: int
    symbolic: str                   # "SX" | "MX"
    primitives: frozenset[str] = frozenset()   # geometry primitives used (fk, sdist, sdist2)
    groups: tuple[RowGroup, ...] = field(default=(), compare=False)   # see `row_groups`
    # with stop-gradient symbols (see `_Builder.open_stops`): (x.., p, o) -> h with the callback
    # outputs o as an input, and (x.., p) -> o; `function` is the first with o substituted
    open_function: ca.Function | None = field(default=None, compare=False)
    stops: ca.Function | None = field(default=None, compare=False)
    # `function`'s values for evaluation only: the open function of the fast stop-gradient
    # values (`GeometryContext.witness_fast`, native distance queries); not differentiable
    evaluate: ca.Function | None = field(default=None, compare=False)

    @property
    def n_rows(self) -> int:
        return len(self.kinds)


# Argument positions whose constant must stay structural (not lifted): fn -> arg indices.
_STATIC_ARGS: dict[str, tuple[int, ...]] = {
    "pow": (1,), "waypoint": (1,), "axis_se3": (1,), "quat_axis": (1,),
}


def static_value(e: Any) -> float:
    """Fold a constant expression (Num, arithmetic on Nums) to a float, e.g. `k + 1`."""
    if isinstance(e, Num):
        return float(e.value)
    if isinstance(e, Call) and e.fn in ("add", "sub", "mul", "div", "neg"):
        a = [static_value(x) for x in e.args]
        if e.fn == "neg":
            return -a[0]
        return {"add": a[0] + a[1], "sub": a[0] - a[1], "mul": a[0] * a[1],
                "div": a[0] / a[1]}[e.fn]
    raise BodyError(f"expected a constant here, got {e!r}", e)


def static_int(e: Any) -> int:
    v = static_value(e)
    if v != int(v):
        raise BodyError(f"expected an integer constant, got {v}", e)
    return int(v)


def lift_constants(body: tuple[Constraint, ...]) -> tuple[tuple, list[float]]:
    """Replace value constants by `_Param(k)`; return (structural key body, parameter values)."""
    params: list[float] = []
    bases: dict[tuple, Vec] = {}

    def walk(e: Any, static: bool = False) -> Any:
        if static:
            return e
        if isinstance(e, Num):
            params.append(float(e.value))
            return _Param(len(params) - 1)
        if isinstance(e, Vec):
            return Vec(tuple(walk(x) for x in e.items))
        if isinstance(e, Call):
            if e.fn == "fk" and len(e.args) == 4:
                return Call(e.fn, (*(walk(a) for a in e.args[:3]), base(e.args[3])))
            st = _STATIC_ARGS.get(e.fn, ())
            return Call(e.fn, tuple(walk(a, i in st) for i, a in enumerate(e.args)))
        if isinstance(e, Index):
            return Index(walk(e.base), e.index, e.stop)
        if isinstance(e, Constraint):
            return Constraint(walk(e.lhs), e.op, walk(e.rhs))
        return e   # Slot, Obj, Str

    def base(e: Any) -> Any:
        # A constant robot base pose is lifted once per body and value: equal `fk(...)` calls
        # then have equal keys, so `_Builder` computes each (robot, joints, frame) chain once
        # (measured on Panda bodies: 1.5-4x smaller Hessians, e.g. panda.grasp 150k -> 37k
        # SX instructions). The sharing pattern is part of the cache key.
        if isinstance(e, Vec) and all(isinstance(x, Num) for x in e.items):
            vals = tuple(float(x.value) for x in e.items)
            if vals not in bases:
                bases[vals] = walk(e)
            return bases[vals]
        return walk(e)

    key = tuple(walk(c) for c in body)
    return key, params


def _params_in(e: Any, out: list[int]) -> None:
    if isinstance(e, _Param):
        out.append(e.index)
    elif isinstance(e, Vec):
        for x in e.items:
            _params_in(x, out)
    elif isinstance(e, Call):
        for x in e.args:
            _params_in(x, out)
    elif isinstance(e, Index):
        _params_in(e.base, out)
    elif isinstance(e, Constraint):
        _params_in(e.lhs, out)
        _params_in(e.rhs, out)


def abstract_constraint(c: Constraint, sigs: tuple[SlotSignature, ...]
                        ) -> tuple[tuple, tuple[tuple[int, int], ...], tuple[int, ...], tuple[int, ...]]:
    """`abstract_block` of one constraint."""
    return abstract_block((c,), sigs)


def abstract_block(cs: tuple, sigs: tuple[SlotSignature, ...]
                   ) -> tuple[tuple, tuple[tuple[int, int], ...], tuple[int, ...], tuple[int, ...]]:
    """(group key, points, whole slots, parameters) of a block of lifted constraints (one
    numbering of points, slots and parameters for the whole block).

    Every waypoint read of a trajectory slot (`waypoint(x, k)`, `x[k]`) becomes `_Point(m)`,
    m numbering the distinct (slot, waypoint) pairs in order of appearance; other slot uses
    become `Slot(m)` renumbered in order of appearance; parameters `_Param(i)` are renumbered
    in order of appearance too (a robot base shared by several constraints keeps one index).
    Two constraints with equal keys compute the same function of their points, slots and
    parameters, so their derivatives are one function evaluated at different arguments."""
    pidx: list[int] = []
    for c in cs:
        _params_in(c, pidx)
    local = {i: m for m, i in enumerate(dict.fromkeys(pidx))}
    points: dict[tuple[int, int], int] = {}
    wholes: dict[int, int] = {}

    def point(base: Any, k_expr: Any) -> Any:
        if not isinstance(base, Slot) or not 0 <= base.index < len(sigs):
            return None
        sig = sigs[base.index]
        if not sig.waypoints:
            return None
        k = static_int(k_expr)
        if not -sig.waypoints <= k < sig.waypoints:
            return None
        return _Point(points.setdefault((base.index, k % sig.waypoints), len(points)))

    def walk(e: Any) -> Any:
        if isinstance(e, _Param):
            return _Param(local[e.index])
        if isinstance(e, Slot):
            return Slot(wholes.setdefault(e.index, len(wholes)))
        if isinstance(e, Vec):
            return Vec(tuple(walk(x) for x in e.items))
        if isinstance(e, Call):
            if e.fn == "waypoint" and len(e.args) == 2:
                pt = point(e.args[0], e.args[1])
                if pt is not None:
                    return pt
            st = _STATIC_ARGS.get(e.fn, ())
            return Call(e.fn, tuple(a if i in st else walk(a) for i, a in enumerate(e.args)))
        if isinstance(e, Index):
            if e.stop is None:
                pt = point(e.base, e.index)
                if pt is not None:
                    return pt
            return Index(walk(e.base), e.index, e.stop)
        if isinstance(e, Constraint):
            return Constraint(walk(e.lhs), e.op, walk(e.rhs))
        return e   # Obj, Str, Num

    ac = tuple(walk(c) for c in cs)
    pts = tuple(points)
    whole = tuple(wholes)
    key = (ac, tuple(sigs[j].point_dim for j, _ in pts), tuple(sigs[j] for j in whole), len(local))
    return key, pts, whole, tuple(local)


def row_groups(body: tuple, sigs: tuple[SlotSignature, ...], row_counts: list[int]
               ) -> tuple[RowGroup, ...]:
    """The constraints of a lifted body cut into blocks and grouped by `abstract_block` key,
    in order of first appearance; `row_counts[i]` is the number of rows of constraint i.

    A block is a run of consecutive constraints reading the same nonempty set of waypoints
    (the body of one `forall k` step, e.g. the six hand/link distances of `paths_apart` at
    waypoint k): differentiated together, they share each arm's kinematic chain (measured:
    one 6-constraint block Hessian 48k SX instructions, six single ones 88k)."""
    point_sets = [frozenset(abstract_constraint(c, sigs)[1]) for c in body]
    starts = np.concatenate([[0], np.cumsum(row_counts)]).astype(int)
    groups: dict[tuple, list[GroupMember]] = {}
    n_rows: dict[tuple, int] = {}
    i = 0
    while i < len(body):
        j = i + 1
        if point_sets[i]:
            while j < len(body) and point_sets[j] == point_sets[i]:
                j += 1
        key, pts, whole, pars = abstract_block(tuple(body[i:j]), sigs)
        groups.setdefault(key, []).append(GroupMember(int(starts[i]), pts, whole, pars))
        n_rows[key] = int(starts[j] - starts[i])
        i = j
    return tuple(RowGroup(k, n_rows[k], tuple(m)) for k, m in groups.items())


def scatter_sum(n_rows: int, n_cols: int, rows: np.ndarray, cols: np.ndarray, values):
    """The n_rows x n_cols matrix (SX or MX, as `values`) with values[i] added at
    (rows[i], cols[i]) (repeated cells summed by one constant sparse product)."""
    S = ca.MX if isinstance(values, ca.MX) else ca.SX
    if rows.size == 0:
        return S(n_rows, n_cols)
    cell = cols.astype(np.int64) * n_rows + rows.astype(np.int64)     # column-major order
    uniq, inv = np.unique(cell, return_inverse=True)
    if uniq.size == cell.size:
        order = np.argsort(cell, kind="stable")
        vals = values[order.tolist()]
    else:
        A = ca.DM(ca.Sparsity.triplet(uniq.size, cell.size, inv.reshape(-1).tolist(),
                                      list(range(cell.size))), 1.0)
        vals = ca.mtimes(A, values)
    sp = ca.Sparsity.triplet(n_rows, n_cols, (uniq % n_rows).tolist(), (uniq // n_rows).tolist())
    return S(sp, vals)


def _split(v, fn: ca.Function, n: int) -> list:
    """The first n inputs of `fn` cut from one stacked column `v`."""
    out, lo = [], 0
    for i in range(n):
        d = fn.size1_in(i)
        out.append(v[lo:lo + d])
        lo += d
    return out


# ---------------------------------------------------------------------------------------------
# casadi implementations of the builtins. Every value is a casadi column vector (scalars 1x1).


def _rotmat_quat(q):
    """Rotation matrix of a unit quaternion [qx, qy, qz, qw]."""
    x, y, z, w = q[0], q[1], q[2], q[3]
    return ca.vertcat(
        ca.horzcat(1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)),
        ca.horzcat(2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)),
        ca.horzcat(2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)),
    )


def quat_mul(a, b):
    va, wa, vb, wb = a[0:3], a[3], b[0:3], b[3]
    return ca.vertcat(wa * vb + wb * va + ca.cross(va, vb), wa * wb - ca.dot(va, vb))


def quat_conj(q):
    return ca.vertcat(-q[0], -q[1], -q[2], q[3])


def quat_rotate(q, v):
    u, w = q[0:3], q[3]
    t = 2 * ca.cross(u, v)
    return v + w * t + ca.cross(u, t)


def compose_se2(a, b):
    c, s = ca.cos(a[2]), ca.sin(a[2])
    return ca.vertcat(a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])


def inv_se2(a):
    c, s = ca.cos(a[2]), ca.sin(a[2])
    return ca.vertcat(-(c * a[0] + s * a[1]), -(-s * a[0] + c * a[1]), -a[2])


def apply_se2(a, p):
    c, s = ca.cos(a[2]), ca.sin(a[2])
    return ca.vertcat(a[0] + c * p[0] - s * p[1], a[1] + s * p[0] + c * p[1])


def compose_se3(a, b):
    return ca.vertcat(a[0:3] + quat_rotate(a[3:7], b[0:3]), quat_mul(a[3:7], b[3:7]))


def inv_se3(a):
    qi = quat_conj(a[3:7])
    return ca.vertcat(-quat_rotate(qi, a[0:3]), qi)


_SIMPLE: dict[str, Callable] = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
    "neg": lambda a: -a,
    "sqrt": ca.sqrt,
    "sin": ca.sin,
    "cos": ca.cos,
    "atan2": ca.atan2,
    "abs": ca.fabs,
    "exp": ca.exp,
    "min": ca.fmin,
    "max": ca.fmax,
    "norm": lambda v: ca.sqrt(ca.sumsqr(v) + NORM_EPS),
    "sqnorm": ca.sumsqr,
    "dot": ca.dot,
    "cross": ca.cross,
    "sum": ca.sum1,
    "concat": lambda *xs: ca.vertcat(*xs),
    "se2": lambda x, y, t: ca.vertcat(x, y, t),
    "compose_se2": compose_se2,
    "inv_se2": inv_se2,
    "pos_se2": lambda a: a[0:2],
    "angle_se2": lambda a: a[2],
    "apply_se2": apply_se2,
    "angle_diff": lambda a, b: ca.atan2(ca.sin(a - b), ca.cos(a - b)),
    "se3": lambda p, q: ca.vertcat(p, q),
    "compose_se3": compose_se3,
    "inv_se3": inv_se3,
    "pos_se3": lambda a: a[0:3],
    "rot_se3": lambda a: a[3:7],
    "apply_se3": lambda a, p: a[0:3] + quat_rotate(a[3:7], p),
    "quat_mul": quat_mul,
    "quat_conj": quat_conj,
    "quat_rotate": quat_rotate,
    "quat_dist": lambda a, b: 1 - ca.dot(a, b) ** 2,
}
"""Builtins whose arguments are all values (no structural constant, no geometry)."""

# Builtins handled in `_Builder.call` because they take a structural constant or a body.
_SPECIAL = {"pow", "waypoint", "axis_se3", "quat_axis", "link", *GEOMETRY_PRIMITIVES}

IMPLEMENTED = frozenset(_SIMPLE) | _SPECIAL
"""Names implemented here (a test checks it equals `BUILTINS`)."""


def _check_size(name: str, value, n: int, node) -> None:
    if value.numel() != n:
        raise BodyError(f"{name}: expected a vector of length {n}, got {value.numel()}", node)


_ARG_SIZES: dict[str, tuple[int | None, ...]] = {
    "cross": (3, 3), "se2": (1, 1, 1), "compose_se2": (3, 3), "inv_se2": (3,),
    "pos_se2": (3,), "angle_se2": (3,), "apply_se2": (3, 2), "angle_diff": (1, 1),
    "se3": (3, 4), "compose_se3": (7, 7), "inv_se3": (7,), "pos_se3": (7,), "rot_se3": (7,),
    "apply_se3": (7, 3), "quat_mul": (4, 4), "quat_conj": (4,), "quat_rotate": (4, 3),
    "quat_dist": (4, 4), "atan2": (1, 1),
}


class _Builder:
    """Builds the casadi expression of one body from slot and parameter symbols."""

    def __init__(self, slots: list, sigs: tuple[SlotSignature, ...], p, geometry: Geometry | None,
                 points: list = (), open_stops: bool = False):
        self.slots, self.sigs, self.p, self.geometry = slots, sigs, p, geometry
        self.points = points            # symbols of `_Point` placeholders (group representatives)
        self._fk: dict[Call, Any] = {}  # one kinematic chain per equal fk(...) node (see lift)
        self._fk_rp: dict[Call, Any] = {}   # the same as (R, p), for distances
        self._chains: dict[tuple, Any] = {}  # (robot, joints, base) -> geometry's FrameChain
        self.shared_chains: set[tuple] = set()   # keys with several frames (`plan_chains`)
        # open_stops (SX only, geometry with `sdist_parts`): each distance's stop-gradient
        # callback output becomes a fresh symbol o_i, with its value expression in `stops`
        self.open_stops = open_stops and hasattr(geometry, "sdist_parts")
        self.stops: list[tuple[Any, Any]] = []     # (symbol o_i, callback(input) expression)
        # the same values for evaluation only (`witness_fast`: the native twin when built)
        self.fast_stops: list[Any] = []

    def plan_chains(self, constraints) -> None:
        """Mark the (robot, joints, base) of `fk` nodes that appear with two or more frames in
        `constraints`: their distances share one `FrameChain` (a lone frame is cheaper as
        the geometry's cached single-frame Function)."""
        if not hasattr(self.geometry, "fk_chain"):
            return
        frames: dict[tuple, set] = {}
        for x in _calls(constraints):
            if x.fn == "fk" and len(x.args) == 4:
                frames.setdefault((x.args[0], x.args[1], x.args[3]), set()).add(x.args[2])
        self.shared_chains = {k for k, v in frames.items() if len(v) > 1}

    def expr(self, e: Any):
        if isinstance(e, _Param):
            return self.p[e.index]
        if isinstance(e, _Point):
            return self.points[e.index]
        if isinstance(e, Num):
            return ca.DM(float(e.value))
        if isinstance(e, Slot):
            if not 0 <= e.index < len(self.slots):
                raise BodyError(f"Slot({e.index}) out of range ({len(self.slots)} variables)", e)
            return self.slots[e.index]
        if isinstance(e, Vec):
            return ca.vertcat(*[self.expr(x) for x in e.items])
        if isinstance(e, Index):
            return self.index(e)
        if isinstance(e, Call):
            return self.call(e)
        if isinstance(e, (Obj, Str)):
            raise BodyError(f"{e!r} is not a numeric value (only geometry primitives take "
                            "object or string arguments)", e)
        raise BodyError(f"unexpected node in a resolved body: {e!r}", e)

    def _traj_point(self, e: Any, k: int, node):
        """Waypoint k of trajectory slot `e` (negative k counts from the end)."""
        if not isinstance(e, Slot) or not self.sigs[e.index].waypoints:
            raise BodyError("waypoint/index on a non-trajectory value", node)
        sig = self.sigs[e.index]
        if not -sig.waypoints <= k < sig.waypoints:
            raise BodyError(f"waypoint {k} out of range ({sig.waypoints} waypoints)", node)
        k %= sig.waypoints
        d = sig.point_dim
        return self.slots[e.index][k * d:(k + 1) * d]

    def index(self, e: Index):
        i = static_int(e.index)
        if isinstance(e.base, Slot) and self.sigs[e.base.index].waypoints and e.stop is None:
            return self._traj_point(e.base, i, e)
        base = self.expr(e.base)
        n = base.numel()
        if e.stop is None:
            if not -n <= i < n:
                raise BodyError(f"index {i} out of range for a vector of length {n}", e)
            return base[i % n]
        j = static_int(e.stop)
        i, j = (i % n if i < 0 else i), (j % n if j < 0 else j)
        if not 0 <= i < j <= n:
            raise BodyError(f"slice {i}:{j} out of range for a vector of length {n}", e)
        return base[i:j]

    def body(self, e: Any) -> Body:
        b = Body.of(e)
        if b is not None:
            return b
        if isinstance(e, Call) and e.fn == "link":
            raise BodyError("link expects (robot object, link name string)", e)
        raise BodyError(f"expected a collision body (object or link(...)), got {e!r}", e)

    def call(self, e: Call):
        b = BUILTINS.get(e.fn)
        if b is None:
            raise BodyError(f"unknown builtin {e.fn!r} in a resolved body", e)
        if b.arity >= 0 and len(e.args) != b.arity:
            raise BodyError(f"{e.fn} expects {b.arity} arguments, got {len(e.args)}", e)
        fn = e.fn
        if fn in _SIMPLE:
            args = [self.expr(a) for a in e.args]
            for a, n in zip(args, _ARG_SIZES.get(fn, ())):
                if n is not None:
                    _check_size(fn, a, n, e)
            if fn in ("add", "sub", "mul", "div", "min", "max", "dot"):
                na, nb = args[0].numel(), args[1].numel()
                if na != nb and 1 not in (na, nb) or (fn == "dot" and na != nb):
                    raise BodyError(f"{fn}: incompatible lengths {na} and {nb}", e)
            return _SIMPLE[fn](*args)
        if fn == "pow":
            return self.expr(e.args[0]) ** static_value(e.args[1])
        if fn == "waypoint":
            return self._traj_point(e.args[0], static_int(e.args[1]), e)
        if fn in ("axis_se3", "quat_axis"):
            v = self.expr(e.args[0])
            i = static_int(e.args[1])
            if not 0 <= i <= 2:
                raise BodyError(f"{fn}: axis index must be 0, 1 or 2, got {i}", e)
            q = v[3:7] if fn == "axis_se3" else v
            _check_size(fn, v, 7 if fn == "axis_se3" else 4, e)
            return _rotmat_quat(q)[:, i]
        if fn == "link":
            raise BodyError("link(...) is only allowed as an argument of sdist/sdist2", e)
        # geometry primitives
        g = self.geometry
        if g is None:
            raise BodyError(f"{fn} needs a geometry implementation, none was given", e)
        if fn == "fk":
            hit = self._fk.get(e)
            if hit is not None:
                return hit
            robot, q, frame, base = e.args
            if not isinstance(robot, Obj) or not isinstance(frame, Str):
                raise BodyError("fk expects (robot object, joints, frame string, base pose)", e)
            out = self._fk[e] = g.fk(robot.name, self.expr(q), frame.value, self.expr(base))
            return out
        ba, pa, bb, pb = e.args
        prim = g.sdist if fn == "sdist" else g.sdist2
        n = 7 if fn == "sdist" else 3
        if self.open_stops:
            cbf, to_rp, model = g.sdist_parts(self.body(ba), self.body(bb), fn == "sdist2")
            (RA, pA), (RB, pB) = (self._rp(x, to_rp, n, e) for x in (pa, pb))
            o = ca.SX.sym(f"o{len(self.stops)}", cbf.size1_out(0))
            x = ca.vertcat(ca.reshape(RA, 9, 1), pA, ca.reshape(RB, 9, 1), pB)
            self.stops.append((o, cbf(x)))
            fast = g.witness_fast(self.body(ba), self.body(bb), fn == "sdist2") \
                if hasattr(g, "witness_fast") else cbf
            self.fast_stops.append(fast(x))
            return model(RA, pA, RB, pB, o)
        xa, xb = self.expr(pa), self.expr(pb)
        _check_size(fn, xa, n, e)
        _check_size(fn, xb, n, e)
        return prim(self.body(ba), xa, self.body(bb), xb)

    def _rp(self, node: Any, to_rp: ca.Function, n: int, e: Call) -> tuple[Any, Any]:
        """(R, p) of a distance's pose argument: straight from `fk_rp` for an `fk(...)` node
        (one chain per equal node, no quaternion round trip), else `to_rp` of its value."""
        if (n == 7 and isinstance(node, Call) and node.fn == "fk" and len(node.args) == 4
                and hasattr(self.geometry, "fk_rp")):
            hit = self._fk_rp.get(node)
            if hit is None:
                robot, q, frame, base = node.args
                if not isinstance(robot, Obj) or not isinstance(frame, Str):
                    raise BodyError("fk expects (robot object, joints, frame string, base pose)",
                                    node)
                if (robot, q, base) in self.shared_chains:   # frames of one arm share joints
                    chain = self._chains.get((robot, q, base))
                    if chain is None:
                        chain = self._chains[(robot, q, base)] = self.geometry.fk_chain(
                            robot.name, self.expr(q), self.expr(base))
                    hit = chain.frame(frame.value)
                else:
                    hit = self.geometry.fk_rp(robot.name, self.expr(q), frame.value,
                                              self.expr(base))
                self._fk_rp[node] = hit
            return hit
        x = self.expr(node)
        _check_size(e.fn, x, n, e)
        return tuple(to_rp(x))


def _constraint_rows(builder: _Builder, c: Any):
    """The rows h of one constraint (see the module docstring for the sign convention)."""
    if not isinstance(c, Constraint) or c.op not in ("==", "<=", ">="):
        raise BodyError(f"expected a constraint lhs op rhs, got {c!r}", c)
    lhs, rhs = builder.expr(c.lhs), builder.expr(c.rhs)
    nl, nr = lhs.numel(), rhs.numel()
    if nl != nr and 1 not in (nl, nr):
        raise BodyError(f"constraint sides have lengths {nl} and {nr}", c)
    h = lhs - rhs if c.op != ">=" else rhs - lhs
    return ca.vec(h)


def _fname(name: str) -> str:
    return "h_" + "".join(ch if ch.isalnum() else "_" for ch in name)


def _calls(xs: Iterable[Any]) -> Iterator[Call]:
    """Every `Call` node in the expressions or constraints `xs`, nested calls included
    (one walk for `_uses` and `_Builder.plan_chains`)."""
    for x in xs:
        if isinstance(x, Call):
            yield x
            yield from _calls(x.args)
        elif isinstance(x, Vec):
            yield from _calls(x.items)
        elif isinstance(x, Index):
            yield from _calls((x.base,))
        elif isinstance(x, Constraint):
            yield from _calls((x.lhs, x.rhs))


def _uses(e: Any, names: set[str]) -> set[str]:
    """The names among `names` called anywhere in the constraints `e`."""
    return {x.fn for x in _calls(e) if x.fn in names}


@dataclass(frozen=True)
class _Named:
    """An object name replaced by its geometry's structure key (cache keys only)."""

    key: Any


def _map_objs(e: Any, f: Callable[[str], Any]) -> Any:
    """`e` with every `Obj(name)` replaced by `f(name)`."""
    if isinstance(e, Obj):
        return f(e.name)
    if isinstance(e, tuple):
        return tuple(_map_objs(x, f) for x in e)
    if isinstance(e, Vec):
        return Vec(tuple(_map_objs(x, f) for x in e.items))
    if isinstance(e, Call):
        return Call(e.fn, tuple(_map_objs(a, f) for a in e.args))
    if isinstance(e, Index):
        return Index(_map_objs(e.base, f), e.index, e.stop)
    if isinstance(e, Constraint):
        return Constraint(_map_objs(e.lhs, f), e.op, _map_objs(e.rhs, f))
    return e


def _has_repeats(cb: CompiledBody) -> bool:
    """True when some row group has several members (derivatives are then assembled from one
    representative per group); bodies without repeats are differentiated directly."""
    return cb.symbolic == "SX" and any(len(g.members) > 1 for g in cb.groups)


def _symbols(cb: CompiledBody) -> tuple[list, Any]:
    F = cb.function
    slots = [ca.SX.sym(f"x{j}", F.size1_in(j)) for j in range(F.n_in() - 1)]
    return slots, ca.SX.sym("p", F.size1_in(F.n_in() - 1))


def _open_rows(cb: CompiledBody, slots: list, p) -> tuple[Any, Any, Any]:
    """(h, o, o's value) on SX symbols: with stop-gradient symbols, h is the open function of
    a fresh o (differentiate with o held constant, then substitute o's value); else o is
    empty."""
    if cb.open_function is None:
        return cb.function(*slots, p), ca.SX(0, 1), ca.SX(0, 1)
    O = ca.SX.sym("o", cb.open_function.size1_in(len(slots) + 1))
    return cb.open_function(*slots, p, O), O, cb.stops(*slots, p)


def _closed(name: str, inputs: list, O, Ov, D, native: Callable | None = None) -> ca.Function:
    """Function inputs -> D with the stop-gradient symbols O replaced by their values Ov (both
    functions of `inputs`). Why an MX wrapper around two SX Functions instead of
    `ca.substitute`: substituting into a Panda Hessian re-evaluates its whole SX graph (0.5 s of
    lab1's assembly); the wrapper costs two call nodes. `native` (a `jit.KernelCache.native`)
    may replace the pure SX part, the derivative itself, by compiled code."""
    native = native or (lambda f: f)
    if O.numel() == 0:
        return native(ca.Function(name, inputs, [D]))
    open_f = native(ca.Function(name + "_open", [*inputs, O], [D]))
    stop_f = ca.Function(name + "_stops", inputs, [Ov])
    m = [ca.MX.sym(f"a{i}", x.sparsity()) for i, x in enumerate(inputs)]
    return ca.Function(name, m, [open_f(*m, stop_f(*m))])


def direct_jacobian(cb: CompiledBody, native: Callable | None = None) -> ca.Function:
    """(x_0, ..., p) -> dh/dX by differentiating the whole body at once (reference for the
    grouped assembly; used for bodies without repeated constraints)."""
    F = cb.function
    slots, p = _symbols(cb)
    X = ca.vertcat(*slots)
    out, O, Ov = _open_rows(cb, slots, p)
    return _closed(F.name() + "_jac", [*slots, p], O, Ov, ca.jacobian(out, X), native)


def direct_hessian(cb: CompiledBody, native: Callable | None = None) -> ca.Function:
    """(x_0, ..., p, lam) -> d^2 (lam . h) / dX^2 by differentiating the whole body at once."""
    F = cb.function
    slots, p = _symbols(cb)
    lam = ca.SX.sym("lam", cb.n_rows)
    X = ca.vertcat(*slots)
    out, O, Ov = _open_rows(cb, slots, p)
    H = ca.hessian(ca.dot(lam, out), X)[0] if cb.n_rows else ca.SX(X.numel(), X.numel())
    return _closed(F.name() + "_hess", [*slots, p, lam], O, Ov, H, native)


class BodyCompiler:
    """Compiles factor bodies to casadi Functions, cached by (template, structure).

    Why a class: it owns the cache and the injected geometry, and lives as long as a solve loop
    so that every template is compiled once across all the graph-NLPs of the loop."""

    def __init__(self, geometry: Geometry | None = None, kernels: Any = None):
        """`kernels`: a `gnppdsl.nlp.jit.KernelCache` to run the large derivative kernels as
        compiled code (None: casadi's virtual machine)."""
        self.geometry = geometry
        self.kernels = kernels
        self._native = kernels.native if kernels is not None else None
        self._cache: dict[tuple, CompiledBody] = {}
        # per-instance memo (by identity; the instance is kept alive in the value): lifting and
        # hashing a body costs more than a lookup, and every subgraph re-assembles its factors
        self._instances: dict[int, tuple[FactorInstance, CompiledBody, np.ndarray]] = {}
        self._bodies: dict[tuple, tuple[tuple, CompiledBody, np.ndarray]] = {}   # see `compile`
        self.compiled = 0           # number of distinct Functions built (for stats / tests)
        self._hessians: dict[int, tuple[CompiledBody, ca.Function]] = {}
        self._jacobians: dict[int, tuple[CompiledBody, ca.Function]] = {}
        self._reps: dict[tuple, ca.Function | None] = {}   # row-group representative derivatives
        self._names: dict[str, Any] = {}                    # object name -> structure key

    def jacobian(self, cb: CompiledBody) -> ca.Function:
        """(x_0, ..., x_{m-1}, p) -> dh/dX (X the stacked slots), an SX Function built once per
        compiled body (see `hessian` for why the nlp layer assembles derivatives itself, and
        `_grouped_derivative` for bodies with repeated per-waypoint constraints)."""
        hit = self._jacobians.get(id(cb))
        if hit is not None and hit[0] is cb:
            return hit[1]
        jf = self._grouped_derivative(cb, False) if _has_repeats(cb) else direct_jacobian(cb, self._native)
        self._jacobians[id(cb)] = (cb, jf)
        return jf

    def hessian(self, cb: CompiledBody) -> ca.Function:
        """(x_0, ..., x_{m-1}, p, lam) -> d^2 (lam . h) / dX^2 with X the stacked slots, built
        once per compiled body as an SX Function. Why not let casadi differentiate the
        assembled MX graph: its forward-over-reverse Hessian through the call nodes was
        measured 10-20x more expensive to build and to evaluate on the Panda templates
        (FK chains, coal feature models) than these per-template SX Hessians."""
        hit = self._hessians.get(id(cb))
        if hit is not None and hit[0] is cb:
            return hit[1]
        hf = self._grouped_derivative(cb, True) if _has_repeats(cb) else direct_hessian(cb, self._native)
        self._hessians[id(cb)] = (cb, hf)
        return hf

    def _representative(self, group: RowGroup, hessian: bool) -> ca.Function | None:
        """Jacobian (points..., slots..., p) -> dh/d[points, slots] or Hessian (..., lam) ->
        d^2 (lam . h) of a row group's representative constraint; cached by group key, so equal
        constraints of different bodies share it too. None when it has no input or no row."""
        key = (group.key, hessian)
        if key in self._reps:
            return self._reps[key]
        ac, pdims, wsigs, n_par = group.key
        pts = [ca.SX.sym(f"w{m}", d) for m, d in enumerate(pdims)]
        slots = [ca.SX.sym(f"x{m}", sg.dim) for m, sg in enumerate(wsigs)]
        p = ca.SX.sym("p", n_par)
        builder = _Builder(slots, wsigs, p, self.geometry, pts, open_stops=True)
        builder.plan_chains(ac)
        h = ca.vertcat(*(_constraint_rows(builder, c) for c in ac))
        fn = None
        if (pts or slots) and h.numel():
            X = ca.vertcat(*pts, *slots)
            if hessian:
                lam = ca.SX.sym("lam", h.numel())
                D = ca.hessian(ca.dot(lam, h), X)[0]
            else:
                D = ca.jacobian(h, X)
            # derivatives with the stop-gradient symbols held constant, then their values
            # (evaluated only: the fast twins)
            O, Ov = ((ca.vertcat(*[o for o, _ in builder.stops]), ca.vertcat(*builder.fast_stops))
                     if builder.stops else (ca.SX(0, 1), ca.SX(0, 1)))
            ins = [*pts, *slots, p, lam] if hessian else [*pts, *slots, p]
            fn = _closed("rep_hess" if hessian else "rep_jac", ins, O, Ov, D, self._native)
        self._reps[key] = fn
        return fn

    def _grouped_derivative(self, cb: CompiledBody, hessian: bool, inline: bool = False
                            ) -> ca.Function:
        """The body's Jacobian or Hessian from its row groups: each group's representative is
        differentiated once, then evaluated at every member's points, slots, parameters (and
        multipliers), and the results are scattered into place and summed. Same function and
        sparsity as differentiating the whole body (`direct_jacobian`, `direct_hessian`).

        Why an MX Function with one mapped call per group (default) rather than inlined SX
        calls (`inline=True`, kept for tests): measured on lab1's paths_apart (108 rows, before
        the later stop-gradient and block changes), the inlined Hessian was a 3.5M-instruction
        SX graph built in 2.7-3.1 s (whole-body ca.hessian: 4.0 s) and evaluated in 36 ms; the
        mapped one built in 13 ms and evaluated in 33 ms, with equal sparsity and values to
        4e-16. `tests/nlp/test_nlp_buildcost*.py` check the values and sparsity."""
        F = cb.function
        m = F.n_in() - 1
        sizes = [F.size1_in(j) for j in range(m)]
        offs = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        n_x = int(offs[-1])
        S = ca.SX if inline else ca.MX
        slots = [S.sym(f"x{j}", sizes[j]) for j in range(m)]
        p = S.sym("p", F.size1_in(m))
        lam = S.sym("lam", cb.n_rows)
        X = ca.vertcat(*slots) if slots else S(0, 1)
        vals, rows, cols = [], [], []
        for g in cb.groups:
            fn = self._representative(g, hessian)
            if fn is None:
                continue
            sp = fn.sparsity_out(0)
            if sp.nnz() == 0:
                continue
            rr, cc = (np.asarray(t, dtype=np.int64) for t in sp.get_triplet())
            pdims, n_par = g.key[1], g.key[3]
            colmaps = []
            for mem in g.members:
                idx = [np.arange(offs[j] + k * d, offs[j] + (k + 1) * d)
                       for (j, k), d in zip(mem.points, pdims)]
                idx += [np.arange(offs[j], offs[j + 1]) for j in mem.slots]
                colmaps.append(np.concatenate(idx))
                rows.append(colmaps[-1][rr] if hessian else mem.row0 + rr)
                cols.append(colmaps[-1][cc])
            G = len(g.members)
            if inline:
                for mem, cm in zip(g.members, colmaps):
                    args = _split(X[cm.tolist()], fn, len(mem.points) + len(mem.slots))
                    args.append(p[list(mem.params)] if n_par else S(0, 1))
                    if hessian:
                        args.append(lam[mem.row0:mem.row0 + g.n_rows])
                    vals.append(ca.vec(fn(*args).nz[:]))
                continue
            cm = np.stack(colmaps, axis=1)                       # inputs x members
            args, lo = [], 0
            for i in range(len(g.members[0].points) + len(g.members[0].slots)):
                d = fn.size1_in(i)
                args.append(ca.reshape(X[cm[lo:lo + d].reshape(-1, order="F").tolist()], d, G))
                lo += d
            pi = np.array([mem.params for mem in g.members], dtype=np.int64).reshape(G, n_par).T
            args.append(ca.reshape(p[pi.reshape(-1, order="F").tolist()], n_par, G)
                        if n_par else S(0, G))
            if hessian:
                li = np.array([np.arange(mem.row0, mem.row0 + g.n_rows) for mem in g.members]).T
                args.append(ca.reshape(lam[li.reshape(-1, order="F").tolist()], g.n_rows, G))
            mapped = fn if G == 1 else fn.map(G, "serial")
            vals.append(ca.vec(mapped(*args).nz[:]))
        cat = (lambda xs: np.concatenate(xs) if xs else np.zeros(0, dtype=np.int64))
        M = scatter_sum(n_x if hessian else cb.n_rows, n_x, cat(rows), cat(cols),
                        ca.vertcat(*vals) if vals else S(0, 1))
        if hessian:
            return ca.Function(F.name() + "_hess", [*slots, p, lam], [M])
        return ca.Function(F.name() + "_jac", [*slots, p], [M])

    def compile(self, factor: FactorInstance) -> tuple[CompiledBody, np.ndarray]:
        """(compiled body, parameter values) for one factor instance.

        Remembered per instance, and per body: the factory gives every instance of one
        resolution (the same rule, call and consulted facts at any step of any plan) the same
        body object with its variables shifted in time (`GraphNLPFactory._cached_instance`),
        and the compiled body and parameters depend only on the template, the body and the
        slots' signatures. Why: a new plan's graph is made of new instances, and computing a
        body's structure key (lifting constants, renaming objects) costs ~1.5 ms for a
        20-waypoint body (lab5: 841 such computations, ~1 s, per solve)."""
        hit = self._instances.get(id(factor))
        if hit is not None and hit[0] is factor:
            return hit[1], hit[2]
        sigs = tuple(SlotSignature.of(v) for v in factor.variables)
        key = (id(factor.body), factor.template, sigs)
        same = self._bodies.get(key)
        if same is not None and same[0] is factor.body:
            cb, params = same[1], same[2]
        else:
            cb, params = self._compile(factor, sigs)
            if len(self._bodies) > 200_000:
                self._bodies.clear()
            self._bodies[key] = (factor.body, cb, params)     # keeps the body alive: ids stay unique
        if len(self._instances) > 200_000:
            self._instances.clear()
        self._instances[id(factor)] = (factor, cb, params)
        return cb, params

    def _structure_of(self, name: str) -> Any:
        key = self._names.get(name)
        if key is None:
            sk = getattr(self.geometry, "structure_key", None)
            key = self._names[name] = _Named(sk(name) if sk is not None else ("name", name))
        return key

    def _compile(self, factor: FactorInstance, sigs: tuple) -> tuple[CompiledBody, np.ndarray]:
        key_body, params = lift_constants(factor.body)
        # object and robot names by what their geometry depends on (`structure_key`): bodies
        # that differ only in the name of a same-shaped block share one Function
        key = (factor.template, _map_objs(key_body, self._structure_of), sigs)
        cb = self._cache.get(key)
        if cb is None:
            try:
                cb = self._build(factor.template, key_body, sigs, len(params))
            except BodyError as err:
                raise BodyError(f"{factor.label}: {err}") from None
            self._cache[key] = cb
            self.compiled += 1
        return cb, np.asarray(params, dtype=float)

    def _build(self, name: str, body: tuple, sigs: tuple[SlotSignature, ...],
               n_params: int) -> CompiledBody:
        prims = _uses(body, set(GEOMETRY_PRIMITIVES))
        mx = self.geometry is not None and any(self.geometry.needs_mx(p) for p in prims)
        S = ca.MX if mx else ca.SX
        slots = [S.sym(f"x{j}", s.dim) for j, s in enumerate(sigs)]
        p = S.sym("p", n_params)
        builder = _Builder(slots, sigs, p, self.geometry, open_stops=not mx)
        builder.plan_chains(body)
        rows, kinds = [], []
        for c in body:
            h = _constraint_rows(builder, c)
            rows.append(h)
            kinds += ["eq" if c.op == "==" else "ineq"] * h.numel()
        out = ca.vertcat(*rows) if rows else S(0, 1)
        fname = _fname(name)
        open_f = stops = evaluate = None
        if builder.stops:
            O, Ov = (ca.vertcat(*t) for t in zip(*builder.stops))
            open_f = ca.Function(fname + "_open", [*slots, p, O], [out])
            # the stop-gradient values are only ever evaluated: the fast twins
            fast = ca.vertcat(*builder.fast_stops)
            stops = ca.Function(fname + "_stops", [*slots, p], [fast])
            # one SX graph: the queries' inputs share the kinematic chains with the model
            evaluate = ca.Function(fname + "_eval", [*slots, p], [ca.substitute(out, O, fast)])
            out = ca.substitute(out, O, Ov)
        f = ca.Function(fname, [*slots, p], [out])
        groups = row_groups(body, sigs, [h.numel() for h in rows]) if not mx else ()
        return CompiledBody(f, tuple(kinds), n_params, "MX" if mx else "SX", frozenset(prims),
                            groups, open_f, stops, evaluate)
