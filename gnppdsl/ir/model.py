"""The resolved, typed model of a .pntc domain and problem (the IR the compiler reads).

Why this module: the compiler (`gnppdsl.compile`: grounding, SAS+, graph-NLP factory) must never
look at syntax. Everything here is already name-resolved (qualified template names, types that
exist, state variables that exist) and type-checked (arity, object types, value spaces), so a
consumer can trust it and only has to *ground* it over the problem's objects.

Produced by `gnppdsl.ir.load_problem(path)` / `gnppdsl.ir.load_domain(path)`. All classes are
frozen dataclasses; every node keeps a `span` (`gnppdsl.ir.expr.Span`, file:line:col) that does
not take part in equality, for diagnostics in later layers.

Conventions used throughout
---------------------------
Logic terms (state-variable arguments and values, rule patterns, goals) reuse the expression
nodes of `gnppdsl.ir.expr`:
  - `Param(name)`  a variable: an action/rule/derived parameter or an `exists` variable;
  - `Obj(name)`    a constant object (problem object or domain constant), or one of the builtin
                   values `none`, `true`, `false` (these are exactly the value names of the
                   `SASVariable`s the compiler builds: booleans have values ("false", "true")).
So grounding is one substitution `Param(x) -> Obj(binding[x])` for logic and template arguments.

Boolean state variables: `free(g)` is `StateLit("free", (g,), Obj("true"))` and `not free(g)` is
`StateLit("free", (g,), Obj("false"))` (never a negated literal). Effects likewise assign
`Obj("true")` / `Obj("false")`.

Derived predicates: `clear(x)` is `DerivedLit("clear", (x,))`, `not clear(x)` has
`negated=True` (SAS+: derived var value 0 = false, negation by failure).

Template bodies are stage-1 expressions (`gnppdsl.ir.expr` docstring). Overloaded operators are
already resolved to monomorphic builtins (`gnppdsl.ir.builtins.BUILTINS`). The user-level calls
that remain for the graph-NLP factory to expand are:
  - `Call("world", (x,))`        world pose of object expression x (Param / Obj / StateValue)
                                 at step i, composed along the kinematic chain of s_i using the
                                 domain's `Frame`s; its space is `Domain.world_space`.
  - `Call("sdist", (a, b))`      two-argument form (objects): signed distance between the shapes
                                 of a and b at their world poses (factory expands to the 4-arg
                                 builtin `sdist` / `sdist2` for planar scenes). The 4-argument
                                 builtin is never produced by the type checker.
  - `Call("fk", (r, q))` / `Call("fk", (r, q, Str(frame)))`  forward kinematics of robot r at
                                 joints q (default frame: the scene robot's `ee`); the factory
                                 adds the robot base to get the 4-arg builtin.
  - `Call("waypoints", (traj,))` the number of waypoints of a trajectory term (an integer
                                 constant once the problem is known).
  - `Call(attr, (o, ...))`       a scene attribute declared with `scene attr(...) : space`
                                 (`Domain.scene_attrs[attr]`), read from the scene (e.g. radius).
  - `Call("next", (e,))`         `e'` where e is a `world`/`sdist` call: evaluate e entirely at
                                 step i+1 (chain of s_{i+1}, variables at i+1). Primes on
                                 continuous variables and state values are NOT wrapped: they set
                                 `CVar.next` / `StateValue.next` directly. A `next` wrapper never
                                 contains nodes with `next=True`.
Module constants (`const grasp_tol = 0.01`) and `pi` are inlined as `Num`.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import Iterable, Iterator, Union

from gnppdsl.ir.builtins import Space
from gnppdsl.ir.expr import Expr, Obj, Param, Span, Statement

ROOT_TYPE = "object"
"""The implicit root of the type hierarchy; every declared root type derives from it."""

NONE = "none"
TRUE = "true"
FALSE = "false"
BUILTIN_VALUES = (NONE, TRUE, FALSE)

_SPAN = dict(default=None, compare=False, hash=False, repr=False)

Term = Union[Param, Obj]
"""A logic term: a variable (`Param`) or a constant object / builtin value (`Obj`)."""


# --------------------------------------------------------------------------------------------
# Types, objects, parameters
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Type:
    """`type region < place`. `parent` is None only for the root type `object`."""

    name: str
    parent: str | None
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class TypedParam:
    """A parameter `o: block` or, in rules and derived predicates, a union `P: place | gripper`.

    `types` lists the allowed types (an object matches if its type is one of them or a subtype).
    """

    name: str
    types: tuple[str, ...]
    span: Span | None = field(**_SPAN)

    @property
    def type(self) -> str:
        """The single type (for action, state-variable and frame parameters)."""
        return self.types[0]


# --------------------------------------------------------------------------------------------
# Logic: literals, formulas, effects
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StateLit:
    """`var(args) = value` (or `!=` when `negated`). Booleans use value Obj("true"/"false")."""

    var: str
    args: tuple[Term, ...]
    value: Term
    negated: bool = False
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class DerivedLit:
    """`pred(args)` or `not pred(args)` for a derived predicate."""

    pred: str
    args: tuple[Term, ...]
    negated: bool = False
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Compare:
    """Static comparison of two terms: `a = b`, `a != b`, `a < b` (also `<=`, `>`, `>=`).

    Used in `where` guards of rules, and in action preconditions / derived bodies for `=`/`!=`.
    Ordering compares objects by their position in `Problem.objects` (declaration order,
    domain constants first) -- meant for symmetry breaking (`where a < b`).
    """

    lhs: Term
    op: str
    rhs: Term
    span: Span | None = field(**_SPAN)


Literal = Union[StateLit, DerivedLit, Compare]


@dataclass(frozen=True)
class And:
    items: tuple["Formula", ...]
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Or:
    items: tuple["Formula", ...]
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Not:
    item: "Formula"
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Exists:
    """`exists z: block . body` (several variables: `exists a: t1, b: t2 . body`)."""

    params: tuple[TypedParam, ...]
    body: "Formula"
    span: Span | None = field(**_SPAN)


Formula = Union[StateLit, DerivedLit, Compare, And, Or, Not, Exists]
"""Derived-predicate bodies. `not` applied directly to a literal is folded into the literal
(`DerivedLit.negated`, `StateLit.negated`, boolean value flip, `Compare` op flip)."""


@dataclass(frozen=True)
class Assign:
    """`var(args) := value` (booleans: `free(g)` -> Obj("true"), `not free(g)` -> Obj("false"))."""

    var: str
    args: tuple[Term, ...]
    value: Term
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Effect:
    """An effect; `conditions` non-empty for `when COND { ... }` (nested `when`s are flattened,
    their conditions conjoined)."""

    assign: Assign
    conditions: tuple[Literal, ...] = ()
    span: Span | None = field(**_SPAN)


# --------------------------------------------------------------------------------------------
# Declarations of the logic
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class StateVar:
    """`state parent(o: block) : place | gripper` / `state free(g: gripper) : bool`.

    `domain` lists the allowed value types (objects of these types or subtypes), plus `"none"`
    if written; for booleans it is exactly `("bool",)` and `is_bool` is True.
    """

    name: str
    params: tuple[TypedParam, ...]
    domain: tuple[str, ...]
    span: Span | None = field(**_SPAN)

    @property
    def is_bool(self) -> bool:
        return self.domain == ("bool",)

    @property
    def allows_none(self) -> bool:
        return NONE in self.domain

    @property
    def value_types(self) -> tuple[str, ...]:
        """The object types in the domain (without `none` / `bool`)."""
        return tuple(t for t in self.domain if t not in (NONE, "bool"))


@dataclass(frozen=True)
class Derived:
    """`derived clear(x: place) := FORMULA` (may be recursive; the compiler stratifies)."""

    name: str
    params: tuple[TypedParam, ...]
    body: Formula
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Action:
    """`action pick(o: block, ...) { pre ...  eff ...  cost 1 }`.

    `pre` is a conjunction of literals (StateLit may be `!=`, DerivedLit may be negated, Compare
    between parameters). Effects assign state variables only (never derived predicates).
    `cost` is the cost of every ground action (a float >= 0), unless `cost_expr`, a typed scalar
    expression of the parameters and the scene (`gnppdsl.ir.resolve_costs`), gives it per ground
    action when the problem is compiled (`gnppdsl.compile.costs`).
    """

    name: str
    params: tuple[TypedParam, ...]
    pre: tuple[Literal, ...]
    effects: tuple[Effect, ...]
    cost: float = 1
    span: Span | None = field(**_SPAN)
    cost_expr: object | None = None


# --------------------------------------------------------------------------------------------
# Continuous side
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Continuous:
    """`continuous pose(o: block) : SE2 tags object` or `traj path(r: arm) : joints(r) waypoints 20`.

    `space` is a `gnppdsl.ir.builtins.Space`; for `joints(r)` it is
    `Space("joints", dim=0, robot="r")` with `robot` naming the *parameter* (dimension and limits
    come from the scene robot bound to it). For trajectories `traj` is True and `waypoints` is
    the declared count, or None to use `SolverSettings.waypoints` (see `Problem.waypoints_of`).
    """

    name: str
    params: tuple[TypedParam, ...]
    space: Space
    tags: frozenset[str] = frozenset()
    traj: bool = False
    waypoints: int | None = None
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Frame:
    """`frame o: block = world(parent(o)) * pose(o)`: how to get the world pose of an object.

    `expr` is a stage-1 expression over `Param(param.name)`: `CVar`s, `StateValue`s and
    `Call("world", ...)` / `Call("fk", ...)`. Its space is `Domain.world_space`. The frame of an
    object is the one declared for its most specific type (`Domain.frame_of`); objects of types
    without a frame are fixed in the world at their scene pose.
    """

    param: TypedParam
    expr: Expr
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Signature:
    """A parameter of a template, scene attribute or primitive.

    kind: "object" (`o: block`; `type` is the object type, subtypes accepted),
          "value"  (`a: R[3]`, `p: SE2`, `q: joints`, `n: int` -> Space("int"); `space` set), or
          "any"    (`a: value`: any space, the same for every parameter typed `value` in one call),
          "string" (`frame: string`).
    """

    name: str
    kind: str
    type: str | None = None
    space: Space | None = None
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Template:
    """`template grasp(o: object, g: object) tags grasp { ... }`.

    `name` is qualified: `MODULE.name` for templates of a module, `DOMAIN.name` for templates
    declared in the domain file. `body` is a tuple of stage-1 statements (ir.expr).
    `two_step` is True when the body uses `'` (it relates x_i and x_{i+1}); only transition
    rules may call such a template.
    """

    name: str
    params: tuple[Signature, ...]
    body: tuple[Statement, ...]
    tags: frozenset[str] = frozenset()
    module: str = ""
    two_step: bool = False
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class SceneAttr:
    """`scene radius(o: object) : R`: a per-object constant read from the scene YAML.

    The factory reads `SceneObject.attributes[name]` (or the robot's), or a derived value for
    the builtin attributes documented in docs/scene.md (`size`, `home`, `pose0`, ...).
    """

    name: str
    params: tuple[Signature, ...]
    space: Space | None                     # None for `: value` (depends on the object)
    module: str = ""
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Primitive:
    """`primitive fk(r: object, q: joints, frame: string) : SE3`: a geometry function.

    Trailing `string` parameters are optional (`fk(r, q)` uses the robot's `ee`). `result` is
    `Space("object")` for primitives returning a body (`link`), None for `: value`.
    """

    name: str
    params: tuple[Signature, ...]
    result: Space | None
    module: str = ""
    span: Span | None = field(**_SPAN)


# --------------------------------------------------------------------------------------------
# Rules (the map Pi)
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class TemplateCall:
    """One template instance a rule creates: `planar.same(pose(o), pose(o)')`.

    `args` are stage-1 expressions over the rule's parameters (`Param`); object arguments are
    `Param`, `Obj` or `StateValue` terms. `tags` = template tags | rule tags (already merged).
    """

    template: str
    args: tuple[Expr, ...]
    tags: frozenset[str]
    span: Span | None = field(**_SPAN)


#: names of the state variable and step the compiler adds for `: initial =>` and `: final =>`
#: rules (compile.ground.MARKER, FINAL): a domain cannot declare them
RESERVED_LOGIC_NAMES = ("initial", "final")


@dataclass(frozen=True)
class Rule:
    """`rule pick(o: block, g: gripper, P: place) where ... : p -> p' => calls tags ...`.

    kind:
      "state"       `: p => ...`        applies at every step i = 0..n where p ⊆ s_i
      "transition"  `: p -> p' => ...`  at i = 0..n-1 where p ⊆ s_i and p' ⊆ s_{i+1}
      "always"      `: always => ...`   every step (p is empty)
      "initial"     `: initial => ...`  only step 0 (compiled to a marker variable)
      "final"       `: final => ...`    only the plan's last step (compiled to a derived
                    variable "the goal holds", which no operator may be applied in)
    `pre` is p and `post` is p' (empty tuple unless "transition"). Pattern literals are
    positive (`StateLit` with negated False; booleans by value; `DerivedLit` may be negated,
    meaning value false). `where` holds static guards (`Compare`) on the parameters.
    """

    name: str
    params: tuple[TypedParam, ...]
    kind: str
    pre: tuple[StateLit | DerivedLit, ...]
    post: tuple[StateLit | DerivedLit, ...]
    calls: tuple[TemplateCall, ...]
    where: tuple[Compare, ...] = ()
    tags: frozenset[str] = frozenset()
    span: Span | None = field(**_SPAN)


# --------------------------------------------------------------------------------------------
# Relaxations, solver settings, reachability
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Relaxation:
    """`no_col_traj : drop collision, traj`: drop every factor (and variable) with one of these
    tags. A `Domain.relaxations` schedule is ordered loose -> tight; the full graph is implied
    after the last one."""

    name: str
    drop: frozenset[str]
    span: Span | None = field(**_SPAN)


AVOID_CATEGORIES = ("robots", "objects", "scene")


@dataclass(frozen=True)
class Avoid:
    """`avoid robots, objects, scene margin 0.01`: every pair of bodies of these categories
    keeps `margin` at every keyframe, waypoint and segment midpoint (robot links: with each
    robot's SRDF-filtered self pairs; objects: the movable objects; scene: static bodies and the
    scene objects a problem does not declare). The engine enforces it by an active set over the
    independent verification's pairs (`gnppdsl.solve.active_set`), no rule lists them."""

    categories: tuple[str, ...]
    margin: float = 0.0
    span: Span | None = field(**_SPAN)


SOLVER_ALGORITHMS = ("gnpp", "oneway", "rlgp")
SOLVER_NLPS = ("ipopt", "sqpmethod")
SOLVER_ORDERS = ("full_first", "relaxed_first", "staged")
# logic modes (gnppdsl.logic.modes): auto = sequential while cheap, then Fast Downward
SOLVER_PLANNERS = ("auto", "sequential", "fd")
#: the solver setting `kinematic_curvature` as written -> its value (`SolverOptions`)
KINEMATIC_CURVATURE_VALUES = {"true": True, "false": False, "auto": "auto"}


@dataclass(frozen=True)
class SolverSettings:
    """`solver { ... }` settings. Defaults here; the domain's block overrides them, the problem's
    block overrides the domain's, and the CLI overrides both (use `merged`).

    algorithm   "gnpp" (the Graph-NLP Planner), "oneway" (baseline: plan, then check), "rlgp"
    switches    subset of "trng" (paper 000: t = subgraph database reuse ... see docs/reference.md)
    nlp         casadi NLP plugin: "ipopt" or "sqpmethod"
    tolerance   constraint violation tolerance of the NLP
    time_limit  seconds for the whole solve
    seed        random seed (NLP initialisation, sampling)
    waypoints   default waypoints of `traj` declarations without an explicit count
    max_horizon longest plan (number of actions) the logic planner tries
    max_iter    NLP iteration limit per solve
    database    path of the subgraph database (SQLite) or None for in-memory
    order       gnpp: when the relaxations are solved relative to the full graph-NLP
                ("full_first", "relaxed_first", "staged"; None: the solver's default)
    jit         large derivative kernels as compiled C (cached on disk; `gnppdsl.nlp.jit`): true =
                compile during the solve, false = never, None = in the background for later solves
    planner     logic mode: "auto" (clingo's shortest plans while a call's proofs stay under 2 s,
                then Fast Downward), "sequential" (clingo, shortest plans: exact N0), "fd" (Fast
                Downward's greedy search with FF on the Appendix-B task: short plans, no proof); see
                `gnppdsl.logic.modes` and docs/design.md "Logic modes and their guarantees"
    distance_curvature
                ipopt's Hessian of the Lagrangian includes the second derivatives of the rows that
                query signed distances (`sdist`, `sdist2`); false: those rows enter linearised, as
                in SQP trajectory optimisers (see `gnppdsl.nlp.feasibility.SolverOptions`)
    kinematic_curvature
                ... and of the rows that use forward kinematics (`fk`); false: those enter
                linearised too (Gauss-Newton-like steps, as KOMO takes); "auto": linearised
                first, exact again from the same start when that does not end feasible
    optimise    minimise the domain's `minimize` terms from the first feasible solution (true)
    anytime     seconds to look for cheaper logical plans after the first solution (0: off;
                `gnppdsl.solve.anytime`)
    batch_conflicts
                gnpp: NLPs per learned conflict spent deciding its renamings onto other objects
                of the same type (`gnppdsl.conflicts.batch`; 0: off)
    batch_lazy  gnpp: renamings beyond the first ones are decided only when a proposed plan holds
                one (true); false: all when the conflict is learned
    interleave_conflicts
                gnpp: a conflict also forbids its copies with steps inserted or removed where its
                subgraph relates consecutive steps only by chain equalities (`gnppdsl.conflicts.interleave`)
    stretch_conflicts
                gnpp, with interleave_conflicts: `preorder`-tagged transitions (a push held over
                several steps) count as chain links too (`gnppdsl.conflicts.interleave`)
    """

    algorithm: str = "gnpp"
    switches: str = "trn"
    nlp: str = "ipopt"
    tolerance: float = 1e-6
    time_limit: float = 60.0
    seed: int = 0
    waypoints: int = 20
    max_horizon: int = 20
    max_iter: int = 1000
    database: str | None = None
    order: str | None = None
    jit: bool | None = None
    distance_curvature: bool = True
    kinematic_curvature: bool | str = "auto"
    planner: str = "auto"
    optimise: bool = True
    anytime: float = 0.0
    batch_conflicts: int = 64
    batch_lazy: bool | None = None
    interleave_conflicts: bool | None = None
    stretch_conflicts: bool | None = None

    def merged(self, **overrides) -> "SolverSettings":
        """A copy with the given fields replaced (None values are ignored)."""
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})


SOLVER_FIELDS: dict[str, type] = {
    "algorithm": str, "switches": str, "nlp": str, "tolerance": float, "time_limit": float,
    "seed": int, "waypoints": int, "max_horizon": int, "max_iter": int, "database": str,
    "order": str, "jit": bool, "distance_curvature": bool,
    "kinematic_curvature": str, "planner": str, "optimise": bool,
    "anytime": float, "batch_conflicts": int, "batch_lazy": bool, "interleave_conflicts": bool, "stretch_conflicts": bool,
}

#: accepted ranges of the numeric solver settings and their command-line twins (inclusive).
#: Why these bounds: ipopt cannot reach a violation below ~1e-10 in double precision (1e-30
#: ended in "no plan"), and above 1e-2 a "solved" plan can be visibly wrong (`--tolerance 1e3`
#: returned a violation of 0.5); a seed must fit numpy's 32-bit generator seed.
SETTING_RANGES: dict[str, tuple[float, float]] = {
    "tolerance": (1e-10, 1e-2), "time_limit": (1e-6, 1e7), "seed": (0, 2**32 - 1),
    "waypoints": (2, 10_000), "max_horizon": (1, 10_000), "max_iter": (1, 10_000_000), "anytime": (0, 1e7),
    "batch_conflicts": (0, 100_000),
}


def setting_problem(key: str, value) -> str | None:
    """Why `value` is not acceptable for the numeric setting `key` ("is out of range [a, b]",
    "must be a finite number"), or None if it is. Callers put the setting's name in front."""
    import math

    if key not in SETTING_RANGES:
        return None
    lo, hi = SETTING_RANGES[key]
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        return "must be a number"
    if not math.isfinite(v):
        return "must be a finite number"
    if not lo <= v <= hi:
        return f"is out of range [{lo:g}, {hi:,}]" if isinstance(hi, int) else f"is out of range [{lo:g}, {hi:g}]"
    return None
    lo, hi = SETTING_RANGES[key]
    try:
        v = float(value)
    except (TypeError, ValueError, OverflowError):
        return f"{key} must be a number"
    if not math.isfinite(v):
        return f"{key} must be a finite number, not {value}"
    if not lo <= v <= hi:
        return f"{key} = {value} is out of range [{lo:g}, {hi:g}]"
    return None


@dataclass(frozen=True)
class Heuristic:
    """`heuristic pick(o, r, from) : travel(r, o)`: the cost of action `action` (its parameters
    named `params`, positionally) is `measure` of the given parameters; `travel(r, x)` is the
    reachability-graph path cost of robot r's end effector from its previous target to object x.
    """

    action: str
    params: tuple[str, ...]
    measure: str
    args: tuple[str, ...]
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Warmstart:
    """`warmstart path(r)`: initialise this trajectory from the reachability graph's path."""

    traj: str
    args: tuple[str, ...]
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Reachability:
    """`reachability NAME { robot = left_arm  frame = "..." ... }` (R-LGP, paper 002).

    weights are (w_x, w_q, w_c) of Eq. 3; interpolation is L; ik_* configure the IK validation
    of Eq. 2. `robot` is a scene robot / problem object name; `workspace` None means the scene's.
    """

    name: str
    robot: str
    frame: str | None = None
    workspace: tuple[tuple[float, ...], tuple[float, ...]] | None = None
    samples: int = 400
    neighbours: int = 8
    weights: tuple[float, float, float] = (1.0, 0.5, 0.1)
    interpolation: int = 10
    ik_restarts: int = 5
    ik_tolerance: float = 1e-3
    seed: int = 0
    heuristics: tuple[Heuristic, ...] = ()
    warmstarts: tuple[Warmstart, ...] = ()
    span: Span | None = field(**_SPAN)


REACHABILITY_FIELDS: dict[str, type] = {
    "robot": str, "frame": str, "workspace": tuple, "samples": int, "neighbours": int,
    "weights": tuple, "interpolation": int, "ik_restarts": int, "ik_tolerance": float, "seed": int,
}


# --------------------------------------------------------------------------------------------
# Modules, domains, problems
# --------------------------------------------------------------------------------------------
@dataclass(frozen=True)
class Module:
    """A library module (`module planar`) as loaded: its own declarations only."""

    name: str
    path: str
    uses: tuple[str, ...] = ()
    consts: dict[str, float | tuple[float, ...]] = field(default_factory=dict)
    templates: dict[str, Template] = field(default_factory=dict)       # by qualified name
    scene_attrs: dict[str, SceneAttr] = field(default_factory=dict)
    primitives: dict[str, Primitive] = field(default_factory=dict)
    span: Span | None = field(**_SPAN)


@dataclass(frozen=True)
class Domain:
    """A resolved, type-checked domain with everything it imports (`use` + implicit prelude).

    Dicts preserve declaration order. `templates` holds all templates reachable by the domain,
    keyed by qualified name. Templates some rule calls (and all templates of the domain file)
    are fully checked; templates of used modules that no rule calls were checked leniently (they
    may refer to variables other domains declare) and should not be instantiated. `constants` are objects declared by the domain
    (`constants { table: surface }`), present in every problem.
    """

    name: str
    path: str
    types: dict[str, Type]
    constants: dict[str, str] = field(default_factory=dict)             # object -> type
    consts: dict[str, float | tuple[float, ...]] = field(default_factory=dict)   # `const`s
    state_vars: dict[str, StateVar] = field(default_factory=dict)
    derived: dict[str, Derived] = field(default_factory=dict)
    actions: dict[str, Action] = field(default_factory=dict)
    continuous: dict[str, Continuous] = field(default_factory=dict)
    frames: tuple[Frame, ...] = ()
    templates: dict[str, Template] = field(default_factory=dict)
    rules: tuple[Rule, ...] = ()
    relaxations: tuple[Relaxation, ...] = ()
    settings: SolverSettings = SolverSettings()
    reachability: tuple[Reachability, ...] = ()
    scene_attrs: dict[str, SceneAttr] = field(default_factory=dict)
    primitives: dict[str, Primitive] = field(default_factory=dict)
    modules: dict[str, Module] = field(default_factory=dict)
    world_space: Space = Space("SE3", 7)
    span: Span | None = field(**_SPAN)
    avoid: Avoid | None = None       # the `avoid` declaration (None: every category, margin 0)

    # ---- the type hierarchy --------------------------------------------------------------
    def ancestors(self, type_name: str) -> tuple[str, ...]:
        """`type_name` and its ancestors up to `object`, most specific first."""
        out = []
        t: str | None = type_name
        while t is not None and t not in out:
            out.append(t)
            t = self.types[t].parent if t in self.types else None
        return tuple(out)

    def is_subtype(self, sub: str, sup: str) -> bool:
        return sup in self.ancestors(sub)

    def frame_of(self, type_name: str) -> Frame | None:
        """The frame declared for the most specific ancestor of `type_name`, if any."""
        by_type = {f.param.type: f for f in self.frames}
        for t in self.ancestors(type_name):
            if t in by_type:
                return by_type[t]
        return None


@dataclass(frozen=True)
class Problem:
    """A resolved problem: its domain, objects, initial state, goal, scene and settings.

    objects     every object (domain constants first, then the problem's, declaration order)
                -> its declared type
    init        one ground `Assign` per state-variable instance: the loader fills defaults
                (booleans false, `none` where allowed) and reports any instance left unassigned
    goal        ground literals (StateLit `=` and DerivedLit), and Or / And of them (`a or b`;
                compiled to a derived goal variable, `gnppdsl.compile.task`)
    settings    domain settings <- problem `solver { }` (apply CLI options with `.merged`)
    relaxations the problem's schedule if it declares one, else the domain's
    scene       the loaded scene (None if the problem names no scene)
    """

    name: str
    path: str
    domain: Domain
    objects: dict[str, str]
    init: tuple[Assign, ...]
    goal: tuple["StateLit | DerivedLit | Or | And", ...]
    settings: SolverSettings = SolverSettings()
    relaxations: tuple[Relaxation, ...] = ()
    reachability: tuple[Reachability, ...] = ()
    scene_path: str | None = None
    scene: object | None = None          # gnppdsl.ir.scene_model.Scene
    span: Span | None = field(**_SPAN)

    def objects_of(self, types: str | Iterable[str]) -> tuple[str, ...]:
        """Objects whose type is one of `types` or a subtype, in declaration order."""
        wanted = (types,) if isinstance(types, str) else tuple(types)
        return tuple(o for o, t in self.objects.items()
                     if any(self.domain.is_subtype(t, w) for w in wanted))

    @property
    def static_obstacles(self) -> dict:
        """Scene objects (`gnppdsl.ir.scene_model.SceneObject`, by name) that never move in this
        problem: `static: true` ones and every scene object the problem does not declare (kept
        at its scene pose as a static obstacle). Empty without a scene. See
        `Scene.static_obstacles`."""
        return {} if self.scene is None else self.scene.static_obstacles(self.objects)

    @property
    def undeclared_scene_objects(self) -> tuple[str, ...]:
        """Scene objects the problem does not declare (scene order): static obstacles for the
        solver and the verifier, never moved, never named by the logic."""
        if self.scene is None:
            return ()
        return tuple(n for n in self.scene.objects if n not in self.objects)

    def object_index(self, name: str) -> int:
        """Position of an object in declaration order (the order `where a < b` uses)."""
        return list(self.objects).index(name)

    def values_of(self, var: StateVar) -> tuple[str, ...]:
        """The value names of a state variable: ("false", "true") for booleans, else the
        objects of its domain types (declaration order) followed by "none" if allowed."""
        if var.is_bool:
            return (FALSE, TRUE)
        vals = self.objects_of(var.value_types) if var.value_types else ()
        return vals + ((NONE,) if var.allows_none else ())

    def waypoints_of(self, cont: Continuous) -> int:
        """Waypoints of a trajectory declaration (declared count or the settings default)."""
        if not cont.traj:
            return 0
        return cont.waypoints if cont.waypoints is not None else self.settings.waypoints

    def groundings(self, params: tuple[TypedParam, ...]) -> Iterator[tuple[str, ...]]:
        """All object tuples matching typed parameters (cartesian product, declaration order)."""
        from itertools import product

        return product(*(self.objects_of(p.types) for p in params))
