"""An independent numpy interpreter of resolved (stage-2) bodies, to re-check solutions.

Why a second implementation: a solution is only trusted if the constraints hold when evaluated
by code that shares nothing with the solver path (`lowering`, `body_compiler` + ipopt). This module interprets
the body tree itself, keeps every numeric constant in place (no lifting), and implements rotations
through explicit rotation matrices and angles (`lowering` uses quaternion algebra), so a bug in
one is unlikely to be repeated in the other. Geometry goes through the numeric methods of the
injected `Geometry`.

Violation of a row: |h| for `==`, max(h, 0) for `<=`/`>=` (after moving everything to h <= 0).

Why compiled: the solve loop re-evaluates every factor of a graph at one point, many graphs per
point (`known_solution`, relaxation screening, the final re-check), and a Lab body is an unrolled
tree of thousands of nodes in which the same subexpression (`world(b1)`, the fk of one waypoint)
recurs in many rows and many factors. So each factor is compiled once into steps over a table of
hash-consed nodes (a node is keyed by its builtin, its static arguments and its children's node
ids; a leaf is a `VarInstance`): constant subtrees are folded when compiled, and one
`max_violation` call evaluates every distinct node once, whichever factors share it. The steps call
the same numeric kernels (`_NUMERIC`) as a plain walk of the body tree would, in the same order
per node, so the numbers are the same bit for bit as such a walk (the tests' oracle,
`tests/nlp/evaluate_reference.py`, walks the tree with numeric kernels of its own and agrees to
rounding). A factor also remembers its rows at its
last few inputs (keyed by the exact bytes of its variables' values and the geometry object):
a pure function, asked again for the same point by the next subgraph. Whatever a body cannot
evaluate (an unknown primitive, sizes that do not fit, a missing value) raises `EvaluationError`.
"""
from __future__ import annotations

import gc
import math
import weakref
from typing import Any, Callable, Iterable, Mapping

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Slot, Vec
from gnppdsl.nlp.geometry_protocol import Body, Geometry


class EvaluationError(ValueError):
    pass


def _rot(q: np.ndarray) -> np.ndarray:
    """Rotation matrix of a quaternion [qx, qy, qz, qw], normalised first (Rodrigues form)."""
    q = np.asarray(q, float)
    nq = np.linalg.norm(q)
    x, y, z, w = q / nq if nq > 0 else (0.0, 0.0, 0.0, 1.0)
    angle = 2.0 * math.atan2(math.sqrt(x * x + y * y + z * z), w)
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-15:
        return np.eye(3)
    k = np.array([x, y, z]) / s
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + math.sin(angle) * K + (1 - math.cos(angle)) * K @ K


def _quat(R: np.ndarray, like: np.ndarray | None = None) -> np.ndarray:
    """Quaternion [qx, qy, qz, qw] of a rotation matrix (sign chosen to match `like`)."""
    t = np.trace(R)
    if t > 0:
        s = math.sqrt(t + 1.0) * 2
        q = np.array([(R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s,
                      (R[1, 0] - R[0, 1]) / s, 0.25 * s])
    else:
        i = int(np.argmax(np.diag(R)))
        j, k = (i + 1) % 3, (i + 2) % 3
        s = math.sqrt(1.0 + R[i, i] - R[j, j] - R[k, k]) * 2
        q = np.zeros(4)
        q[i] = 0.25 * s
        q[j] = (R[j, i] + R[i, j]) / s
        q[k] = (R[k, i] + R[i, k]) / s
        q[3] = (R[k, j] - R[j, k]) / s
    if like is not None and float(np.dot(q, like)) < 0:
        q = -q
    return q


def _hamilton(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Hamilton product via the 4x4 left-multiplication matrix of a (xyzw layout)."""
    x, y, z, w = a
    L = np.array([[w, -z, y, x],
                  [z, w, -x, y],
                  [-y, x, w, z],
                  [-x, -y, -z, w]])
    return L @ np.asarray(b, float)


def _r2(t: float) -> np.ndarray:
    return np.array([[math.cos(t), -math.sin(t)], [math.sin(t), math.cos(t)]])


def _scalar(v: np.ndarray) -> float:
    if v.size != 1:
        raise EvaluationError(f"expected a scalar, got length {v.size}")
    return float(v.reshape(-1)[0])


def _const(e: Any) -> float:
    if isinstance(e, Num):
        return float(e.value)
    if isinstance(e, Call) and e.fn in ("add", "sub", "mul", "div", "neg"):
        a = [_const(x) for x in e.args]
        return -a[0] if e.fn == "neg" else {"add": a[0] + a[1], "sub": a[0] - a[1],
                                             "mul": a[0] * a[1], "div": a[0] / a[1]}[e.fn]
    raise EvaluationError(f"expected a constant, got {e!r}")


def _compose_se2(a, b):
    return np.concatenate([a[:2] + _r2(a[2]) @ b[:2], [a[2] + b[2]]])


def _inv_se2(a):
    return np.concatenate([-_r2(a[2]).T @ a[:2], [-a[2]]])


def _compose_se3(a, b):
    Ra, Rb = _rot(a[3:7]), _rot(b[3:7])
    q = _quat(Ra @ Rb, like=_hamilton(a[3:7], b[3:7]))
    return np.concatenate([a[:3] + Ra @ b[:3], q])


def _inv_se3(a):
    R = _rot(a[3:7])
    q = _quat(R.T, like=np.array([-a[3], -a[4], -a[5], a[6]]))
    return np.concatenate([-R.T @ a[:3], q])


def _angle_diff(a, b):
    d = math.fmod(_scalar(a) - _scalar(b), 2 * math.pi)
    if d > math.pi:
        d -= 2 * math.pi
    elif d <= -math.pi:
        d += 2 * math.pi
    return d


_NUMERIC = {
    "add": lambda a, b: a + b,
    "sub": lambda a, b: a - b,
    "mul": lambda a, b: a * b,
    "div": lambda a, b: a / b,
    "neg": lambda a: -a,
    "sqrt": np.sqrt,
    "sin": np.sin,
    "cos": np.cos,
    "atan2": np.arctan2,
    "abs": np.abs,
    "exp": np.exp,
    "min": np.minimum,
    "max": np.maximum,
    "norm": lambda v: math.sqrt(float(v @ v)),
    "sqnorm": lambda v: float(v @ v),
    "dot": lambda a, b: float(a @ b),
    "cross": np.cross,
    "sum": np.sum,
    "concat": lambda *xs: np.concatenate(xs),
    "se2": lambda x, y, t: np.concatenate([x, y, t]),
    "compose_se2": _compose_se2,
    "inv_se2": _inv_se2,
    "pos_se2": lambda a: a[:2],
    "angle_se2": lambda a: a[2],
    "apply_se2": lambda a, p: a[:2] + _r2(a[2]) @ p,
    "angle_diff": _angle_diff,
    "se3": lambda p, q: np.concatenate([p, q]),
    "compose_se3": _compose_se3,
    "inv_se3": _inv_se3,
    "pos_se3": lambda a: a[:3],
    "rot_se3": lambda a: a[3:7],
    "apply_se3": lambda a, p: a[:3] + _rot(a[3:7]) @ p,
    "quat_mul": lambda a, b: _quat(_rot(a) @ _rot(b), like=_hamilton(a, b))
    * (np.linalg.norm(a) * np.linalg.norm(b)),
    "quat_conj": lambda q: np.array([-q[0], -q[1], -q[2], q[3]]),
    "quat_rotate": lambda q, v: _rot(q) @ v,
    "quat_dist": lambda a, b: 1.0 - float(a @ b) ** 2,
}

EVALUATED = frozenset(_NUMERIC) | {"pow", "waypoint", "axis_se3", "quat_axis", "fk", "sdist",
                                   "sdist2", "link"}



# ---------------------------------------------------------------------------------------------
# compiled evaluation
# ---------------------------------------------------------------------------------------------
_F64 = np.dtype(float)


def _vec(r: Any) -> np.ndarray:
    """The value of a node as a flat float vector (what a tree walk makes of a call's result)."""
    if r.__class__ is np.ndarray and r.ndim == 1 and r.dtype == _F64:
        return r
    if r.__class__ is float:
        return np.array([r])
    return np.atleast_1d(np.asarray(r, float)).reshape(-1)


_GEO = 0
"""Node id of the injected geometry in every table: `m[_GEO]` is the `Geometry` of the call."""


class _Table:
    """Hash-consed nodes: a node is keyed by `prefix + kids` (its builtin, static arguments and
    children's ids), so an expression that recurs is one node.

    Node kinds: leaf (`prefix` names it; its value is supplied per call), constant (folded when
    made: every child constant), step (`op[id](*values of kids[id])`, run once per call).
    Node 0 is the geometry leaf. A node of the shared table holds its key, a tuple of child ids
    and a function made when its body's template was compiled (no closure per node), so a large
    table gives the garbage collector little to walk."""

    def __init__(self) -> None:
        self.ids: dict[tuple, int] = {}
        self.prefix: list[tuple] = [("geometry",)]
        self.op: list[Callable | None] = [None]          # id -> function, None for leaves
        self.kids: list[tuple[int, ...]] = [()]          # id -> children
        self.const: dict[int, np.ndarray] = {}           # id -> folded value

    def _new(self, key: tuple, prefix: tuple, op: Callable | None, kids: tuple) -> int:
        nid = self.ids[key] = len(self.op)
        self.prefix.append(prefix)
        self.op.append(op)
        self.kids.append(kids)
        return nid

    def leaf(self, prefix: tuple) -> int:
        nid = self.ids.get(prefix)
        return nid if nid is not None else self._new(prefix, prefix, None, ())

    def constant(self, value: np.ndarray) -> int:
        key = ("const", value.tobytes())
        nid = self.ids.get(key)
        if nid is None:
            nid = self._new(key, key, None, ())
            self.const[nid] = value
        return nid

    def node(self, prefix: tuple, op: Callable, kids: tuple[int, ...]) -> int:
        """The node `_vec(op(*values of kids))`; folded now if every kid is constant."""
        key = prefix + kids
        nid = self.ids.get(key)
        if nid is not None:
            return nid
        const = self.const
        if all(k in const for k in kids):
            value = _vec(op(*[const[k] for k in kids]))
            nid = self._new(key, prefix, op, kids)
            const[nid] = value
            return nid
        return self._new(key, prefix, op, kids)

    def is_step(self, nid: int) -> bool:
        return self.op[nid] is not None and nid not in self.const


def _slot_signature(v: VarInstance) -> tuple[int, int]:
    """What compiling a body needs to know about a slot's variable."""
    return v.waypoints, v.dim


class _Compiler:
    """Turns a body into nodes of a table whose leaves are the slots ("slot", j)."""

    def __init__(self, body: tuple[Constraint, ...], sigs: tuple[tuple[int, int], ...],
                 table: _Table):
        self.body, self.sigs, self.t = body, sigs, table
        self.leaves = [table.leaf(("slot", j)) for j in range(len(sigs))]
        self.seen: dict[int, int] = {}       # id(expr) -> node: a shared subtree compiles once

    def slot(self, e: Any) -> int:
        if not 0 <= e.index < len(self.sigs):
            raise EvaluationError(f"slot {e.index} of a factor with {len(self.sigs)} variables")
        return e.index

    def waypoint(self, e: Any, k: int) -> int:
        if not isinstance(e, Slot) or not self.sigs[self.slot(e)][0]:
            raise EvaluationError("waypoint of a non-trajectory")
        n, dim = self.sigs[e.index]
        d = dim // n
        return self.t.node(("waypoint", k, n, d), lambda x: x.reshape(n, d)[k],
                           (self.leaves[e.index],))

    def body_of(self, e: Any) -> Body:
        b = Body.of(e)
        if b is None:
            raise EvaluationError(f"not a body: {e!r}")
        return b

    def num(self, value: float) -> int:
        return self.t.constant(np.array([value]))

    def expr(self, e: Any) -> int:
        nid = self.seen.get(id(e))
        if nid is not None:
            return nid
        cls = e.__class__
        if cls is Call:
            nid = self.call(e)
        elif cls is Num:
            nid = self.num(float(e.value))
        elif cls is Vec and e.items and all(i.__class__ is Num for i in e.items):
            nid = self.t.constant(np.array([float(i.value) for i in e.items]))
        else:
            nid = self._expr(e)
        self.seen[id(e)] = nid
        return nid

    def _expr(self, e: Any) -> int:
        t = self.t
        if isinstance(e, Num):
            return self.num(float(e.value))
        if isinstance(e, Slot):
            return self.leaves[self.slot(e)]
        if isinstance(e, Vec):
            kids = tuple([self.expr(i) for i in e.items])
            return t.node(("vec",), lambda *xs: np.concatenate(xs), kids)
        if isinstance(e, Index):
            i = int(_const(e.index))
            if isinstance(e.base, Slot) and self.sigs[self.slot(e.base)][0] and e.stop is None:
                return self.waypoint(e.base, i)
            b = self.expr(e.base)
            if e.stop is None:
                return t.node(("index", i), lambda x: x[[i]], (b,))
            stop = int(_const(e.stop))
            return t.node(("slice", i, stop), lambda x: x[i:stop], (b,))
        if isinstance(e, Call):
            return self.call(e)
        raise EvaluationError(f"cannot evaluate {e!r}")

    def call(self, e: Call) -> int:
        t, fn, A = self.t, e.fn, e.args
        if fn == "pow":
            p = _const(A[1])
            return t.node(("pow", p), lambda x: x ** p, (self.expr(A[0]),))
        if fn == "waypoint":
            return self.waypoint(A[0], int(_const(A[1])))
        if fn == "axis_se3":
            j = int(_const(A[1]))
            return t.node((fn, j), lambda x: _rot(x[3:7])[:, j], (self.expr(A[0]),))
        if fn == "quat_axis":
            j = int(_const(A[1]))
            return t.node((fn, j), lambda x: _rot(x)[:, j], (self.expr(A[0]),))
        if fn == "fk":
            robot, frame = A[0].name, A[2].value
            return t.node(("fk", robot, frame), lambda g, q, b: g.fk_numeric(robot, q, frame, b),
                          (_GEO, self.expr(A[1]), self.expr(A[3])))
        if fn == "sdist":
            ba, bb = self.body_of(A[0]), self.body_of(A[2])
            return t.node(("sdist", ba.name, ba.link, bb.name, bb.link),
                          lambda g, a, b: g.sdist_numeric(ba, a, bb, b),
                          (_GEO, self.expr(A[1]), self.expr(A[3])))
        if fn == "sdist2":
            ba, bb = self.body_of(A[0]), self.body_of(A[2])
            return t.node(("sdist2", ba.name, ba.link, bb.name, bb.link),
                          lambda g, a, b: g.sdist2_numeric(ba, a, bb, b),
                          (_GEO, self.expr(A[1]), self.expr(A[3])))
        kernel = _NUMERIC.get(fn)
        if kernel is None:
            raise EvaluationError(f"cannot evaluate the primitive {fn!r}")
        return t.node((fn,), kernel, tuple([self.expr(a) for a in A]))

    def constraint(self, c: Constraint) -> tuple[bool, int]:
        lhs, rhs = self.expr(c.lhs), self.expr(c.rhs)
        kids = (lhs, rhs) if c.op != ">=" else (rhs, lhs)
        return c.op == "==", self.t.node(("sub",), _NUMERIC["sub"], kids)


class _Template:
    """A body compiled once for every factor with that body and those slot signatures: its
    nodes in a small table (leaves: the slots), in an order where children come first."""

    __slots__ = ("table", "order", "rows", "size")

    def __init__(self, body: tuple[Constraint, ...], sigs: tuple[tuple[int, int], ...]):
        self.table = t = _Table()
        c = _Compiler(body, sigs, t)
        self.rows = [c.constraint(con) for con in body]
        self.size = len(c.seen)             # expression objects in the body (it is held)
        order: list[int] = []
        done: set[int] = set()
        for _, root in self.rows:           # post-order from the rows: only needed nodes
            stack = [(root, False)]
            while stack:
                nid, expanded = stack.pop()
                if nid in done:
                    continue
                if expanded or not t.is_step(nid):
                    done.add(nid)
                    order.append(nid)
                    continue
                stack.append((nid, True))
                stack.extend((k, False) for k in t.kids[nid] if k not in done)
        self.order = order


class _Program:
    """One factor instance: its variables' leaves in the shared table, the constants and steps
    it needs (children before parents), its rows, and its rows at its last few inputs."""

    __slots__ = ("vars", "consts", "steps", "rows", "eq_at", "ineq_at", "recent", "table")

    def __init__(self, template: _Template, factor: FactorInstance, table: _Table):
        loc = template.table
        g: dict[int, int] = {_GEO: _GEO}
        leaves = [table.leaf(("v", v)) for v in factor.variables]
        steps: list[int] = []
        consts: list[int] = []
        placed: set[int] = set()
        for i in template.order:
            if i == _GEO:
                continue
            if i in loc.const:
                nid = g[i] = table.constant(loc.const[i])
                consts.append(nid)
            elif loc.op[i] is None:
                g[i] = leaves[loc.prefix[i][1]]
            else:
                nid = g[i] = table.node(loc.prefix[i], loc.op[i], tuple([g[k] for k in loc.kids[i]]))
                if nid not in placed:
                    placed.add(nid)
                    steps.append(nid)
        self.vars = list(zip(leaves, factor.variables))
        self.consts = tuple(consts)
        self.steps = tuple(steps)
        self.rows = tuple((eq, g[h]) for eq, h in template.rows)
        self.eq_at = tuple(i for i, (eq, _) in enumerate(self.rows) if eq)
        self.ineq_at = tuple(i for i, (eq, _) in enumerate(self.rows) if not eq)
        self.table = table
        self.recent: dict[tuple, list[np.ndarray]] = {}


_TABLE = _Table()
_MAX_NODES = 1_000_000
"""Above this many nodes the shared table is emptied (with every compiled factor) before a call.
Why 1M, not 200k (issue 19, helper scale): one check of stack_32's plan graph (24293 factors)
builds ~400k nodes (594k at the end of a solve), so with 200k the next call emptied the table,
every factor was compiled again and no remembered row survived: 6 times per solve, 78k factor
programs for ~50k factors, the final re-checks (`Run.solution`) 2 x 9.4 s CPU. The peak RSS is
the same (1.69 GB against 1.72 GB: the table reached that size before each emptying anyway)."""

_BODIES: dict[tuple, tuple[tuple, _Template]] = {}
"""(id(body), slot signatures) -> (body, template). The factory hands the same body object to
the instances of a rule at every step (time invariance), so a body is compiled once per object.
By identity, not by equality: equal bodies would share one compiled form even where they differ
in the sign of a zero constant (Num(0.0) == Num(-0.0)), and hashing a whole tree costs about as
much as compiling it. The body is held, so its id stays its own."""
_MAX_TEMPLATES = 10_000      # stack_32 holds 4769 bodies (2000 emptied them 3 times per solve)
_MAX_HELD = 1_000_000
"""Expression objects of the held bodies above which `_BODIES` is emptied before a call (the
factory holds the bodies of a problem anyway; this bounds what outlives it, ~150 MB)."""
_held = 0


def _template(factor: FactorInstance) -> _Template:
    """The compiled body of a factor, shared by every factor with the same body object and slot
    signatures."""
    body, sigs = factor.body, tuple([_slot_signature(v) for v in factor.variables])
    global _held
    hit = _BODIES.get((id(body), sigs))
    if hit is not None and hit[0] is body:
        return hit[1]
    tpl = _Template(body, sigs)
    _BODIES[(id(body), sigs)] = (body, tpl)
    _held += tpl.size
    return tpl


_RECENT = 4
"""Inputs remembered per factor (the checker asks several subgraphs about one point)."""


_PROGRAMS: dict[int, tuple[weakref.ref, _Program]] = {}


def _program(factor: FactorInstance) -> _Program:
    """The compiled form of a factor instance, cached while the instance lives."""
    key = id(factor)
    hit = _PROGRAMS.get(key)
    if hit is not None and hit[0]() is factor and hit[1].table is _TABLE:
        return hit[1]
    paused = gc.isenabled()
    if paused:          # compiling allocates many small objects that all stay alive: a
        gc.disable()    # collection pass would find nothing, but walk every object in the heap
    try:
        prog = _Program(_template(factor), factor, _TABLE)
    finally:
        if paused:
            gc.enable()
    try:
        ref = weakref.ref(factor, lambda r, k=key: _forget(k, r))
    except TypeError:                     # not weak-referenceable: compile on every call
        return prog
    _PROGRAMS[key] = (ref, prog)
    return prog


def _forget(key: int, ref: weakref.ref) -> None:
    hit = _PROGRAMS.get(key)
    if hit is not None and hit[0] is ref:
        del _PROGRAMS[key]


_GEOMETRIES: dict[int, tuple[weakref.ref, int]] = {}
_TOKENS = iter(range(1, 1 << 62))


def _geometry_token(geometry: Any) -> int | None:
    """A number naming this geometry object while it lives (None: do not remember results)."""
    if geometry is None:
        return 0
    key = id(geometry)
    hit = _GEOMETRIES.get(key)
    if hit is not None and hit[0]() is geometry:
        return hit[1]

    def forget(ref: weakref.ref, key: int = key) -> None:
        if _GEOMETRIES.get(key, (None,))[0] is ref:
            del _GEOMETRIES[key]
    try:
        ref = weakref.ref(geometry, forget)
    except TypeError:
        return None
    token = next(_TOKENS)
    _GEOMETRIES[key] = (ref, token)
    return token


def _start_call(geometry: Any) -> tuple[dict, int | None]:
    """The memo of one public call (holding the geometry) and the geometry's token."""
    global _TABLE, _held
    if len(_TABLE.op) > _MAX_NODES:      # bound the memory; only between calls
        _TABLE = _Table()
        _PROGRAMS.clear()
    if len(_BODIES) > _MAX_TEMPLATES or _held > _MAX_HELD:
        _BODIES.clear()
        _held = 0
    return {_GEO: geometry}, _geometry_token(geometry)


_ERRORS = (ValueError, IndexError, TypeError, KeyError, AttributeError, ZeroDivisionError)


def _values_of_rows(factor: FactorInstance, values: Mapping[VarInstance, Any], m: dict,
                    token: int | None) -> tuple[_Program, list[np.ndarray]]:
    """(program, h of every constraint) of a factor; `m` is the memo of the current call."""
    try:
        prog = _program(factor)
        key: list = [token]
        for nid, var in prog.vars:
            x = m.get(nid)
            if x is None:
                try:
                    raw = values[var]
                except KeyError:
                    raise EvaluationError(f"no value for variable {var}") from None
                x = m[nid] = np.asarray(raw, float).reshape(-1)
            key.append(x.tobytes())
        k = tuple(key)
        if token is not None:
            hs = prog.recent.get(k)
            if hs is not None:
                return prog, hs
        const = prog.table.const
        for nid in prog.consts:
            if nid not in m:
                m[nid] = const[nid]
        ops, args = prog.table.op, prog.table.kids
        for nid in prog.steps:
            if nid not in m:
                ks = args[nid]
                if len(ks) == 2:
                    m[nid] = _vec(ops[nid](m[ks[0]], m[ks[1]]))
                elif len(ks) == 1:
                    m[nid] = _vec(ops[nid](m[ks[0]]))
                else:
                    m[nid] = _vec(ops[nid](*[m[k] for k in ks]))
        hs = [m[h] for _, h in prog.rows]
    except EvaluationError:
        raise
    except _ERRORS as err:
        raise EvaluationError(f"{getattr(factor, 'label', factor)}: {type(err).__name__}: {err}") \
            from err
    if token is not None:
        if len(prog.recent) >= _RECENT:
            del prog.recent[next(iter(prog.recent))]     # oldest first
        prog.recent[k] = hs
    return prog, hs


def _margin(prog: _Program, hs: list[np.ndarray]) -> float:
    """Largest row value, signed (|h| for equalities, h for inequalities, which hold at h <= 0);
    -inf for a factor without rows, NaN anywhere -> inf."""
    worst = -math.inf
    for at, eq in ((prog.eq_at, True), (prog.ineq_at, False)):
        if not at:
            continue
        h = hs[at[0]] if len(at) == 1 else np.concatenate([hs[i] for i in at])
        if not h.size:
            continue
        v = float(np.abs(h).max() if eq else h.max())
        if v != v:
            return math.inf
        if v > worst:
            worst = v
    return worst


def _worst(prog: _Program, hs: list[np.ndarray]) -> float:
    """Largest row violation (|h| for equalities, max(h, 0) otherwise); NaN anywhere -> inf."""
    return max(_margin(prog, hs), 0.0)


# ---------------------------------------------------------------------------------------------
# public functions
# ---------------------------------------------------------------------------------------------
def constraint_rows(factor: FactorInstance, values: Mapping[VarInstance, Any],
                    geometry: Geometry | None = None) -> list[tuple[str, float]]:
    """[(kind, h)] for every row of the factor, kind "eq" (h = 0) or "ineq" (h <= 0)."""
    m, token = _start_call(geometry)
    prog, hs = _values_of_rows(factor, values, m, token)
    rows: list[tuple[str, float]] = []
    for (eq, _), h in zip(prog.rows, hs):
        kind = "eq" if eq else "ineq"
        rows += [(kind, v) for v in h.tolist()]
    return rows


def factor_violation(factor: FactorInstance, values: Mapping[VarInstance, Any],
                     geometry: Geometry | None = None) -> float:
    """Largest violation over the factor's rows (0 when satisfied, NaN counts as infinite)."""
    m, token = _start_call(geometry)
    return _worst(*_values_of_rows(factor, values, m, token))


def max_violation(factors: Iterable[FactorInstance], values: Mapping[VarInstance, Any],
                  geometry: Geometry | None = None) -> tuple[float, FactorInstance | None]:
    """(largest violation over all factors, the factor attaining it; None if no factor).

    One memo for the whole call: a node shared by several factors is evaluated once."""
    m, token = _start_call(geometry)
    best, arg = 0.0, None
    for f in factors:
        v = _worst(*_values_of_rows(f, values, m, token))
        if arg is None or v > best:
            best, arg = v, f
    return best, arg


def factor_margins(factors: Iterable[FactorInstance], values: Mapping[VarInstance, Any],
                   geometry: Geometry | None = None) -> list[float]:
    """Per factor, its largest row value, signed: h for inequality rows (h <= 0 holds, so a
    negative margin says how far the factor is from becoming active), |h| for equality rows;
    NaN counts as infinite. Why signed: `gnppdsl.solve.screening` keeps only the collision
    factors within a distance of becoming active, which `max_violation` (0 for every factor
    that holds) cannot tell apart. One memo for the whole call, as `max_violation`."""
    m, token = _start_call(geometry)
    return [_margin(*_values_of_rows(f, values, m, token)) for f in factors]
