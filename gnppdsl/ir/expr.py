"""Expression IR: the bodies of constraint templates.

Two stages use the same node classes:

1. *Typed template bodies* (output of `ir` resolution + type checking): may contain `Param`
   (template parameters), `CVar` (continuous variable terms such as `pose(o)'`), `StateValue`
   (the object a state variable holds, e.g. `parent(o)`), `IterVar` (a `forall` index), `With`
   (substitution), and `Call`s of *user-level* functions (`world`, `sdist(a, b)`, `size`, ...).
   The type checker has already replaced every overloaded operator by a monomorphic builtin of
   `gnppdsl.ir.builtins` (e.g. pose `*` on SE2 -> `Call("compose_se2", ...)`), so later stages
   never need to re-infer types.

2. *Resolved factor bodies* (output of the graph-NLP factory in `gnppdsl.compile.factors`):
   parameters substituted, `world(o)` expanded along the kinematic chain of the symbolic state,
   scene attributes folded to `Num`/`Vec` constants, `forall` unrolled, `With` applied, and every
   continuous variable replaced by `Slot(j)` (the factor's j-th variable). Only `Num`, `Vec`,
   `Slot`, `Obj`, `Str`, `Call` (of `gnppdsl.ir.builtins` names), `Index` and `Constraint` remain.
   The nlp layer turns such a body into one casadi Function (cached by its structure).

Every node may carry a `span` (file, line, column) for diagnostics; spans never take part in
equality or hashing, so structurally equal bodies share one compiled function.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Union

from gnppdsl.lang.span import Span  # re-exported: IR nodes keep their source position




@dataclass(frozen=True)
class Num:
    value: float
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Str:
    """A string literal (frame and link names: `fk(r, q(r), "panda_hand_tcp")`)."""

    value: str
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Vec:
    items: tuple["Expr", ...]
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Param:
    """Reference to a template parameter (stage 1 only)."""

    name: str
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Obj:
    """A constant object of the problem (after substitution), e.g. `b1`."""

    name: str
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class IterVar:
    """The index of an enclosing `forall k in a..b` (stage 1 only)."""

    name: str
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class CVar:
    """A continuous variable term `name(args)` at step i, or at i+1 when `next` (written `'`)."""

    name: str
    args: tuple["Expr", ...]
    next: bool = False
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class StateValue:
    """The object held by a state variable, `parent(o)` (at i, or i+1 when `next`)."""

    name: str
    args: tuple["Expr", ...]
    next: bool = False
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Slot:
    """The j-th variable of a factor instance (stage 2 only)."""

    index: int
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Call:
    """Application of a builtin (`gnppdsl.ir.builtins.BUILTINS`) or a user-level function."""

    fn: str
    args: tuple["Expr", ...]
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Index:
    """`base[index]` on a vector (one component) or a trajectory (one waypoint).

    `stop` is set for slices `base[index:stop]` (end exclusive)."""

    base: "Expr"
    index: "Expr"
    stop: "Expr | None" = None
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class With:
    """`body with x = e, ...`: substitute continuous variable terms (stage 1 only).

    Used e.g. to evaluate `world(o)` along a trajectory waypoint: `world(o) with q(r) = path(r)[k]`.
    """

    body: "Expr"
    substitutions: tuple[tuple[CVar, "Expr"], ...]
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


Expr = Union[Num, Str, Vec, Param, Obj, IterVar, CVar, StateValue, Slot, Call, Index, With]


@dataclass(frozen=True)
class Constraint:
    """`lhs op rhs` with op in {"==", "<=", ">="}; h = lhs - rhs is the constraint function."""

    lhs: Expr
    op: str
    rhs: Expr
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Forall:
    """`forall k in lo..hi: body` (inclusive bounds; unrolled by the factory)."""

    var: str
    lo: Expr
    hi: Expr
    body: tuple["Constraint | Forall | Objective", ...]
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


@dataclass(frozen=True)
class Objective:
    """`minimize expr`: a scalar term of the objective (stages 1 and 2).

    Never a constraint: feasibility (the graph-NLPs of paper 000) ignores it; once a plan is
    feasible, the optimisation phase minimises the sum of the plan's terms subject to all of
    its factors (paper 002's optimal TAMP). The factory keeps the terms of a template call
    apart from its constraints (`GraphNLPFactory.objectives`)."""

    expr: Expr
    span: Span | None = field(default=None, compare=False, hash=False, repr=False)


Statement = Union[Constraint, Forall, Objective]
