"""Type checking of expressions: surface syntax (lang.ast) -> typed stage-1 `ir.expr`.

Why here and not in the compiler: every overloaded surface operator (`*` on poses, `pos`,
`inv`, ...) must become one monomorphic builtin of `gnppdsl.ir.builtins` before the graph-NLP
factory sees it, and every mistake (arity, object types, spaces, dimensions, a prime where it
makes no sense) must be reported at the user's file:line:col. The checker works on any scope:
template bodies, frame expressions, rule template-call arguments.

Types of expressions (`Ty`):
  value   a vector in a `Space` (R[n], SE2, SE3, quat, joints); `is_int` for integer scalars
  object  an object expression (parameter, constant, `parent(o)`, `link(r, "...")`)
  traj    a trajectory term; `space` is the space of one waypoint
  string  a string literal
  any     a `value` parameter or attribute: any space (checked at the call site / by the factory)
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable

from gnppdsl.ir import builtins as B
from gnppdsl.ir.builtins import Space
from gnppdsl.ir.expr import (Call, Constraint, CVar, Expr, Forall, Index, IterVar, Num, Obj,
                             Objective, Param, StateValue, Str, Vec, With)
from gnppdsl.lang import ast
from gnppdsl.lang.diagnostics import Reporter, did_you_mean


@dataclass(frozen=True)
class Ty:
    kind: str                          # "value", "object", "traj", "string", "any", "error"
    space: Space | None = None
    types: tuple[str, ...] = ()
    is_int: bool = False

    def __str__(self) -> str:
        if self.kind == "value":
            return "int" if self.is_int and self.space == B.SCALAR else str(self.space)
        if self.kind == "object":
            return " | ".join(self.types) if self.types else "object"
        if self.kind == "traj":
            return f"trajectory of {self.space}"
        if self.kind == "any":
            return "value"
        return self.kind


def VAL(space: Space, is_int: bool = False) -> Ty:
    return Ty("value", space, (), is_int)


INT = VAL(B.SCALAR, True)
REAL = VAL(B.SCALAR)
ANY = Ty("any")
STRING = Ty("string")
ERROR = Ty("error")       # already reported; suppresses follow-up errors


def OBJ(types: tuple[str, ...]) -> Ty:
    return Ty("object", None, tuple(types))


# user-level functions whose value depends on the step (wrapped in Call("next") when primed)
STEP_FUNCTIONS = ("world", "sdist")

SPACE_NAMES = ("R", "SE2", "SE3", "quat", "joints", "value", "string", "int")

# surface functions (overloaded or monomorphic) the checker knows, for did-you-mean
SURFACE_FUNCTIONS = ("inv", "pos", "rot", "angle", "axis", "apply", "conj", "world", "waypoints")

# the reachability graph's travel in an action cost (`gnppdsl.ir.resolve_costs`): travel(r, a, b)
# and its straight-line lower bound travel_lb(r, a, b), evaluated by `gnppdsl.compile.costs`
TRAVEL_FUNCTIONS = ("travel", "travel_lb")


@dataclass
class Scope:
    """What names mean in the expression being checked.

    `params` maps names to (typed IR node factory, Ty): template parameters, rule parameters,
    the frame variable. `cont`, `state`, ... come from the domain (may be empty when a module is
    checked on its own; then `open_world` lets unknown calls through as `any`).
    """

    params: dict[str, tuple[Expr, Ty]] = field(default_factory=dict)
    consts: dict[str, object] = field(default_factory=dict)          # name -> float | tuple
    qconsts: dict[str, object] = field(default_factory=dict)         # "mod.name" -> value
    objects: dict[str, str] = field(default_factory=dict)            # domain constants -> type
    continuous: dict = field(default_factory=dict)                   # name -> model.Continuous
    state_vars: dict = field(default_factory=dict)                   # name -> model.StateVar
    scene_attrs: dict = field(default_factory=dict)                  # name -> model.SceneAttr
    primitives: dict = field(default_factory=dict)                   # name -> model.Primitive
    world_space: Space | None = None                                 # None: any (first pass)
    is_subtype: Callable[[str, str], bool] = lambda a, b: a == b or b == "object"
    open_world: bool = False
    allow_prime: bool = True
    prime_context: str = ""                                          # why a prime is refused
    iter_vars: tuple[str, ...] = ()
    used_prime: bool = False
    allow_travel: bool = False                                       # travel(...) in an action cost


class Checker:
    """Checks expressions within a scope and reports to a `Reporter`."""

    def __init__(self, scope: Scope, reporter: Reporter) -> None:
        self.s = scope
        self.r = reporter

    # ------------------------------------------------------------------ errors
    def err(self, span, msg: str, kind: str = "type", hint: str | None = None) -> tuple[Expr, Ty]:
        self.r.error(span, msg, kind, hint)
        return Num(0.0, span), ERROR

    # ------------------------------------------------------------------ statements
    def statements(self, stmts: tuple) -> tuple:
        out = []
        for st in stmts:
            if isinstance(st, ast.ConstraintAst):
                out.extend(self.constraint(st))
            elif isinstance(st, ast.MinimizeAst):
                o = self.objective(st)
                if o is not None:
                    out.append(o)
            else:
                f = self.forall(st)
                if f is not None:
                    out.append(f)
        return tuple(out)

    def constraint(self, c: ast.ConstraintAst) -> list[Constraint]:
        typed = [self.expr(e) for e in c.operands]
        out = []
        for i, op in enumerate(c.ops):
            (le, lt), (re_, rt) = typed[i], typed[i + 1]
            ok = True
            for e_ast, t in ((c.operands[i], lt), (c.operands[i + 1], rt)):
                if t.kind in ("object", "traj", "string"):
                    self.err(e_ast.span, f"a constraint compares values, but this is {_a(t)}",
                             hint="use world(o) for an object's pose" if t.kind == "object" else None)
                    ok = False
            if ok and not compatible(lt, rt, broadcast=True):
                self.err(op.span, f"cannot compare {lt} with {rt}", "dimension",
                         hint="both sides must have the same space and dimension")
                ok = False
            if ok:
                out.append(Constraint(le, op.value, re_, c.span))
        return out

    def objective(self, o: ast.MinimizeAst) -> Objective | None:
        e, t = self.expr(o.expr)
        if t.kind == "error":
            return None
        if t.kind == "any" or (t.kind == "value" and t.space is not None and t.space.kind in ("R", "int")
                               and t.space.dim == 1):
            return Objective(e, o.span)
        what = str(t) if t.kind == "value" else _a(t)
        self.err(o.expr.span, f"minimize takes a scalar (R), but this is {what}", "dimension",
                 hint="e.g. norm(v), dot(v, v) or v[0] for a vector v")
        return None

    def forall(self, f: ast.ForallAst) -> Forall | None:
        name = f.var.value
        if name in self.s.params or name in self.s.iter_vars:
            self.err(f.var.span, f"'{name}' is already defined here", "duplicate")
        lo, lt = self.expr(f.lo)
        hi, ht = self.expr(f.hi)
        for e, t in ((f.lo, lt), (f.hi, ht)):
            if t.kind != "error" and not (t.kind == "value" and t.is_int):
                self.err(e.span, f"forall bounds must be integers, got {t}")
        saved = self.s.iter_vars
        self.s.iter_vars = saved + (name,)
        try:
            body = self.statements(f.body)
        finally:
            self.s.iter_vars = saved
        return Forall(name, lo, hi, body, f.span)

    # ------------------------------------------------------------------ expressions
    def expr(self, e) -> tuple[Expr, Ty]:
        m = getattr(self, "_" + type(e).__name__)
        return m(e)

    def value(self, e, what: str = "a value") -> tuple[Expr, Ty]:
        x, t = self.expr(e)
        if t.kind in ("object", "traj", "string"):
            return self.err(e.span, f"expected {what}, but this is {_a(t)}")
        return x, t

    def obj(self, e, what: str = "an object") -> tuple[Expr, Ty]:
        x, t = self.expr(e)
        if t.kind in ("object", "error", "any"):
            return x, (t if t.kind != "any" else OBJ(("object",)))
        return self.err(e.span, f"expected {what}, but this is {_a(t)}")

    def _ENum(self, e: ast.ENum):
        return Num(e.value, e.span), VAL(B.SCALAR, float(e.value).is_integer() and "." not in e.text
                                          and "e" not in e.text.lower())

    def _EStr(self, e: ast.EStr):
        return Str(e.value, e.span), STRING

    def _EVec(self, e: ast.EVec):
        items = []
        ok = True
        for it in e.items:
            x, t = self.value(it, "a number")
            if t.kind == "error":
                ok = False
            elif not (t.kind == "value" and t.space.dim == 1 and t.space.kind == "R"):
                self.err(it.span, f"vector items must be scalars, got {t}",
                         hint="use concat(a, b) to join vectors")
                ok = False
            items.append(x)
        if not ok:
            return Num(0.0, e.span), ERROR
        return Vec(tuple(items), e.span), VAL(B.R(len(items)))

    def _ERef(self, e: ast.ERef):
        text = e.text
        span = e.span
        if len(e.qname) > 1:
            if text in self.s.qconsts:
                return _const_expr(self.s.qconsts[text], span)
            return self.err(span, f"unknown constant '{text}'", "unknown-name",
                            did_you_mean(text, self.s.qconsts))
        if text in self.s.iter_vars:
            return IterVar(text, span), INT
        if text in self.s.params:
            node, t = self.s.params[text]
            return _with_span(node, span), t
        if text in self.s.consts:
            return _const_expr(self.s.consts[text], span)
        if text == "pi":
            return Num(math.pi, span), REAL
        if text in self.s.objects:
            return Obj(text, span), OBJ((self.s.objects[text],))
        if text in self.s.continuous:
            return self._cvar(text, (), span)
        if text in self.s.state_vars:
            return self._state_value(text, (), span)
        if self.s.open_world:
            return Param(text, span), ANY
        cands = (list(self.s.params) + list(self.s.consts) + list(self.s.iter_vars)
                 + list(self.s.objects) + list(self.s.continuous) + ["pi"])
        return self.err(span, f"unknown name '{text}'", "unknown-name", did_you_mean(text, cands))

    def _EBin(self, e: ast.EBin):
        (a, at), (b, bt) = self.value(e.lhs), self.value(e.rhs)
        if ERROR in (at, bt):
            return Num(0.0, e.span), ERROR
        return binary(self, e.op, a, at, b, bt, e.span)

    def _ENeg(self, e: ast.ENeg):
        a, t = self.value(e.arg)
        if t.kind == "error":
            return a, t
        if isinstance(a, Num):
            return Num(-a.value, e.span), t
        return Call("neg", (a,), e.span), (VAL(t.space, t.is_int) if t.kind == "value" else t)

    def _EPrime(self, e: ast.EPrime):
        x, t = self.expr(e.arg)
        if t.kind == "error":
            return x, t
        if not self.s.allow_prime:
            return self.err(e.span, f"' (the next step) is not allowed {self.s.prime_context}",
                            "prime")
        try:
            shifted, changed = shift(x)
        except _DoublePrime:
            return self.err(e.span, "this is already at the next step (double ')", "prime")
        if not changed:
            return self.err(e.span, "' has no effect here: it applies to continuous variables, "
                            "state values, world(...) and sdist(...)", "prime")
        self.s.used_prime = True
        return shifted, t

    def _EIndex(self, e: ast.EIndex):
        base, bt = self.expr(e.base)
        if bt.kind == "error":
            return base, bt
        idx, it = self.value(e.index, "an index")
        if it.kind == "error":
            return idx, it
        if not (it.kind == "value" and it.is_int):
            return self.err(e.index.span, f"an index must be an integer expression, got {it}")
        if e.stop is not None:
            stop, st = self.value(e.stop, "an index")
            if st.kind == "error":
                return stop, st
            lo, hi = fold_int(idx), fold_int(stop)
            if bt.kind != "value":
                return self.err(e.span, f"cannot slice {_a(bt)}")
            if lo is None or hi is None:
                return self.err(e.span, "slice bounds must be integer constants")
            if hi <= lo:
                return self.err(e.span, f"empty slice [{lo}:{hi}]")
            if bt.space.dim and hi > bt.space.dim:
                return self.err(e.span, f"slice [{lo}:{hi}] is out of range for {bt.space}", "dimension")
            return Index(base, idx, stop, e.span), VAL(B.R(hi - lo))
        if bt.kind == "traj":
            return Index(base, idx, None, e.span), VAL(bt.space)
        if bt.kind == "value" or bt.kind == "any":
            k = fold_int(idx)
            if bt.kind == "value" and k is not None and bt.space.dim and not (-bt.space.dim <= k < bt.space.dim):
                return self.err(e.index.span, f"index {k} is out of range for {bt.space}", "dimension")
            return Index(base, idx, None, e.span), REAL
        return self.err(e.span, f"cannot index {_a(bt)}")

    def _EWith(self, e: ast.EWith):
        subs = []
        for lhs, rhs in e.substs:
            lx, lt = self.expr(lhs)
            if lt.kind == "error":
                continue
            if not isinstance(lx, CVar):
                self.err(lhs.span, "only a continuous variable term can be substituted "
                         "(e.g. `with q(r) = path(r)[k]`)", "with")
                continue
            rx, rt = self.value(rhs)
            if rt.kind == "error":
                continue
            if not compatible(lt, rt):
                self.err(rhs.span, f"cannot substitute {rt} for {lx.name}(...) : {lt}", "dimension")
                continue
            subs.append((lx, rx))
        body, bt = self.expr(e.body)
        if bt.kind == "error":
            return body, bt
        return With(body, tuple(subs), e.span), bt

    def _ECall(self, e: ast.ECall):
        name = e.text
        span = e.span
        if len(e.qname) > 1:
            return self.err(e.qname[0].span and span, f"unknown function '{name}'", "unknown-name",
                            hint="templates are instantiated by rules, not called in expressions")
        if name in self.s.params or name in self.s.iter_vars:
            return self.err(span, f"'{name}' is a parameter, not a function", "not-callable")
        if name == "world":
            if len(e.args) != 1:
                return self.err(span, f"world takes 1 argument, got {len(e.args)}", "arity")
            x, t = self.obj(e.args[0])
            if t.kind == "error":
                return x, t
            return Call("world", (x,), span), (VAL(self.s.world_space) if self.s.world_space else ANY)
        if name == "waypoints":
            if len(e.args) != 1:
                return self.err(span, f"waypoints takes 1 argument, got {len(e.args)}", "arity")
            x, t = self.expr(e.args[0])
            if t.kind == "error":
                return x, t
            if t.kind not in ("traj", "any"):
                return self.err(e.args[0].span, f"waypoints needs a trajectory, got {_a(t)}")
            return Call("waypoints", (x,), span), INT
        if name in self.s.continuous:
            args = self._object_args(e, self.s.continuous[name].params, name)
            if args is None:
                return Num(0.0, span), ERROR
            return self._cvar(name, args, span)
        if name in self.s.state_vars:
            args = self._object_args(e, self.s.state_vars[name].params, name)
            if args is None:
                return Num(0.0, span), ERROR
            return self._state_value(name, args, span)
        if name in self.s.primitives:
            return self._signature_call(e, self.s.primitives[name].params,
                                        self.s.primitives[name].result, "primitive")
        if name in self.s.scene_attrs:
            return self._signature_call(e, self.s.scene_attrs[name].params,
                                        self.s.scene_attrs[name].space, "scene attribute")
        if name in TRAVEL_FUNCTIONS:
            return self._travel(e)
        args = []
        for a in e.args:
            x, t = self.expr(a)
            if t.kind == "error":
                return x, t
            args.append((x, t))
        res = builtin_call(self, name, args, span)
        if res is not None:
            return res
        if self.s.open_world:       # a continuous variable of a domain that uses this module
            return CVar(name, tuple(x for x, _ in args), False, span), ANY
        cands = (list(B.BUILTINS) + list(SURFACE_FUNCTIONS) + list(TRAVEL_FUNCTIONS) + list(self.s.continuous)
                 + list(self.s.state_vars) + list(self.s.primitives) + list(self.s.scene_attrs))
        return self.err(span, f"unknown function '{name}'", "unknown-name", did_you_mean(name, cands))

    def _travel(self, e: ast.ECall):
        """`travel(r, a, b)` / `travel_lb(r, a, b)`: a number (R) of three objects, only in an
        action cost (a number per ground action, from the reachability graph of robot r)."""
        name = e.text
        if not self.s.allow_travel:
            return self.err(e.span, f"{name}(...) is the reachability graph's travel, usable only in an "
                            "action's `cost`", "cost", "in a template, the length of the motion belongs "
                            "in a `minimize` statement")
        if len(e.args) != 3:
            return self.err(e.span, f"{name} takes 3 arguments (robot, from, to), got {len(e.args)}",
                            "arity")
        args = []
        for a, role in zip(e.args, ("the robot", "where the end effector starts", "where it goes")):
            x, t = self.obj(a, f"an object ({role})")
            if t.kind == "error":
                return x, t
            args.append(x)
        return Call(name, tuple(args), e.span), VAL(B.SCALAR)

    # ------------------------------------------------------------------ helpers
    def _object_args(self, e: ast.ECall, params, name: str):
        if len(e.args) != len(params):
            self.err(e.span, f"'{name}' takes {len(params)} argument{'s' * (len(params) != 1)}, "
                     f"got {len(e.args)}", "arity")
            return None
        out = []
        for a, p in zip(e.args, params):
            x, t = self.obj(a)
            if t.kind == "error":
                return None
            if t.kind == "object" and not self._may_match(t.types, p.types):
                self.err(a.span, f"'{name}' expects {' | '.join(p.types)} here, got {t}", "type")
                return None
            out.append(x)
        return tuple(out)

    def _may_match(self, have: tuple[str, ...], want: tuple[str, ...]) -> bool:
        """Some object of a type in `have` may be of a type in `want` (sub- or supertype)."""
        sub = self.s.is_subtype
        return any(sub(h, w) or sub(w, h) for h in have for w in want)

    def _cvar(self, name: str, args: tuple, span):
        c = self.s.continuous[name]
        space = c.space
        if space.kind == "joints":
            idx = [p.name for p in c.params].index(space.robot) if space.robot in [p.name for p in c.params] else None
            robot = _expr_text(args[idx]) if idx is not None and idx < len(args) else space.robot
            space = Space("joints", 0, robot)
        t = Ty("traj", space) if c.traj else VAL(space)
        return CVar(name, tuple(args), False, span), t

    def _state_value(self, name: str, args: tuple, span):
        v = self.s.state_vars[name]
        if v.is_bool:
            return self.err(span, f"'{name}' is a boolean state variable; it has no object value "
                            "to use in an expression", "type")
        return StateValue(name, tuple(args), False, span), OBJ(v.value_types or ("object",))

    def _signature_call(self, e: ast.ECall, params, result: Space | None, what: str):
        name = e.text
        n_required = len(params)
        while n_required and params[n_required - 1].kind == "string":
            n_required -= 1
        if not (n_required <= len(e.args) <= len(params)):
            want = str(len(params)) if n_required == len(params) else f"{n_required} to {len(params)}"
            return self.err(e.span, f"{what} '{name}' takes {want} arguments, got {len(e.args)}", "arity")
        args = []
        for a, p in zip(e.args, params):
            if p.kind == "object":
                x, t = self.obj(a)
                if t.kind == "error":
                    return x, t
                if t.kind == "object" and p.type and not self._may_match(t.types, (p.type,)):
                    return self.err(a.span, f"argument '{p.name}' of '{name}' must be {p.type}, got {t}")
            elif p.kind == "string":
                x, t = self.expr(a)
                if t.kind == "error":
                    return x, t
                if not isinstance(x, Str):
                    return self.err(a.span, f"argument '{p.name}' of '{name}' must be a string literal")
            else:
                x, t = self.value(a)
                if t.kind == "error":
                    return x, t
                want = VAL(p.space) if p.kind == "value" else ANY
                if not compatible(t, want):
                    return self.err(e.span, f"argument '{p.name}' of '{name}' must be {p.space}, got {t}",
                                    "dimension")
            args.append(x)
        if result is None:
            rt = ANY
        elif result.kind == "object":
            rt = OBJ(("object",))
        else:
            rt = VAL(result)
        return Call(name, tuple(args), e.span), rt


# ----------------------------------------------------------------------------------------
# Space compatibility and operator resolution
# ----------------------------------------------------------------------------------------
def _a(t: Ty) -> str:
    if t.kind == "object":
        return f"an object ({t})"
    if t.kind == "traj":
        return f"a trajectory ({t.space})"
    if t.kind == "string":
        return "a string"
    return f"a {t}"


def compatible(a: Ty, b: Ty, broadcast: bool = False) -> bool:
    """Can values of types a and b be compared / assigned? Scalars broadcast when allowed."""
    if "any" in (a.kind, b.kind) or "error" in (a.kind, b.kind):
        return True
    if a.kind != "value" or b.kind != "value":
        return a.kind == b.kind
    sa, sb = a.space, b.space
    if sa.kind == "joints" or sb.kind == "joints":
        other = sb if sa.kind == "joints" else sa
        return other.kind in ("joints", "R")
    if broadcast and (sa == B.SCALAR or sb == B.SCALAR):
        return True
    return sa.dim == sb.dim


POSES = ("SE2", "SE3")


def _vec_result(at: Ty, bt: Ty) -> Ty:
    """Result of elementwise arithmetic."""
    if at.kind == "any" or bt.kind == "any":
        other = bt if at.kind == "any" else at
        return ANY if other.kind == "any" or other.space == B.SCALAR else VAL(B.R(other.space.dim))
    sa, sb = at.space, bt.space
    if sa.kind == "joints" or sb.kind == "joints":
        return VAL(sa if sa.kind == "joints" else sb)
    if sa == B.SCALAR:
        return VAL(sb if sb.kind == "R" else B.R(sb.dim), at.is_int and bt.is_int)
    return VAL(B.R(sa.dim), at.is_int and bt.is_int)


def binary(ch: Checker, op: str, a: Expr, at: Ty, b: Expr, bt: Ty, span) -> tuple[Expr, Ty]:
    if isinstance(a, Num) and isinstance(b, Num) and op in "+-*/^":
        try:
            v = {"+": lambda: a.value + b.value, "-": lambda: a.value - b.value,
                 "*": lambda: a.value * b.value, "/": lambda: a.value / b.value,
                 "^": lambda: a.value ** b.value}[op]()
        except (ZeroDivisionError, OverflowError, ValueError):
            return ch.err(span, "invalid constant arithmetic")
        if isinstance(v, complex):
            return ch.err(span, "invalid constant arithmetic")
        return Num(float(v), span), VAL(B.SCALAR, at.is_int and bt.is_int and op in "+-*")
    if op in "+-":
        if not compatible(at, bt, broadcast=True):
            return ch.err(span, f"cannot {'add' if op == '+' else 'subtract'} {bt} "
                          f"{'to' if op == '+' else 'from'} {at}", "dimension",
                          "both sides must have the same dimension (or one is a scalar)")
        return Call("add" if op == "+" else "sub", (a, b), span), _vec_result(at, bt)
    if op == "*":
        ka = at.space.kind if at.kind == "value" else "any"
        kb = bt.space.kind if bt.kind == "value" else "any"
        da = at.space.dim if at.kind == "value" else None
        db = bt.space.dim if bt.kind == "value" else None
        for k, mono, point, pdim in (("SE2", "se2", "apply_se2", 2), ("SE3", "se3", "apply_se3", 3)):
            if (ka, kb) in ((k, k), (k, "any"), ("any", k)):
                return Call(f"compose_{mono}", (a, b), span), VAL(B.SE2 if k == "SE2" else B.SE3)
            if ka == k and kb == "R" and db == pdim:
                return Call(point, (a, b), span), VAL(B.R(pdim))
        if ka == "quat" and kb in ("quat", "any"):
            return Call("quat_mul", (a, b), span), VAL(B.QUAT)
        if ka == "quat" and kb == "R" and db == 3:
            return Call("quat_rotate", (a, b), span), VAL(B.R(3))
        if at == ERROR or bt == ERROR:
            return Num(0.0, span), ERROR
        if da == 1 or db == 1 or (ka == "R" and kb == "R" and da == db) \
                or (ka == "any" and kb in ("R", "joints")) or (kb == "any" and ka in ("R", "joints")):
            if ka in POSES or kb in POSES or ka == "quat" or kb == "quat":
                if not (da == 1 or db == 1):
                    return ch.err(span, f"cannot multiply {at} by {bt}", "type")
            return Call("mul", (a, b), span), _vec_result(at, bt)
        if ka == "joints" and kb in ("R", "joints") or kb == "joints" and ka == "R":
            return Call("mul", (a, b), span), _vec_result(at, bt)
        if ka == "any" and kb == "any":
            if ch.s.open_world:        # unknown variables of a module checked on its own
                return Call("mul", (a, b), span), ANY
            return ch.err(span, "cannot tell which '*' is meant for two 'value' operands",
                          hint="give the parameters a space (R, SE2, SE3, ...)")
        return ch.err(span, f"cannot multiply {at} by {bt}", "dimension",
                      "'*' composes poses of the same kind, applies a pose to a point, or scales")
    if op == "/":
        if not (bt.kind == "any" or bt.space.dim == 1 or compatible(at, bt)):
            return ch.err(span, f"cannot divide {at} by {bt}", "dimension")
        return Call("div", (a, b), span), _vec_result(at, bt)
    if op == "^":
        if bt.kind == "value" and bt.space.dim != 1:
            return ch.err(span, f"an exponent must be a scalar, got {bt}", "dimension")
        t = VAL(at.space, at.is_int and bt.is_int) if at.kind == "value" else at
        return Call("pow", (a, b), span), t
    return ch.err(span, f"unknown operator {op}")


def _kind(t: Ty) -> str:
    return t.space.kind if t.kind == "value" else t.kind


def _dim(t: Ty) -> int | None:
    return t.space.dim if t.kind == "value" else None


def builtin_call(ch: Checker, name: str, args: list[tuple[Expr, Ty]], span):
    """Resolve a builtin / overloaded surface function; None if `name` is not one."""
    xs = tuple(x for x, _ in args)
    ts = [t for _, t in args]
    n = len(args)

    def arity(k: int):
        if n != k:
            return ch.err(span, f"'{name}' takes {k} argument{'s' * (k != 1)}, got {n}", "arity")
        return None

    def values_only():
        for (x, t), i in zip(args, range(n)):
            if t.kind in ("object", "traj", "string"):
                return ch.err(x.span or span, f"argument {i + 1} of '{name}' must be a value, "
                              f"got {_a(t)}")
        return None

    def bad(i: int, want: str):
        return ch.err(span, f"argument {i + 1} of '{name}' must be {want}, got {ts[i]}", "dimension")

    overloads: dict[str, dict[str, tuple[str, Ty]]] = {
        "inv": {"SE2": ("inv_se2", VAL(B.SE2)), "SE3": ("inv_se3", VAL(B.SE3)),
                "quat": ("quat_conj", VAL(B.QUAT))},
        "pos": {"SE2": ("pos_se2", VAL(B.R(2))), "SE3": ("pos_se3", VAL(B.R(3)))},
        "rot": {"SE2": ("angle_se2", REAL), "SE3": ("rot_se3", VAL(B.QUAT))},
        "angle": {"SE2": ("angle_se2", REAL)},
        "conj": {"quat": ("quat_conj", VAL(B.QUAT))},
    }
    if name in overloads:
        if (r := arity(1)) or (r := values_only()):
            return r
        table = overloads[name]
        k = _kind(ts[0])
        if k == "any" and ch.s.open_world:
            return Call(name, xs, span), ANY
        if k in table:
            mono, rt = table[k]
            return Call(mono, xs, span), rt
        if k == "R" and ts[0].space.dim in (3, 7, 4):      # a vector laid out like a pose
            guess = {3: "SE2", 7: "SE3", 4: "quat"}[ts[0].space.dim]
            if guess in table:
                mono, rt = table[guess]
                return Call(mono, xs, span), rt
        return ch.err(span, f"'{name}' is defined for {', '.join(table)}, not for {ts[0]}", "type",
                      "give 'value' parameters a space" if k == "any" else None)
    if name in ("axis", "apply"):
        if (r := arity(2)) or (r := values_only()):
            return r
        k = _kind(ts[0])
        if k == "any" and ch.s.open_world:
            return Call(name, xs, span), (VAL(B.R(3)) if name == "axis" else ANY)
        if name == "axis":
            if fold_int(xs[1]) not in (0, 1, 2):
                return ch.err(span, "the axis index must be the constant 0, 1 or 2")
            if k == "SE3":
                return Call("axis_se3", xs, span), VAL(B.R(3))
            if k == "quat":
                return Call("quat_axis", xs, span), VAL(B.R(3))
            return bad(0, "SE3 or quat")
        if k == "SE2" and _dim(ts[1]) == 2:
            return Call("apply_se2", xs, span), VAL(B.R(2))
        if k == "SE3" and _dim(ts[1]) == 3:
            return Call("apply_se3", xs, span), VAL(B.R(3))
        if k == "quat" and _dim(ts[1]) == 3:
            return Call("quat_rotate", xs, span), VAL(B.R(3))
        return ch.err(span, f"'apply' needs (SE2, R[2]), (SE3, R[3]) or (quat, R[3]), got "
                      f"({ts[0]}, {ts[1]})", "dimension")
    if name not in B.BUILTINS:
        return None
    b = B.BUILTINS[name]
    if name in ("fk", "sdist", "sdist2", "link"):
        return ch.err(span, f"'{name}' is not declared", "unknown-name",
                      "geometry primitives are declared in stdlib/prelude.pntc")
    if b.arity >= 0 and (r := arity(b.arity)):
        return r
    if name == "waypoint":
        if ts[0].kind not in ("traj", "any"):
            return bad(0, "a trajectory")
        if not ts[1].is_int:
            return bad(1, "an integer")
        return Call(name, xs, span), (VAL(ts[0].space) if ts[0].kind == "traj" else ANY)
    if (r := values_only()):
        return r
    if name in ("norm", "sqnorm", "sum"):
        return Call(name, xs, span), REAL
    if name == "dot":
        if not compatible(ts[0], ts[1]):
            return ch.err(span, f"'dot' needs two vectors of the same dimension, got {ts[0]} and {ts[1]}",
                          "dimension")
        return Call(name, xs, span), REAL
    if name == "cross":
        for i in range(2):
            if ts[i].kind == "value" and ts[i].space.dim != 3:
                return bad(i, "R[3]")
        return Call(name, xs, span), VAL(B.R(3))
    if name == "concat":
        if any(t.kind != "value" or t.space.kind == "joints" for t in ts):
            return Call(name, xs, span), ANY
        return Call(name, xs, span), VAL(B.R(sum(t.space.dim for t in ts)))
    if name in ("sqrt", "sin", "cos", "abs", "exp", "neg"):
        t = ts[0]
        return Call(name, xs, span), (VAL(B.R(t.space.dim)) if t.kind == "value" else t)
    if name in ("add", "sub", "mul", "div", "pow", "min", "max", "atan2"):
        if not compatible(ts[0], ts[1], broadcast=True):
            return ch.err(span, f"'{name}' needs arguments of the same dimension, got {ts[0]} and {ts[1]}",
                          "dimension")
        return Call(name, xs, span), _vec_result(ts[0], ts[1])
    if name == "angle_diff":
        return Call(name, xs, span), REAL
    scalar = REAL
    sig: dict[str, tuple[tuple[Ty | None, ...], Ty]] = {
        "se2": ((scalar, scalar, scalar), VAL(B.SE2)),
        "se3": ((VAL(B.R(3)), VAL(B.QUAT)), VAL(B.SE3)),
        "compose_se2": ((VAL(B.SE2), VAL(B.SE2)), VAL(B.SE2)),
        "inv_se2": ((VAL(B.SE2),), VAL(B.SE2)),
        "pos_se2": ((VAL(B.SE2),), VAL(B.R(2))),
        "angle_se2": ((VAL(B.SE2),), REAL),
        "apply_se2": ((VAL(B.SE2), VAL(B.R(2))), VAL(B.R(2))),
        "compose_se3": ((VAL(B.SE3), VAL(B.SE3)), VAL(B.SE3)),
        "inv_se3": ((VAL(B.SE3),), VAL(B.SE3)),
        "pos_se3": ((VAL(B.SE3),), VAL(B.R(3))),
        "rot_se3": ((VAL(B.SE3),), VAL(B.QUAT)),
        "apply_se3": ((VAL(B.SE3), VAL(B.R(3))), VAL(B.R(3))),
        "axis_se3": ((VAL(B.SE3), INT), VAL(B.R(3))),
        "quat_mul": ((VAL(B.QUAT), VAL(B.QUAT)), VAL(B.QUAT)),
        "quat_conj": ((VAL(B.QUAT),), VAL(B.QUAT)),
        "quat_rotate": ((VAL(B.QUAT), VAL(B.R(3))), VAL(B.R(3))),
        "quat_dist": ((VAL(B.QUAT), VAL(B.QUAT)), REAL),
        "quat_axis": ((VAL(B.QUAT), INT), VAL(B.R(3))),
    }
    if name in sig:
        params, rt = sig[name]
        for i, (p, t) in enumerate(zip(params, ts)):
            if not compatible(p, t):
                return bad(i, str(p))
        return Call(name, xs, span), rt
    return Call(name, xs, span), ANY


# ----------------------------------------------------------------------------------------
# Primes, constants
# ----------------------------------------------------------------------------------------
class _DoublePrime(Exception):
    pass


def _has_next(e) -> bool:
    if isinstance(e, (CVar, StateValue)) and e.next:
        return True
    if isinstance(e, Call) and e.fn == "next":
        return True
    for child in _children(e):
        if _has_next(child):
            return True
    return False


def _children(e) -> tuple:
    if isinstance(e, (Call, Vec)):
        return e.args if isinstance(e, Call) else e.items
    if isinstance(e, (CVar, StateValue)):
        return e.args
    if isinstance(e, Index):
        return (e.base, e.index) + ((e.stop,) if e.stop is not None else ())
    if isinstance(e, With):
        return (e.body,) + tuple(x for kv in e.substitutions for x in kv)
    return ()


def shift(e) -> tuple[Expr, bool]:
    """`e'`: move every step-dependent part of e to step i+1 (see gnppdsl.ir.model docstring)."""
    if isinstance(e, (CVar, StateValue)):
        if e.next:
            raise _DoublePrime
        args = tuple(shift(a)[0] if _step_dependent(a) else a for a in e.args)
        return type(e)(e.name, args, True, e.span), True
    if isinstance(e, Call):
        if e.fn == "next":
            raise _DoublePrime
        if e.fn in STEP_FUNCTIONS:
            if _has_next(e):
                raise _DoublePrime
            return Call("next", (e,), e.span), True
        changed = False
        args = []
        for a in e.args:
            x, c = shift(a)
            args.append(x)
            changed |= c
        return Call(e.fn, tuple(args), e.span), changed
    if isinstance(e, Vec):
        items, changed = [], False
        for a in e.items:
            x, c = shift(a)
            items.append(x)
            changed |= c
        return Vec(tuple(items), e.span), changed
    if isinstance(e, Index):
        base, c = shift(e.base)
        return Index(base, e.index, e.stop, e.span), c
    if isinstance(e, With):
        body, changed = shift(e.body)
        subs = tuple((shift(k)[0], shift(v)[0]) for k, v in e.substitutions)
        return With(body, subs, e.span), changed
    return e, False


def _step_dependent(e) -> bool:
    return isinstance(e, (CVar, StateValue)) or (isinstance(e, Call) and (e.fn in STEP_FUNCTIONS or any(
        _step_dependent(a) for a in e.args)))


def fold_int(e) -> int | None:
    """The integer value of a constant expression, or None."""
    v = fold(e)
    if v is None or not float(v).is_integer():
        return None
    return int(v)


def fold(e) -> float | None:
    if isinstance(e, Num):
        return e.value
    if isinstance(e, Call):
        vals = [fold(a) for a in e.args]
        if any(v is None for v in vals):
            return None
        try:
            if e.fn == "neg":
                return -vals[0]
            if e.fn in ("add", "sub", "mul", "div", "pow"):
                a, b = vals
                return {"add": a + b, "sub": a - b, "mul": a * b,
                        "div": a / b if b else None, "pow": a ** b if a >= 0 or float(b).is_integer() else None}[e.fn]
        except (OverflowError, ZeroDivisionError):
            return None
    return None


def _const_expr(value, span) -> tuple[Expr, Ty]:
    if isinstance(value, tuple):
        return Vec(tuple(Num(float(v), span) for v in value), span), VAL(B.R(len(value)))
    return Num(float(value), span), VAL(B.SCALAR, float(value).is_integer())


def _with_span(node, span):
    try:
        return type(node)(**{**node.__dict__, "span": span})
    except TypeError:
        return node


def _expr_text(e) -> str:
    if isinstance(e, (Param, Obj)):
        return e.name
    if isinstance(e, StateValue):
        return f"{e.name}({', '.join(_expr_text(a) for a in e.args)})"
    return "?"
