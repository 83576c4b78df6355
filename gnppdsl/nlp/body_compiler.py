"""Resolved (stage-2) factor bodies -> casadi Functions, one per body structure, built and cached.

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
of kind "eq" (h = 0) or "ineq" (h <= 0); what the rows are (the lowering of the expression
language, the builtins in casadi) is `gnppdsl.nlp.lowering`.

Functions are built from SX (fully expanded, fastest) unless the injected geometry says a used
primitive needs MX (a `casadi.Callback`); either kind can be called on MX symbols during
assembly (`gnppdsl.nlp.feasibility`).
"""
from __future__ import annotations

import hashlib
from dataclasses import dataclass, field, fields, is_dataclass, replace
from typing import Any, Callable

import casadi as ca
import numpy as np

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.nlp.function_store import FunctionStore
from gnppdsl.nlp.jit import FLAGS
from gnppdsl.ir.expr import Obj
from gnppdsl.nlp.geometry_protocol import GEOMETRY_PRIMITIVES, Body, Geometry
from gnppdsl.nlp.lowering import (BodyError, BodyLowering, RowGroup, SlotSignature, constraint_rows,
                                  lift_constants, row_groups, structure_key, uses)


@dataclass(frozen=True, eq=False)
class CompiledBody:
    """One casadi Function for a body structure, with the kind of each output row. Compared
    and hashed by identity (the caches key compiled bodies by `id`)."""

    source: Any                     # `function`, or a zero-argument callable building it
    kinds: tuple[str, ...]          # "eq" | "ineq", one per row of h
    n_params: int
    symbolic: str                   # "SX" | "MX"
    primitives: frozenset[str] = frozenset()   # geometry primitives used (fk, sdist, sdist2)
    groups: tuple[RowGroup, ...] = field(default=(), compare=False)   # see `row_groups`
    # with stop-gradient symbols (see `lowering.BodyLowering.open_stops`): (x.., p, o) -> h with the callback
    # outputs o as an input, and (x.., p) -> o; `function` is the first with o substituted
    open_function: ca.Function | None = field(default=None, compare=False)
    stops: ca.Function | None = field(default=None, compare=False)
    # `function`'s values for evaluation only: the open function of the fast stop-gradient
    # values (`GeometryContext.witness_fast`, native distance queries); not differentiable
    evaluate: ca.Function | None = field(default=None, compare=False)
    # `function`'s name and its slots' dimensions (its inputs but the last, p), known without
    # building it; read from `source` when it is a Function
    name: str = ""
    slot_dims: tuple[int, ...] = ()
    # with stop-gradient symbols: (x.., p, o) -> (h, the fast stop-gradient values) in one
    # graph, the values' inputs sharing the rows' kinematic chains (`_open_rows`' shared form)
    joint: ca.Function | None = field(default=None, compare=False)

    def __post_init__(self) -> None:
        f = self.source
        if isinstance(f, ca.Function):
            object.__setattr__(self, "name", f.name())
            object.__setattr__(self, "slot_dims", tuple(f.size1_in(j) for j in range(f.n_in() - 1)))

    @property
    def function(self) -> ca.Function:
        """(x_0, ..., x_{m-1}, p) -> h, the distance queries as their differentiable callbacks
        (`Geometry.sdist_parts`), the form casadi differentiates itself. Built on first use
        when the body queries distances (`source` a builder, `_with_queries`). Why lazily: the
        solver's default path never evaluates it (ipopt gets `evaluate` as g and the
        per-template derivatives from `open_function` and `stops`); building it cost a
        substitution of the callbacks into the whole SX graph and a Function per template,
        ~0.14 s of lab1_paper's 0.70 s of loading stored templates in a cold process. Its
        name and slot dimensions are `name` and `slot_dims`."""
        f = self.source
        if not isinstance(f, ca.Function):
            f = f()
            object.__setattr__(self, "source", f)
        return f

    @property
    def n_rows(self) -> int:
        return len(self.kinds)


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


def scatter_parts(n_rows: int, n_cols: int, entries: list, parts: list) -> ca.MX:
    """The sparse matrix with entry (row, col, k) of `entries` adding element k of the stacked
    `parts` at (row, col): the Jacobian and Hessian assembly's final scatter, done by
    `scatter_sum` (one constant sparse product)."""
    ent = np.array(entries, dtype=np.int64).reshape(-1, 3)
    values = ca.vertcat(*[ca.vec(q) for q in parts])
    return scatter_sum(n_rows, n_cols, ent[:, 0], ent[:, 1], values[ent[:, 2].tolist()])


def mapped_inputs(x: ca.MX, P: ca.MX, cb, k: int, stacked, p0: int) -> tuple[list, ca.MX]:
    """The inputs of one template's k instances for a mapped call: each variable slot as a
    (dim x k) matrix gathered from x, and the parameters as (n_params x k). Shared by the
    Jacobian and Hessian assembly so both read the instances in the same layout."""
    slots = []
    for j, d in enumerate(cb.slot_dims):
        lo = sum(cb.slot_dims[:j])
        idx = [stacked[t][lo + m] for t in range(k) for m in range(d)]
        slots.append(ca.reshape(x[idx], d, k))
    Pg = ca.reshape(P[p0:p0 + cb.n_params * k], cb.n_params, k) if cb.n_params else ca.MX(0, k)
    return slots, Pg


def _split(v, fn: ca.Function, n: int) -> list:
    """The first n inputs of `fn` cut from one stacked column `v`."""
    out, lo = [], 0
    for i in range(n):
        d = fn.size1_in(i)
        out.append(v[lo:lo + d])
        lo += d
    return out


def _renamed(e: Any, m: dict[str, str]) -> Any:
    """`e` (row groups, distance-query bodies: tuples, lists and frozen dataclasses of the
    expression tree) with every object name n replaced by m[n] (KeyError: a name outside m)."""
    if isinstance(e, Obj):
        return Obj(m[e.name], span=e.span)
    if isinstance(e, Body):
        return Body(m[e.name], link=e.link)
    if isinstance(e, (tuple, list)):
        return type(e)(_renamed(x, m) for x in e)
    if is_dataclass(e) and not isinstance(e, type):
        return replace(e, **{f.name: _renamed(getattr(e, f.name), m) for f in fields(e) if f.init})
    return e


@dataclass(frozen=True)
class _Named:
    """An object name replaced by its geometry's structure key (cache keys only)."""

    key: Any


def _fname(name: str) -> str:
    return "h_" + "".join(ch if ch.isalnum() else "_" for ch in name)


def _has_repeats(cb: CompiledBody) -> bool:
    """True when some row group has several members (derivatives are then assembled from one
    representative per group); bodies without repeats are differentiated directly."""
    return cb.symbolic == "SX" and any(len(g.members) > 1 for g in cb.groups)


def _symbols(cb: CompiledBody) -> tuple[list, Any]:
    slots = [ca.SX.sym(f"x{j}", d) for j, d in enumerate(cb.slot_dims)]
    return slots, ca.SX.sym("p", cb.n_params)


def _open_rows(cb: CompiledBody, slots: list, p, shared: bool = False) -> tuple[Any, Any, Any]:
    """(h, o, o's value) on SX symbols: with stop-gradient symbols, h is the open function of
    a fresh o (differentiate with o held constant, then substitute o's value); else o is
    empty. `shared`: h and o's value from one call of `CompiledBody.joint`, so that the
    queries' inputs are the very nodes of h's kinematic chains (what `_closed(fuse=True)`
    needs); else from two calls (two copies of the chains)."""
    if cb.open_function is None:
        return cb.function(*slots, p), ca.SX(0, 1), ca.SX(0, 1)
    O = ca.SX.sym("o", cb.open_function.size1_in(len(slots) + 1))
    if shared and cb.joint is not None:
        h, Ov = cb.joint(*slots, p, O)
        return h, O, Ov
    return cb.open_function(*slots, p, O), O, cb.stops(*slots, p)


def _closed(name: str, inputs: list, O, Ov, D, native: Callable | None = None,
            fuse: bool = False) -> ca.Function:
    """Function inputs -> D with the stop-gradient symbols O replaced by their values Ov (both
    functions of `inputs`). Why an MX wrapper around two SX Functions instead of
    `ca.substitute`: substituting into a Panda Hessian re-evaluates its whole SX graph (0.5 s of
    lab1's assembly); the wrapper costs two call nodes. `native` (a `jit.KernelCache.native`)
    may replace the pure SX part, the derivative itself, by compiled code.

    `fuse` (Jacobians without compiled kernels): one SX Function, O substituted by Ov, where
    Ov's inputs are nodes of D's own graph (`_open_rows(shared=True)`, a representative's one
    builder). Why: the wrapper's stop Function ran the kinematic chains a second time for the
    queries' inputs; fused, reverse AD's forward sweep (which reuses the rows' nodes) feeds
    the queries too. Measured on `bench_komo.py`'s keyframe NLP templates (casadi's virtual
    machine, per call): panda clear_gripper 19.6 -> 13.1 us (k=2 form), 34.1 -> 18.7 us
    (grasp form), self_clear 9.4 -> 7.4 us; the same values (0 difference); build +2-6 ms
    per template (the substitution)."""
    if fuse and native is None and O.numel():
        return ca.Function(name, inputs, [ca.substitute(D, O, Ov)])
    native = native or (lambda f: f)
    if O.numel() == 0:
        return native(ca.Function(name, inputs, [D]))
    open_f = native(ca.Function(name + "_open", [*inputs, O], [D]))
    stop_f = ca.Function(name + "_stops", inputs, [Ov])
    m = [ca.MX.sym(f"a{i}", x.sparsity()) for i, x in enumerate(inputs)]
    return ca.Function(name, m, [open_f(*m, stop_f(*m))])


def _with_queries(fname: str, slots: list, p, out, O, Ov: Callable[[], Any], fast) -> tuple:
    """(f, open_f, stops, evaluate, joint) of a body whose rows `out` read the distance queries'
    values through the symbols O: a builder of f, the rows with the queries' differentiable
    callbacks `Ov()` substituted (built on first use: `CompiledBody.function`), the open form
    (x.., p, o), the queries' fast twins `fast` alone, one graph with the fast twins
    substituted (the queries' inputs share the kinematic chains with the model), and the open
    rows with the fast twins as a second output of one graph (`CompiledBody.joint`). Shared by a
    freshly lowered body and one loaded from the store, so their graphs are equal."""
    open_f = ca.Function(fname + "_open", [*slots, p, O], [out])
    # the stop-gradient values are only ever evaluated: the fast twins
    stops = ca.Function(fname + "_stops", [*slots, p], [fast])
    evaluate = ca.Function(fname + "_eval", [*slots, p], [ca.substitute(out, O, fast)])
    joint = ca.Function(fname + "_joint", [*slots, p, O], [out, fast])

    def f() -> ca.Function:
        return ca.Function(fname, [*slots, p], [ca.substitute(out, O, Ov())])
    return f, open_f, stops, evaluate, joint


def sx_jacobian(out, X, others: list) -> Any:
    """d out / d X as an SX expression (X a vertcat of symbols, `others` the other symbols `out`
    depends on): by reverse AD when `out` has at most as many rows as X has entries, else by
    forward or reverse AD, whichever gives the shorter graph. Why not `ca.jacobian`'s own
    choice: casadi picks the mode from the sparsity colouring with forward sweeps weighted
    cheaper, and so takes forward mode for most Panda bodies, whose reverse sweeps give a
    1.4-2x shorter graph (SX instructions of lab1's templates, casadi's choice -> this: panda
    clear_gripper 9733 -> 5194, self_clear 7696 -> 4468, grasp 12197 -> 7089, clear_arms
    71330 -> 36088 (34 rows of 14 entries: both built); in all 155k -> 107k;
    `benchmarks/bench_komo.py`'s keyframe NLP: its constraint Jacobian ~584 -> ~410 us a call,
    run every ipopt iteration by casadi's virtual machine). Build time of lab1's Panda
    Jacobians 0.07 -> 0.14 s (both modes for every body: 0.22 s, for 2 % fewer instructions)."""
    others = [o for o in others if o.numel()]
    if out.numel() <= X.numel():
        # no more reverse sweeps than forward ones: reverse mode, one build (on lab1's bodies
        # of this shape never longer than casadi's choice; kin_switch_rel's forward graph is
        # 23 % shorter still)
        return ca.jacobian(out, X, {"helper_options": {"ad_weight": 1.0, "ad_weight_sp": 1.0}})
    best, size = None, None
    for w in (1.0, 0.0):
        J = ca.jacobian(out, X, {"helper_options": {"ad_weight": w, "ad_weight_sp": w}})
        n = ca.Function("J", [X, *others], [J]).n_instructions()
        if best is None or n < size:
            best, size = J, n
    return best


def direct_jacobian(cb: CompiledBody, native: Callable | None = None) -> ca.Function:
    """(x_0, ..., p) -> dh/dX by differentiating the whole body at once (reference for the
    grouped assembly; used for bodies without repeated constraints)."""
    slots, p = _symbols(cb)
    X = ca.vertcat(*slots)
    out, O, Ov = _open_rows(cb, slots, p, shared=native is None)
    return _closed(cb.name + "_jac", [*slots, p], O, Ov, sx_jacobian(out, X, [p, O]), native,
                   fuse=True)


def direct_hessian(cb: CompiledBody, native: Callable | None = None) -> ca.Function:
    """(x_0, ..., p, lam) -> d^2 (lam . h) / dX^2 by differentiating the whole body at once."""
    slots, p = _symbols(cb)
    lam = ca.SX.sym("lam", cb.n_rows)
    X = ca.vertcat(*slots)
    out, O, Ov = _open_rows(cb, slots, p)
    H = ca.hessian(ca.dot(lam, out), X)[0] if cb.n_rows else ca.SX(X.numel(), X.numel())
    return _closed(cb.name + "_hess", [*slots, p, lam], O, Ov, H, native)


class BodyCompiler:
    """Compiles factor bodies to casadi Functions, cached by (template, structure).

    Why a class: it owns the cache and the injected geometry, and lives as long as a solve loop
    so that every template is compiled once across all the graph-NLPs of the loop."""

    def __init__(self, geometry: Geometry | None = None, kernels: Any = None, store: Any = "default"):
        """`kernels`: a `gnppdsl.nlp.jit.KernelCache` to run the large derivative kernels as
        compiled code (None: casadi's virtual machine). `store`: a
        `gnppdsl.nlp.function_store.FunctionStore` of built bodies persisted across processes
        ("default": `FunctionStore.default()`, None: build every body)."""
        self.geometry = geometry
        self.store = FunctionStore.default() if store == "default" else store
        self.loaded = 0             # of `compiled`, how many came from the store
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
        self._keys: dict[int, tuple[CompiledBody, str]] = {}   # id(cb) -> (cb, its store key)

    def jacobian(self, cb: CompiledBody) -> ca.Function:
        """(x_0, ..., x_{m-1}, p) -> dh/dX (X the stacked slots), an SX Function built once per
        compiled body (see `hessian` for why the nlp layer assembles derivatives itself, and
        `_grouped_derivative` for bodies with repeated per-waypoint constraints)."""
        hit = self._jacobians.get(id(cb))
        if hit is not None and hit[0] is cb:
            return hit[1]
        jf = self._grouped_derivative(cb, False) if _has_repeats(cb) else self._direct(cb, False)
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
        hf = self._grouped_derivative(cb, True) if _has_repeats(cb) else self._direct(cb, True)
        self._hessians[id(cb)] = (cb, hf)
        return hf

    def _direct(self, cb: CompiledBody, hessian: bool) -> ca.Function:
        """`direct_hessian` or `direct_jacobian` of cb; with compiled kernels and a store, its
        kernel loaded by the key remembered for cb's stored body, without building the SX
        derivative (`_stored_derivative`)."""
        build = direct_hessian if hessian else direct_jacobian
        k = self._keys.get(id(cb))
        if k is None or k[0] is not cb or self.kernels is None or self.store is None:
            return build(cb, self._native)
        dkey = hashlib.sha256(f"{k[1]}|{'hessian' if hessian else 'jacobian'}|{FLAGS}".encode()).hexdigest()
        fn = self._stored_derivative(cb, dkey, hessian)
        if fn is not None:
            return fn
        used = []

        def native(f: ca.Function) -> ca.Function:
            g = self._native(f)
            used.append(self.kernels.last)
            return g
        fn = build(cb, native)
        if len(used) == 1 and used[0] is not None:
            self.store.save(dkey, {"kernel": used[0][0], "expected": used[0][1]})
        return fn

    def _stored_derivative(self, cb: CompiledBody, dkey: str, hessian: bool) -> ca.Function | None:
        """cb's direct derivative from its compiled kernel, found by the kernel key stored
        under `dkey` (`KernelCache.cached`: the library checked against the values stored
        with the key), the distance queries' values from cb's own `stops` as `_closed` feeds
        them; None when either is missing. Why: building a large body's SX Hessian costs more
        than everything else of its set-up, and when its kernel is compiled the SX graph is
        only used for the kernel's key (field3: 53 per-body Hessians, 0.6-0.9 s CPU per
        process; casadi's serialization of them, 118 MB, loads slower than they build)."""
        rec = self.store.load(dkey)
        g = self.kernels.cached(rec["kernel"], rec["expected"]) if rec is not None else None
        if g is None:
            return None
        if cb.open_function is None:
            return g
        n = len(cb.slot_dims) + 1
        if g.n_in() != n + 1 + hessian:
            return None
        m = [ca.MX.sym(f"a{i}", g.sparsity_in(i)) for i in range(g.n_in() - 1)]
        return ca.Function(cb.name + ("_hess" if hessian else "_jac"), m, [g(*m, cb.stops(*m[:n]))])

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
        builder = BodyLowering(slots, wsigs, p, self.geometry, pts, open_stops=True)
        builder.plan_chains(ac)
        h = ca.vertcat(*(constraint_rows(builder, c) for c in ac))
        fn = None
        if (pts or slots) and h.numel():
            X = ca.vertcat(*pts, *slots)
            # derivatives with the stop-gradient symbols held constant, then their values
            # (evaluated only: the fast twins)
            O, Ov = ((ca.vertcat(*[o for o, _ in builder.stops]), ca.vertcat(*builder.fast_stops))
                     if builder.stops else (ca.SX(0, 1), ca.SX(0, 1)))
            if hessian:
                lam = ca.SX.sym("lam", h.numel())
                D = ca.hessian(ca.dot(lam, h), X)[0]
            else:
                D = sx_jacobian(h, X, [p, O])
            ins = [*pts, *slots, p, lam] if hessian else [*pts, *slots, p]
            # (one builder: the queries' inputs are nodes of the rows' chains, `_closed`)
            fn = _closed("rep_hess" if hessian else "rep_jac", ins, O, Ov, D, self._native,
                         fuse=not hessian)
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
        sizes = list(cb.slot_dims)
        m = len(sizes)
        offs = np.concatenate([[0], np.cumsum(sizes)]).astype(np.int64)
        n_x = int(offs[-1])
        S = ca.SX if inline else ca.MX
        slots = [S.sym(f"x{j}", sizes[j]) for j in range(m)]
        p = S.sym("p", cb.n_params)
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
            return ca.Function(cb.name + "_hess", [*slots, p, lam], [M])
        return ca.Function(cb.name + "_jac", [*slots, p], [M])

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
        # object and robot names by what their geometry depends on (`structure_key`): bodies
        # that differ only in the name of a same-shaped block share one Function
        names: list[str] = []           # the objects named, in the walk's order

        def rename(name: str) -> Any:
            names.append(name)
            return self._structure_of(name)

        skey, params = structure_key(factor.body, rename)
        key = (factor.template, skey, sigs)
        cb = self._cache.get(key)
        if cb is None:
            # from the store, keyed by the same structure (no lifting, no lowering)
            store_key = None
            if self.store is not None:
                store_key = self.store.key(self.geometry, factor.template, skey, names, sigs,
                                           len(params), hasattr(self.geometry, "sdist_parts"))
                cb = self._stored(factor.template, sigs, len(params), store_key, names)
            if cb is None:
                key_body, lifted = lift_constants(factor.body)
                if lifted != params:      # the Function's parameters must be the key's
                    raise RuntimeError(f"{factor.label}: structure_key and lift_constants disagree")
                try:
                    cb = self._build(factor.template, key_body, sigs, len(params), store_key, names)
                except BodyError as err:
                    raise BodyError(f"{factor.label}: {err}") from None
            self._cache[key] = cb
            self.compiled += 1
            if store_key is not None:
                self._keys[id(cb)] = (cb, store_key)
        return cb, np.asarray(params, dtype=float)

    def _stored(self, name: str, sigs: tuple[SlotSignature, ...], n_params: int,
                store_key: str | None, names: list[str]) -> CompiledBody | None:
        """The body stored under `store_key`, or None (absent, or not attachable here).

        The key holds the body's structure, in which objects are their geometry's structure
        (as in the in-memory cache), so a body stored for other objects of the same structure
        (another problem's blocks, the other arm of the same model) is found too: the stored
        body's object names (`names` of the process that stored it, in the order of
        `structure_key`'s walk) are mapped to this body's, position by position, and its
        distance queries and row groups are renamed accordingly; a map that would send one
        name to two is a miss."""
        payload = self.store.load(store_key) if store_key is not None else None
        if payload is None:
            return None
        g = self.geometry
        if g is not None and any(g.needs_mx(p) for p in payload["primitives"]):
            return None                    # stored as SX, an MX body here: built instead
        stored = payload["names"]
        if len(stored) != len(names):
            return None
        m: dict[str, str] = {}
        for a, b in zip(stored, names):
            if m.setdefault(a, b) != b:
                return None
        try:
            if any(a != b for a, b in m.items()):
                payload = {**payload, "groups": _renamed(payload["groups"], m),
                           "stops": _renamed(payload["stops"], m)}
            cb = self._from_store(name, sigs, n_params, payload)
        except Exception:                  # a payload this geometry cannot attach: rebuild
            return None
        self.loaded += 1
        return cb

    def _build(self, name: str, body: tuple, sigs: tuple[SlotSignature, ...],
               n_params: int, store_key: str | None = None, names: list[str] = ()) -> CompiledBody:
        """The body lowered to casadi Functions (`_lower`), and stored under `store_key`
        with its object `names` (`_stored`; not MX bodies, nor graphs with an embedded
        callback)."""
        prims = uses(body, set(GEOMETRY_PRIMITIVES))
        mx = self.geometry is not None and any(self.geometry.needs_mx(p) for p in prims)
        cb, stored = self._lower(name, body, sigs, n_params, prims, mx)
        if store_key is not None and stored is not None:
            self.store.save(store_key, {**stored, "names": list(names)})
        return cb

    def _from_store(self, name: str, sigs: tuple[SlotSignature, ...], n_params: int,
                    payload: dict) -> CompiledBody:
        """A stored body's CompiledBody: the serialized open Function called on fresh
        symbols, its distance queries attached again from the live geometry, the same
        substitutions as `_lower` (equal graphs, `tests/nlp/test_nlp_function_store.py`)."""
        g = self.geometry
        fname = _fname(name)
        F = ca.Function.deserialize(payload["function"])
        meta = (tuple(payload["kinds"]), n_params, "SX", frozenset(payload["primitives"]),
                tuple(payload["groups"]))
        if not payload["stops"]:
            return CompiledBody(F, *meta)
        slots = [ca.SX.sym(f"x{j}", s.dim) for j, s in enumerate(sigs)]
        p = ca.SX.sym("p", n_params)
        O = ca.SX.sym("o", F.size1_in(len(slots) + 1))
        out, A = F(*slots, p, O)
        queries, fast, lo = [], [], 0          # (callback, its input), fast twins' outputs
        for a, b, planar in payload["stops"]:
            cbf = g.sdist_parts(a, b, planar)[0]
            x = A[lo:lo + cbf.size1_in(0)]
            lo += cbf.size1_in(0)
            queries.append((cbf, x))
            fast.append((g.witness_fast(a, b, planar) if hasattr(g, "witness_fast") else cbf)(x))
        if lo != A.numel():
            raise ValueError("stored distance queries do not match the geometry's")
        f, open_f, stops, evaluate, joint = _with_queries(
            fname, slots, p, out, O, lambda: ca.vertcat(*[cbf(x) for cbf, x in queries]),
            ca.vertcat(*fast))
        return CompiledBody(f, *meta, open_f, stops, evaluate, fname, tuple(s.dim for s in sigs),
                            joint)

    def _lower(self, name: str, body: tuple, sigs: tuple[SlotSignature, ...], n_params: int,
               prims: set, mx: bool) -> tuple[CompiledBody, dict | None]:
        """(the body lowered to casadi, the payload to store or None when it cannot be
        serialized: MX bodies, distance queries embedded without `sdist_parts`)."""
        S = ca.MX if mx else ca.SX
        slots = [S.sym(f"x{j}", s.dim) for j, s in enumerate(sigs)]
        p = S.sym("p", n_params)
        builder = BodyLowering(slots, sigs, p, self.geometry, open_stops=not mx)
        builder.plan_chains(body)
        rows, kinds = [], []
        for c in body:
            h = constraint_rows(builder, c)
            rows.append(h)
            kinds += ["eq" if c.op == "==" else "ineq"] * h.numel()
        out = ca.vertcat(*rows) if rows else S(0, 1)
        fname = _fname(name)
        open_f = stops = evaluate = joint = None
        if builder.stops:
            O, Ov = (ca.vertcat(*t) for t in zip(*builder.stops))
            f, open_f, stops, evaluate, joint = _with_queries(fname, slots, p, out, O, lambda: Ov,
                                                              ca.vertcat(*builder.fast_stops))
        else:
            f = ca.Function(fname, [*slots, p], [out])
        groups = row_groups(body, sigs, [h.numel() for h in rows]) if not mx else ()
        cb = CompiledBody(f, tuple(kinds), n_params, "MX" if mx else "SX", frozenset(prims),
                          groups, open_f, stops, evaluate, fname, tuple(s.dim for s in sigs), joint)
        stored = None
        if not mx and self.store is not None:
            try:
                # the open rows and the queries' inputs in one graph (shared chains)
                stored_f = f if open_f is None else ca.Function(
                    fname + "_stored", [*slots, p, O], [out, ca.vertcat(*builder.stop_inputs)])
                stored = {"function": stored_f.serialize(), "kinds": list(kinds),
                          "primitives": sorted(prims), "groups": groups,
                          "stops": list(builder.stop_bodies) if open_f is not None else []}
            except Exception:          # e.g. a callback embedded in the graph: not stored
                stored = None
        return cb, stored
