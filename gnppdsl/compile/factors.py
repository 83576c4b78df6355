"""Graph-NLP factory output: variable vertices and factor instances (paper 000, Sec. IV).

Given a sequence of symbolic states <s_0 ... s_n>, the factory (`GraphNLPFactory` in
`gnppdsl.compile.factory`) applies the domain's rules Π to every step and lists

- the variable vertices x_i^k (`VarInstance`), and
- the factor vertices h (`FactorInstance`), each remembering its template, tags, variables, and
  the partial states (p at step i, and p' at step i+1 for transition rules) that generated it.

That memory is what maps an infeasible subgraph back to a sequence of partial states
<p_0 ... p_L> (paper Sec. VII). The generating partial state includes every fact the factor
depends on, i.e. the rule's pattern *plus* the state facts consulted to expand `world(o)`
along the kinematic chain, so factor time-invariance (Property 4.2) holds by construction.

Nothing here solves anything; the nlp layer turns each `body` into a casadi Function.
"""
from __future__ import annotations

from dataclasses import dataclass, field, replace
from functools import cached_property

from gnppdsl.compile.sas import PartialState
from gnppdsl.ir.expr import Constraint


@dataclass(frozen=True)
class VarInstance:
    """A variable vertex x_i^k. `key` (kind + args) is k; `step` is i."""

    kind: str                       # declared continuous variable, e.g. "pose", "q", "path"
    args: tuple[str, ...]           # objects, e.g. ("b1",)
    step: int
    space: str                      # "R", "SE2", "SE3", "joints"
    dim: int                        # total length of the flat vector (waypoints * point_dim)
    tags: frozenset[str] = frozenset()
    waypoints: int = 0              # > 0 for trajectories (`traj` declarations)
    lower: tuple[float, ...] | None = field(default=None, compare=False)   # per component
    upper: tuple[float, ...] | None = field(default=None, compare=False)

    @cached_property
    def key(self) -> str:
        """The variable kind k without time (`pose(b1)`): semantic label for matching.
        Computed once per instance (kept in its `__dict__`, outside the fields, so equality,
        hashing and `replace` are unchanged). Why: the semantic graphs of the database's
        lookups read it for every variable of every checked graph (lab3_paper, 3 seeds:
        55854 calls, 0.57 s of a 19 s profile)."""
        return f"{self.kind}({', '.join(self.args)})" if self.args else self.kind

    @property
    def name(self) -> str:
        return f"{self.key}@{self.step}"

    @property
    def point_dim(self) -> int:
        return self.dim // self.waypoints if self.waypoints else self.dim


@dataclass(frozen=True)
class FactorInstance:
    """A factor vertex h of the graph-NLP (one template instance)."""

    template: str                   # qualified template name, e.g. "planar.grasp"
    rule: str                       # the rule that produced it, e.g. "held"
    bindings: tuple[tuple[str, str], ...]   # rule pattern variables -> objects, e.g. (("o","b1"),)
    tags: frozenset[str]
    step: int                       # i: the factor relates x_i (and x_{i+1} if span == 2)
    span: int                       # 1: single-state rule, 2: transition rule
    generator: tuple[PartialState, ...]     # (p,) or (p, p') at steps i (, i+1)
    variables: tuple[VarInstance, ...]      # Slot(j) in `body` refers to variables[j]
    body: tuple[Constraint, ...]            # resolved (stage 2) constraints, see ir.expr

    @cached_property
    def label(self) -> str:
        """Human-readable: `held(o=b1, r=g) -> planar.grasp @3`. Computed once per instance
        (as `VarInstance.key`): the semantic graphs sort every factor by it (field4, 2 seeds:
        12728 calls, 0.43 s of a 31 s profile)."""
        b = ", ".join(f"{k}={v}" for k, v in self.bindings)
        return f"{self.rule}({b}) -> {self.template} @{self.step}"

    @property
    def steps(self) -> tuple[int, ...]:
        return tuple(sorted({v.step for v in self.variables}))

    def shifted(self, by: int) -> "FactorInstance":
        """The same factor `by` steps later (its variables too): a subgraph moved along a plan."""
        return replace(self, step=self.step + by,
                       variables=tuple(replace(v, step=v.step + by) for v in self.variables))
