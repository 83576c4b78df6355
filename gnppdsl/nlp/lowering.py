"""Lowering the expression language: resolved (stage-2) factor bodies -> casadi expressions.

What a body means in casadi: `BodyLowering` turns the expression IR (`gnppdsl.ir.expr`) of one
body into casadi expressions of its slot and parameter symbols, one column of rows per
constraint (`constraint_rows`); every builtin of `gnppdsl.ir.builtins` is implemented here
(`IMPLEMENTED`, a test checks it equals `BUILTINS`). Also the structural analysis the Function
cache keys on: numeric constants lifted into a parameter vector (`lift_constants`), repeated
per-waypoint constraints found and grouped (`row_groups`).

Why separate from `body_compiler` (building and caching casadi Functions, differentiating them):
what the language means is one question, how the solver gets cheap Functions and derivatives
out of it is another, and each changes for its own reasons.

A body's rows: `lhs == rhs` gives rows lhs - rhs (eq), `lhs <= rhs` rows lhs - rhs (ineq) and
`lhs >= rhs` rows rhs - lhs (ineq).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable, Iterable, Iterator

import casadi as ca
import numpy as np

from gnppdsl.compile.factors import VarInstance
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
        # then have equal keys, so `BodyLowering` computes each (robot, joints, frame) chain once
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


def structure_key(body: tuple[Constraint, ...], rename: Callable[[str], Any]) -> tuple[tuple, list[float]]:
    """(key, parameter values) of a body: the key equal for two bodies exactly when
    `(map_objs(lift_constants(b)[0], rename))` is, the parameter values those of
    `lift_constants`, in one walk and as plain tuples. Why not those two functions: a new
    problem's factor bodies are new objects, so the template compiler computes every body's key
    once per problem; the two walks rebuilt the tree twice as frozen dataclasses, whose hash
    and equality (the cache lookup) run in Python per node: 27-36 ms per new pick-and-place
    problem of `bench_komo.py` (31 factors) against ~8 ms for this. Tags keep the encoding
    injective: ("p", k) a lifted constant, ("n", v) a structural one, ("o", rename(name)) an
    object; leaves without constants (slots, strings) are kept as they are.

    Written for speed (a new problem walks every body once; `bench_komo.py`'s pick-and-place,
    31 bodies of ~14k nodes, was 6.3-7.8 ms, now 4.4-5.3 ms, a quarter of its path NLPs'
    CPU): constants among a call's arguments or a vector's items are lifted in place rather
    than by a call of `walk`, lists are built by loops rather than generators, and the node
    types are tested in the order of their frequency (Num, Call, Obj, Vec)."""
    params: list[float] = []
    push = params.append
    bases: dict[tuple, tuple] = {}
    static_args = _STATIC_ARGS

    def walk(e: Any, static: bool) -> Any:
        t = type(e)
        if t is Num:
            if static:
                return ("n", e.value)
            push(float(e.value))
            return ("p", len(params) - 1)
        if t is Call:
            fn, args = e.fn, e.args
            out = ["c", fn]
            if static:
                for a in args:
                    out.append(("n", a.value) if type(a) is Num else walk(a, True))
                return tuple(out)
            if fn == "fk" and len(args) == 4:
                out += (walk(args[0], False), walk(args[1], False), walk(args[2], False), base(args[3]))
                return tuple(out)
            st = static_args.get(fn)
            if st is None:
                for a in args:
                    if type(a) is Num:
                        push(float(a.value))
                        out.append(("p", len(params) - 1))
                    else:
                        out.append(walk(a, False))
            else:
                for i, a in enumerate(args):
                    out.append(walk(a, i in st))
            return tuple(out)
        if t is Obj:
            return ("o", rename(e.name))
        if t is Vec:
            out = ["v"]
            if static:
                for x in e.items:
                    out.append(("n", x.value) if type(x) is Num else walk(x, True))
            else:
                for x in e.items:
                    if type(x) is Num:
                        push(float(x.value))
                        out.append(("p", len(params) - 1))
                    else:
                        out.append(walk(x, False))
            return tuple(out)
        if t is Constraint:
            return ("k", walk(e.lhs, static), e.op, walk(e.rhs, static))
        if t is Index:
            return ("i", walk(e.base, static), e.index, e.stop)
        return e    # Slot, Str (no subclasses of the node types exist: `type(e) is`)

    def base(e: Any) -> Any:
        # as `lift_constants`: a constant base pose is lifted once per body and value
        if type(e) is Vec:
            items = e.items
            if all(type(x) is Num for x in items):
                vals = tuple([float(x.value) for x in items])
                hit = bases.get(vals)
                if hit is None:
                    hit = bases[vals] = walk(e, False)
                return hit
        return walk(e, False)

    return tuple([walk(c, False) for c in body]), params


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

# Builtins handled in `BodyLowering.call` because they take a structural constant or a body.
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


class BodyLowering:
    """Builds the casadi expression of one body from slot and parameter symbols."""

    def __init__(self, slots: list, sigs: tuple[SlotSignature, ...], p, geometry: Geometry | None,
                 points: list = (), open_stops: bool = False):
        self.slots, self.sigs, self.p, self.geometry = slots, sigs, p, geometry
        # the parameters' elements, split once: indexing a casadi symbol from Python
        # (`p[i]`, SWIG overload resolution) costs tens of microseconds per element
        self._p_items = ca.vertsplit(p) if isinstance(p, ca.SX) and p.numel() else []
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
        self.stop_bodies: list[tuple[Any, Any, bool]] = []   # (body a, body b, planar) per stop
        self.stop_inputs: list[Any] = []                     # the query's input x per stop

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
            if not 0 <= e.index < len(self._p_items):
                return self.p[e.index]          # casadi's own error for an index out of range
            return self._p_items[e.index]
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
            self.stop_bodies.append((self.body(ba), self.body(bb), fn == "sdist2"))
            self.stop_inputs.append(x)
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


def constraint_rows(builder: BodyLowering, c: Any):
    """The rows h of one constraint (see the module docstring for the sign convention)."""
    if not isinstance(c, Constraint) or c.op not in ("==", "<=", ">="):
        raise BodyError(f"expected a constraint lhs op rhs, got {c!r}", c)
    lhs, rhs = builder.expr(c.lhs), builder.expr(c.rhs)
    nl, nr = lhs.numel(), rhs.numel()
    if nl != nr and 1 not in (nl, nr):
        raise BodyError(f"constraint sides have lengths {nl} and {nr}", c)
    h = lhs - rhs if c.op != ">=" else rhs - lhs
    return ca.vec(h)


def _calls(xs: Iterable[Any]) -> Iterator[Call]:
    """Every `Call` node in the expressions or constraints `xs`, nested calls included
    (one walk for `_uses` and `BodyLowering.plan_chains`)."""
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


def uses(e: Any, names: set[str]) -> set[str]:
    """The names among `names` called anywhere in the constraints `e`."""
    return {x.fn for x in _calls(e) if x.fn in names}


def map_objs(e: Any, f: Callable[[str], Any]) -> Any:
    """`e` with every `Obj(name)` replaced by `f(name)`."""
    if isinstance(e, Obj):
        return f(e.name)
    if isinstance(e, tuple):
        return tuple(map_objs(x, f) for x in e)
    if isinstance(e, Vec):
        return Vec(tuple(map_objs(x, f) for x in e.items))
    if isinstance(e, Call):
        return Call(e.fn, tuple(map_objs(a, f) for a in e.args))
    if isinstance(e, Index):
        return Index(map_objs(e.base, f), e.index, e.stop)
    if isinstance(e, Constraint):
        return Constraint(map_objs(e.lhs, f), e.op, map_objs(e.rhs, f))
    return e
