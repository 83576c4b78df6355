"""Collision coverage by an active set: every pair the domain's `avoid` declaration covers is
kept clear at keyframes, waypoints and segment midpoints, without listing the pairs by hand.

Why an active set and not every pair in every NLP: the Lab has 2 x 11 links, up to 17 blocks
and the scene; every pair at every waypoint would be ~10^4 distance rows per motion, nearly all
of them 20 cm or more apart. The independent verification (`gnppdsl.solve.verify_solution`,
pinocchio + coal with a bounding-sphere broadphase over ALL pairs) already finds the pairs that
matter at a solution; this module turns each one closer than `ActiveSet.near` into a factor
(`GraphNLPFactory.pair_factor`: sdist(a, b) >= margin at that keyframe, waypoint or midpoint),
adds them to the plan's graph-NLP and solves it again warm-started from the solution, until the
verification is clean (or `max_rounds`). Pairs in resting contact (an object and its parent, a
held object and its robot) are left to the domain's `on` / `grasp` factors: their signed
distance is 0 at a face contact, where its witness points jump and ipopt oscillates (see the
Lab domain's `apart` rule).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from gnppdsl.solve.result import SOLVED, UNVERIFIED, Result, Step
from gnppdsl.solve.verify_solution import SolutionReport, _FACT, verify_solution


@dataclass(frozen=True)
class ActiveSet:
    """Settings of the active set (from the domain's `avoid` declaration)."""

    avoid: tuple[str, ...] | None = None    # categories (`verify_solution.CATEGORIES`); None: all
    margin: float = 0.0                     # sdist >= margin for the pairs it adds
    near: float = 0.005                     # pairs closer than margin + near at a solution join
    max_rounds: int = 4


@dataclass
class Repair:
    """What the active set did to one solution."""

    rounds: int = 0
    added: int = 0                          # factors added over all rounds
    nlp_solves: int = 0
    time: float = 0.0
    report: SolutionReport | None = None
    values: dict = field(default_factory=dict)
    graph: Any = None


def active_set_of(problem: Any) -> ActiveSet:
    """The domain's `avoid` declaration as settings (default: all categories, margin 0)."""
    decl = getattr(problem.domain, "avoid", None)
    if decl is None:
        return ActiveSet()
    return ActiveSet(avoid=tuple(decl.categories), margin=float(decl.margin))


def verify(compiled: Any, result: Any, settings: ActiveSet | None = None, **kw: Any) -> SolutionReport:
    """The independent verification of a result of this compiled problem."""
    settings = settings or active_set_of(compiled.problem)
    return verify_solution(compiled.geometry, result, avoid=settings.avoid,
                           declared=compiled.problem.objects, **kw)


def _body(name: str) -> str | tuple[str, str]:
    return tuple(name.split("/", 1)) if "/" in name else name        # type: ignore[return-value]


def _parents(result: Any, step: int) -> dict[str, str]:
    return {o: p for var, o, p in _FACT.findall(result.steps[step].state) if var == "parent"}


def near_pairs(compiled: Any, result: Any, settings: ActiveSet) -> list[tuple[int, float | None, str, str]]:
    """(step, waypoint, body a, body b) of every covered pair closer than margin + near,
    except resting and grasp contacts (an object with its parent)."""
    rep = verify(compiled, result, settings, margin=settings.margin + settings.near, check_logic=False,
                 tolerance=0.0)
    out = []
    for f in rep.issues:
        if f.kind != "collision":
            continue
        a, b = f.bodies
        parents = _parents(result, f.step)
        owner = lambda x: x.split("/", 1)[0]       # noqa: E731
        if parents.get(a) == owner(b) or parents.get(b) == owner(a):
            continue
        out.append((f.step, f.waypoint, a, b))
    return out


def _known(factors) -> set:
    """(step, waypoint, {a, b}) of the pair factors already in a graph (repeat rounds)."""
    return {(f.step, dict(f.bindings).get("w"), frozenset((dict(f.bindings)["a"], dict(f.bindings)["b"])))
            for f in factors if f.rule == "avoid"}


def repair(compiled: Any, result: Result, solver: Any, settings: ActiveSet | None = None,
           deadline: float = float("inf")) -> Repair:
    """Add the near pairs of `result` as factors and re-solve its graph-NLP from its values,
    until the verification is clean. `solver`: a FeasibilitySolver (`solve(graph, warm_start)`).
    The returned `Repair.report` is the last verification (ok or not)."""
    from gnppdsl.nlp.graph import GraphNLP

    settings = settings or active_set_of(compiled.problem)
    t0 = time.perf_counter()
    out = Repair(report=verify(compiled, result, settings))
    graph, values = result.extras["graph"], dict(result.extras["values"])
    plan = result.extras["plan"]
    factory = compiled.factory
    current = result
    while not out.report.ok and out.rounds < settings.max_rounds and time.perf_counter() < deadline:
        if any(f.kind != "collision" for f in out.report.issues):
            break                                  # not a coverage gap: nothing to add
        known = _known(graph.factor_instances)
        new = []
        for step, wp, a, b in near_pairs(compiled, current, settings):
            key = (step, None if wp is None else f"{wp:g}", frozenset((a, b)))
            if key in known:
                continue
            known.add(key)
            f = factory.pair_factor(plan.states, step, _body(a), _body(b), settings.margin, wp)
            if f is not None:
                new.append(f)
        if not new:
            break
        out.rounds += 1
        out.added += len(new)
        graph = GraphNLP.from_factors(list(graph.factor_instances) + new, graph.variables,
                                      name=graph.name, initial_guess=getattr(graph, "initial_guess", None))
        r = solver.solve(graph, warm_start=values)
        out.nlp_solves += 1
        if r is None or not r.feasible:
            break
        values = {**values, **r.values}
        current = with_values(result, compiled.task, plan, graph, values)
        out.report = verify(compiled, current, settings)
    out.values, out.graph, out.time = values, graph, time.perf_counter() - t0
    return out


def with_values(result: Result, task: Any, plan: Any, graph: Any, values: dict) -> Result:
    """A copy of `result` whose steps carry `values` (the plan and states unchanged)."""
    steps = []
    for i, s in enumerate(plan.states):
        st = Step(i, plan.names[i - 1] if i > 0 else None, task.state_str(s))
        for v in graph.variables:
            if v.step != i or v not in values:
                continue
            x = np.asarray(values[v], float).reshape(-1)
            if v.waypoints:
                st.trajectories[v.key] = x.reshape(v.waypoints, v.point_dim).tolist()
            else:
                st.values[v.key] = x.tolist()
        steps.append(st)
    extras = {**result.extras, "graph": graph, "values": values}
    return Result(problem=result.problem, domain=result.domain, algorithm=result.algorithm,
                  switches=result.switches, seed=result.seed, status=result.status, message=result.message,
                  plan=list(result.plan), steps=steps, conflicts=result.conflicts, stats=result.stats,
                  time_limit=result.time_limit, verification=result.verification, extras=extras)


def verified(compiled: Any, result: Result, options: Any) -> Result:
    """Every solve's last word: a solved result is verified independently; one that fails is
    repaired by the active set, and if that does not make it clean it is reported as
    `verification_failed` (never as solved). The JSON carries `verification`."""
    if result.status != SOLVED:
        return result
    from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
    from gnppdsl.nlp import jit

    settings = active_set_of(compiled.problem)
    cpu0, wall0 = time.process_time(), time.perf_counter()
    report = verify(compiled, result, settings)
    if not report.ok and "graph" in result.extras:
        opts = SolverOptions(tolerance=options.tolerance, max_iter=options.max_iter, plugin=options.nlp,
                             distance_curvature=options.distance_curvature, restarts=0)
        solver = FeasibilitySolver(compiled.geometry, opts, compiler=compiled.body_compiler(jit.mode(options.jit)))
        rep = repair(compiled, result, solver, settings)
        result.stats.nlp_solves += rep.nlp_solves
        result.stats.ipopt_runs += solver.solves
        result.stats.nlp_time += solver.solve_time
        if rep.report.ok:
            result = with_values(result, compiled.task, result.extras["plan"], rep.graph, rep.values)
            result.stats.factors = rep.graph.n_factors
            result.message += (f"; the active set added {rep.added} pair factors in {rep.rounds} "
                               f"round{'s' if rep.rounds != 1 else ''}")
        report = rep.report
    result.stats.cpu_time += time.process_time() - cpu0
    result.stats.total_time += time.perf_counter() - wall0
    result.verification = report.to_json()
    if not report.ok:
        result.status = UNVERIFIED
        result.message = ("the solution fails the independent verification (pinocchio + coal): "
                          + "; ".join(report.failures[:3])
                          + (f" (+{len(report.issues) - 3} more)" if len(report.issues) > 3 else ""))
    return result
