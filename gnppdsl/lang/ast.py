"""Syntax tree of a .pntc file: what was written, with a `Span` on every node.

Why a separate AST (and not lark trees): the resolver and type checker pattern-match on named
fields instead of child positions, and every node carries the span diagnostics need. Nothing
here is resolved: names are just `Name`s; `gnppdsl.ir` turns this into `gnppdsl.ir.model`.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any, Union

from gnppdsl.lang.span import Span

_S = dict(default=None, compare=False, repr=False)


@dataclass(frozen=True)
class Name:
    value: str
    span: Span | None = field(**_S)

    def __str__(self) -> str:
        return self.value


# ------------------------------------------------------------------ logic
@dataclass(frozen=True)
class LTerm:
    """`name` (args None) or `name(args)`."""

    name: "Name | IndexedName"          # IndexedName only in `init` / `goal` facts
    args: tuple["LTerm", ...] | None
    span: Span | None = field(**_S)

    def text(self) -> str:
        if self.args is None:
            return self.name.value
        return f"{self.name.value}({', '.join(a.text() for a in self.args)})"


@dataclass(frozen=True)
class Lit:
    """kind "atom" (`clear(o)`), "not" (`not free(g)`), "cmp" (`parent(o) = x`, `a < b`)."""

    kind: str
    lhs: LTerm
    op: str | None = None
    rhs: LTerm | None = None
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class FOr:
    items: tuple["Formula", ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class FAnd:
    items: tuple["Formula", ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class FNot:
    item: "Formula"
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class FExists:
    params: tuple["Param", ...]
    body: "Formula"
    span: Span | None = field(**_S)


Formula = Union[Lit, FOr, FAnd, FNot, FExists]


@dataclass(frozen=True)
class Param:
    """`o: block`, `P: place | gripper`, or untyped `P` (types empty)."""

    name: Name
    types: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EffAssign:
    lhs: LTerm
    rhs: LTerm
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EffBool:
    lhs: LTerm
    value: bool
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EffWhen:
    cond: Formula
    effects: tuple["EffectAst", ...]
    span: Span | None = field(**_S)


EffectAst = Union[EffAssign, EffBool, EffWhen]


# ------------------------------------------------------------------ expressions
@dataclass(frozen=True)
class ENum:
    value: float
    text: str
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EStr:
    value: str
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ERef:
    """A (possibly qualified) name: `a`, `pi`, `planar.grasp_tol`."""

    qname: tuple[Name, ...]
    span: Span | None = field(**_S)

    @property
    def text(self) -> str:
        return ".".join(n.value for n in self.qname)


@dataclass(frozen=True)
class ECall:
    qname: tuple[Name, ...]
    args: tuple["ExprAst", ...]
    span: Span | None = field(**_S)

    @property
    def text(self) -> str:
        return ".".join(n.value for n in self.qname)


@dataclass(frozen=True)
class EVec:
    items: tuple["ExprAst", ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EBin:
    op: str                      # + - * / ^
    lhs: "ExprAst"
    rhs: "ExprAst"
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ENeg:
    arg: "ExprAst"
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EPrime:
    arg: "ExprAst"
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EIndex:
    base: "ExprAst"
    index: "ExprAst"
    stop: "ExprAst | None" = None
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class EWith:
    body: "ExprAst"
    substs: tuple[tuple["ExprAst", "ExprAst"], ...]
    span: Span | None = field(**_S)


ExprAst = Union[ENum, EStr, ERef, ECall, EVec, EBin, ENeg, EPrime, EIndex, EWith]


@dataclass(frozen=True)
class ConstraintAst:
    """`lhs op rhs` or a chain `a <= b <= c` (ops has one or two entries)."""

    operands: tuple[ExprAst, ...]
    ops: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ForallAst:
    var: Name
    lo: ExprAst
    hi: ExprAst
    body: tuple["StmtAst", ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class MinimizeAst:
    """`minimize e`: a scalar term of the objective (paper 002's optimal TAMP)."""

    expr: ExprAst
    span: Span | None = field(**_S)


StmtAst = Union[ConstraintAst, ForallAst, MinimizeAst]


# ------------------------------------------------------------------ declarations
@dataclass(frozen=True)
class SpaceAst:
    """`R`, `R[3]`, `SE2`, `joints(r)`, `value`, or an object type name (template params)."""

    name: Name
    dim: int | None = None
    arg: Name | None = None
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class SigParam:
    name: Name
    space: SpaceAst
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class Header:
    kind: str                    # "domain", "problem", "module"
    name: Name
    domain: Name | None = None   # problems: `for DOMAIN`
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class UseDecl:
    names: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class TypeDecl:
    names: tuple[Name, ...]
    parent: Name | None
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ConstDecl:
    name: Name
    expr: ExprAst
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ObjRange:
    """`b1..b16` in an `objects` or `constants` group: the objects b1, b2, ..., b16 (same prefix,
    integer suffixes; the resolver expands it and reports a bad range at its span)."""

    lo: Name
    hi: Name
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ObjGroup:
    names: tuple[Name | ObjRange, ...]
    type: Name
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ConstantsDecl:
    groups: tuple[ObjGroup, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ObjectsDecl:
    groups: tuple[ObjGroup, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class StateDecl:
    name: Name
    params: tuple[Param, ...]
    domain: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class DerivedDecl:
    name: Name
    params: tuple[Param, ...]
    body: Formula
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ActionDecl:
    name: Name
    params: tuple[Param, ...]
    pre: tuple[Lit, ...]
    effects: tuple[EffectAst, ...]
    cost: "ExprAst | None"                 # `cost 2`, `cost 10 + norm(...)`: see ir.resolve_costs
    duplicates: tuple[Name, ...] = ()      # repeated `pre`/`eff`/`cost` keywords (an error)
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ContinuousDecl:
    name: Name
    params: tuple[Param, ...]
    space: SpaceAst
    tags: tuple[Name, ...]
    traj: bool = False
    waypoints: ENum | None = None
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class FrameDecl:
    var: Name
    type: Name
    expr: ExprAst
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class TemplateDecl:
    name: Name
    params: tuple[SigParam, ...]
    tags: tuple[Name, ...]
    body: tuple[StmtAst, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class SceneAttrDecl:
    name: Name
    params: tuple[SigParam, ...]
    space: SpaceAst
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class PrimitiveDecl:
    name: Name
    params: tuple[SigParam, ...]
    space: SpaceAst
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class TCall:
    qname: tuple[Name, ...]
    args: tuple[ExprAst, ...]
    span: Span | None = field(**_S)

    @property
    def text(self) -> str:
        return ".".join(n.value for n in self.qname)


@dataclass(frozen=True)
class RuleDecl:
    name: Name
    params: tuple[Param, ...]
    where: tuple[Lit, ...]
    kind: str                    # "state", "transition", "always", "initial", "final"
    pre: tuple[Lit, ...]
    post: tuple[Lit, ...]
    calls: tuple[TCall, ...]
    tags: tuple[Name, ...]
    pattern_span: Span | None = field(**_S)
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class RelaxationAst:
    name: Name
    drop: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class AvoidDecl:
    """`avoid robots, objects, scene margin 0.01`: the categories whose bodies keep clear."""

    categories: tuple[Name, ...]
    margin: Any = None               # an expression (folded to a number), None: 0
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class RelaxationsDecl:
    items: tuple[RelaxationAst, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class Value:
    """A settings value: float/int, str (quoted), name (`gnpp`), or list of Values."""

    value: Any
    kind: str                    # "number", "string", "name", "list"
    span: Span | None = field(**_S)

    def plain(self) -> Any:
        if self.kind == "list":
            return [v.plain() for v in self.value]
        return self.value


@dataclass(frozen=True)
class Setting:
    key: Name
    value: Value
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class SolverDecl:
    settings: tuple[Setting, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class HeuristicAst:
    action: Name
    params: tuple[Name, ...]
    measure: Name
    args: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class WarmstartAst:
    traj: Name
    args: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class ReachabilityDecl:
    name: Name
    settings: tuple[Setting, ...]
    heuristics: tuple[HeuristicAst, ...]
    warmstarts: tuple[WarmstartAst, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class SceneRef:
    path: str
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class IndexedName:
    """`b{2*i}` in an `init` / `goal` fact: an object name made of a prefix and an integer
    index expression over `forall` indices (`gnppdsl.ir.families` evaluates it)."""

    prefix: Name
    index: "ExprAst"
    span: Span | None = field(**_S)

    @property
    def value(self) -> str:
        return f"{self.prefix.value}{{...}}"


@dataclass(frozen=True)
class TypeBinder:
    """`b: block` (or `x: spot | region`) in a fact `forall`: every problem object of the types."""

    name: Name
    types: tuple[Name, ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class IndexBinder:
    """`i in 1..8` in a fact `forall`: the integers lo..hi (both included)."""

    name: Name
    lo: "ENum"
    hi: "ENum"
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class FactForall:
    """`forall b: block . parent(b) = table` or `forall i in 1..8 { ... }` in `init` / `goal`:
    the facts of `body` for every combination of the binders (expanded by the resolver)."""

    binders: tuple[TypeBinder | IndexBinder, ...]
    body: tuple["Lit | FactForall", ...]
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class InitDecl:
    lits: tuple["Lit | FactForall | FOr | FAnd", ...]      # FOr / FAnd: an error (resolver)
    span: Span | None = field(**_S)


@dataclass(frozen=True)
class GoalDecl:
    lits: tuple["Lit | FactForall | FOr | FAnd", ...]      # `a or b`, `(a and b) or c`
    span: Span | None = field(**_S)


Decl = Union[UseDecl, TypeDecl, ConstDecl, ConstantsDecl, StateDecl, DerivedDecl, ActionDecl,
             ContinuousDecl, FrameDecl, TemplateDecl, SceneAttrDecl, PrimitiveDecl, RuleDecl,
             RelaxationsDecl, SolverDecl, ReachabilityDecl, SceneRef, ObjectsDecl, InitDecl,
             GoalDecl, AvoidDecl]


@dataclass(frozen=True)
class FileAst:
    path: str
    header: Header
    items: tuple[Decl, ...]
