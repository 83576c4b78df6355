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
from gnppdsl.conflicts.semantic import by_identity
from gnppdsl.solve.result import Result
from gnppdsl.solve.verify_solution import SolutionReport, _FACT, plan_failures, verify_solution


@dataclass(frozen=True)
class ActiveSet:
    """Settings of the active set (from the domain's `avoid` declaration)."""

    avoid: tuple[str, ...] | None = None    # categories (`verify_solution.CATEGORIES`); None: all
    margin: float = 0.0                     # sdist >= margin for the pairs it adds
    near: float = 0.005                     # pairs closer than margin + near at a solution join
    max_rounds: int = 4                     # rounds for an optimised solution (then `Coverage.unoptimised`)
    # rounds for a solution the optimisation phase did not move: it has no feasible solution to
    # fall back on, so the run ends verification_failed when these run out. Why more: each
    # round re-solves for feasibility from the last solution and adds fewer pairs (field5 seed
    # 3: 99, 6, 5, 3, then 1 pair at -0.0039 m, clean after the fifth round; with 4 it ended
    # verification_failed, Table I 149/150 on a523e21)
    max_feasible_rounds: int = 8


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


Near = tuple[int, "float | None", str, str, float]
"""(step, waypoint, body a, body b, distance): a pair at a keyframe (waypoint None), a waypoint
or a segment midpoint of the motion s_step -> s_step+1."""


def near_pairs(result: Any, candidates: list[Near], riding: dict | None = None) -> list[Near]:
    """The `candidates` (the verification's `SolutionReport.near`: every covered pair closer
    than margin + near, `verify`; or `along_motion`'s spread) except resting and grasp contacts
    (an object with its parent) and the sliding contact of an object riding on a held tool with
    the static body it rests on at the motion's first keyframe (`riding`: the report's
    `SolutionReport.riding`; the domain's push rows,
    stdlib/tools.pntc `push_path`, keep it on that support's plane along the motion, and the
    verification still checks the pair at its resting margin). Why: a pushed block slides on
    the table at signed distance 0, where the witness points jump; its rows, fixed keyframes
    at each end, stalled every repair NLP of the push motion at 1e-5 .. 1e-4 (Work_1 seed 0,
    `avoid(table, b1)` at waypoints 6-11 of motion 2) and sent it on to the joint solves."""
    out = []
    owner = lambda x: x.split("/", 1)[0]       # noqa: E731
    riding = riding or {}
    by_step: dict[int, dict[str, str]] = {}
    for step, wp, a, b, d in candidates:
        parents = by_step.get(step)
        if parents is None:
            parents = by_step[step] = _parents(result, step)
        if parents.get(a) == owner(b) or parents.get(b) == owner(a):
            continue
        if b in riding.get((step, a), ()) or a in riding.get((step, b), ()):
            continue
        out.append((step, wp, a, b, d))
    return out


def along_motion(result: Any, report: SolutionReport) -> list[Near]:
    """(step, waypoint, a, b, distance) at every interior waypoint and segment midpoint of the
    motion s_step -> s_step+1 for each pair the verification found colliding somewhere along
    it (a `collision` failure at a waypoint or midpoint), filtered like `near_pairs`. Why the
    whole motion and not only where it collided: the optimisation phase (`solve.optimal`)
    shortens the path again from the repaired solution and cuts the obstacle's corner at the
    next unconstrained point. Measured on sort_random_pr2 instance 8 (R-LGP, PR2 base and arm
    against the centre table in the long base drive s0->s1): each of the four rounds moved the
    collision to other midpoints (3-4, 8-9, 10-11; 5-6; 11-12; 6-7; 9-10, -4 .. -7 cm) and the
    run ended verification_failed."""
    out = []
    for f in report.issues:
        if f.kind != "collision" or f.waypoint is None or f.step is None or len(f.bodies) != 2:
            continue
        n = max((len(P) for P in result.steps[f.step].trajectories.values()), default=0)
        a, b = f.bodies
        out += [(f.step, float(k), a, b, f.distance) for k in range(1, n - 1)]
        out += [(f.step, k + 0.5, a, b, f.distance) for k in range(n - 1)]
    return near_pairs(result, out, report.riding)


def _known(factors) -> set:
    """(step, waypoint, {a, b}) of every signed distance some factor of the graph already
    constrains: the pair factors of earlier rounds and the domain's own templates (a waypoint
    of a template read as `path(r)[k]`: "k"; a keyframe: None). Why: the near pairs of a
    solution are mostly those the templates hold at their margins (lab5: 300 of them), and a
    second row on the same pair adds NLP work and nothing else."""
    from gnppdsl.ir.expr import Call, Num, Obj, Str

    def body_name(e) -> str | None:
        if isinstance(e, Obj):
            return e.name
        if isinstance(e, Call) and e.fn == "link" and isinstance(e.args[0], Obj) and isinstance(e.args[1], Str):
            return f"{e.args[0].name}/{e.args[1].value}"
        return None

    def waypoints(e, out: set) -> set:
        if isinstance(e, Call):
            if e.fn == "waypoint" and isinstance(e.args[1], Num):
                out.add(int(e.args[1].value))
            for x in e.args:
                waypoints(x, out)
        for x in getattr(e, "items", ()):
            waypoints(x, out)
        return out

    def distances(e):
        if isinstance(e, Call):
            if e.fn in ("sdist", "sdist2") and len(e.args) == 4:
                yield e
            for x in e.args:
                yield from distances(x)

    def body_pairs(body) -> list:
        """The (waypoint, pair) of each distance a body queries (walked once per body: each
        round and each plan's graph share the bodies; walking them again cost 4 s a call on
        lab5_paper, 3229 factors, a profile)."""
        pairs = []
        for c in body:
            for d in distances(c.lhs):
                a, b = body_name(d.args[0]), body_name(d.args[2])
                if a is None or b is None:
                    continue
                ks = waypoints(d.args[1], set()) | waypoints(d.args[3], set())
                pairs.append((f"{ks.pop():g}" if len(ks) == 1 else None, frozenset((a, b))))
        return pairs

    known = set()
    for f in factors:
        if f.rule == "avoid":
            b = dict(f.bindings)
            known.add((f.step, b.get("w"), frozenset((b["a"], b["b"]))))
            continue
        if "collision" not in f.tags:
            continue
        known.update((f.step, w, pair) for w, pair in by_identity("pairs", f.body, body_pairs))
    return known


def pair_factors(compiled: Any, result: Result, report: SolutionReport, graph: Any,
                 settings: ActiveSet, spread: bool = False) -> list:
    """The factors (`gnppdsl.compile.pair_factors`, at the domain's margin) of the near pairs of
    `result` (its verification `report`) that `graph` does not hold yet.

    A pair near at a waypoint (or midpoint) of the motion s_step -> s_step+1 whose factor
    reads no trajectory (neither body moves with a robot in that phase: two resting objects,
    a resting object and the scene) is the same constraint at every waypoint and at the
    keyframe s_step (`static_pair`), so it is added once, as the keyframe's factor. Why:
    lab5_paper's first round found 1997 near pairs, ~1700 of them resting blocks against the
    table under their pads and against the obstacles beside them, listed at each of the
    motion's 19 waypoints and 20 midpoints; they became 1278 pair factors, most of them
    copies of one row, which the repair's NLPs carried through every iteration.

    `spread` (a solution the optimisation phase moved): a pair colliding somewhere along a
    motion joins at every waypoint and midpoint of it (`along_motion`)."""
    plan = result.extras["plan"]
    known = _known(graph.factor_instances)
    static: dict[tuple, bool] = {}          # (step, pair): its factor reads no trajectory
    new = []

    def build(step: int, a: str, b: str, wp: float | None):
        return pair_factor(compiled.factory, plan.states, step, _body(a), _body(b), settings.margin, wp)

    for step, wp, a, b, d in near_pairs(result, report.near, report.riding) + (along_motion(result, report) if spread else []):
        pair = frozenset((a, b))
        if wp is not None and static.get((step, pair)) is None:
            f = build(step, a, b, wp)
            static[(step, pair)] = f is not None and static_pair(f)
        if wp is not None and static[(step, pair)]:
            wp = None                       # the keyframe's factor is the same row
        key = (step, None if wp is None else f"{wp:g}", pair)
        if key in known:
            continue
        if wp is not None and not float(wp).is_integer() and d >= settings.margin - 1e-4 and \
                any((step, f"{k:g}", pair) in known for k in (wp - 0.5, wp + 0.5)):
            continue    # near, not violated, between waypoints whose rows already hold the pair
        known.add(key)
        f = build(step, a, b, wp)
        if f is not None:
            new.append(f)
    return new


def static_pair(f: Any) -> bool:
    """Does a pair factor built at a waypoint read no trajectory variable (so its row is the
    same at every waypoint of the motion and at its first keyframe)?"""
    from gnppdsl.solve.plan_graph import is_trajectory

    return not any(is_trajectory(v) for v in f.variables)
