"""Collision coverage by an active set: which pairs join a plan's graph-NLP (the loop that adds
them and solves again is `gnppdsl.solve.coverage`). Every pair the domain's `avoid` declaration
covers is kept clear at keyframes, waypoints and segment midpoints, without listing pairs by hand.

Why an active set and not every pair in every NLP: the Lab has 2 x 11 links, up to 17 blocks
and the scene; every pair at every waypoint would be ~10^4 distance rows per motion, nearly all
of them 20 cm or more apart. The independent verification (`gnppdsl.solve.verify_solution`,
pinocchio + coal with a bounding-sphere broadphase over ALL pairs) already finds the pairs that
matter at a solution; this module turns each one closer than `ActiveSet.near` into a factor
(`gnppdsl.compile.pair_factors`: sdist(a, b) >= margin at that keyframe, waypoint or midpoint);
the loop adds them to the plan's graph-NLP and solves it again warm-started from the solution,
until the verification is clean (or `max_rounds`). Pairs in resting contact (an object and its parent, a
held object and its robot) are left to the domain's `on` / `grasp` factors: their signed
distance is 0 at a face contact, where its witness points jump and ipopt oscillates (see the
Lab domain's `apart` rule).
"""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from gnppdsl.compile.pair_factors import pair_factor
from gnppdsl.solve.result import Result
from gnppdsl.solve.verify_solution import SolutionReport, _FACT, plan_failures, verify_solution


@dataclass(frozen=True)
class ActiveSet:
    """Settings of the active set (from the domain's `avoid` declaration)."""

    avoid: tuple[str, ...] | None = None    # categories (`verify_solution.CATEGORIES`); None: all
    margin: float = 0.0                     # sdist >= margin for the pairs it adds
    near: float = 0.005                     # pairs closer than margin + near at a solution join
    max_rounds: int = 4


def active_set_of(problem: Any) -> ActiveSet:
    """The domain's `avoid` declaration as settings (default: all categories, margin 0)."""
    decl = getattr(getattr(problem, "domain", None), "avoid", None)
    if decl is None:
        return ActiveSet()
    return ActiveSet(avoid=tuple(decl.categories), margin=float(decl.margin))


def verify(compiled: Any, result: Any, settings: ActiveSet | None = None, **kw: Any) -> SolutionReport:
    """The independent verification of a result of this compiled problem (its `near` list: the
    pairs closer than the active set's margin + near)."""
    settings = settings or active_set_of(compiled.problem)
    if compiled.geometry is None:        # no scene: nothing but the plan to verify
        issues = plan_failures(result)
        return SolutionReport(not issues, issues, keyframes=len(result.steps))
    return verify_solution(compiled.geometry, result, avoid=settings.avoid,
                           declared=compiled.problem.objects, near=settings.margin + settings.near, **kw)


def _body(name: str) -> str | tuple[str, str]:
    return tuple(name.split("/", 1)) if "/" in name else name        # type: ignore[return-value]


def _parents(result: Any, step: int) -> dict[str, str]:
    return {o: p for var, o, p in _FACT.findall(result.steps[step].state) if var == "parent"}


def near_pairs(result: Any, report: SolutionReport) -> list[tuple[int, float | None, str, str]]:
    """(step, waypoint, body a, body b) of every covered pair the verification found closer than
    margin + near (`verify`), except resting and grasp contacts (an object with its parent)."""
    out = []
    owner = lambda x: x.split("/", 1)[0]       # noqa: E731
    for step, wp, a, b, _ in report.near:
        parents = _parents(result, step)
        if parents.get(a) == owner(b) or parents.get(b) == owner(a):
            continue
        out.append((step, wp, a, b))
    return out


def _known(factors) -> set:
    """(step, waypoint, {a, b}) of the pair factors already in a graph (repeat rounds)."""
    return {(f.step, dict(f.bindings).get("w"), frozenset((dict(f.bindings)["a"], dict(f.bindings)["b"])))
            for f in factors if f.rule == "avoid"}


def pair_factors(compiled: Any, result: Result, report: SolutionReport, graph: Any,
                 settings: ActiveSet) -> list:
    """The factors (`gnppdsl.compile.pair_factors`, at the domain's margin) of the near pairs of
    `result` (its verification `report`) that `graph` does not hold yet."""
    plan = result.extras["plan"]
    known = _known(graph.factor_instances)
    new = []
    for step, wp, a, b in near_pairs(result, report):
        key = (step, None if wp is None else f"{wp:g}", frozenset((a, b)))
        if key in known:
            continue
        known.add(key)
        f = pair_factor(compiled.factory, plan.states, step, _body(a), _body(b), settings.margin, wp)
        if f is not None:
            new.append(f)
    return new
