"""Finding a small infeasible subgraph (paper 000, Sec. VI and Algorithm 1, Appendix A).

    for r in R (loose to tight, the full graph last):
        G_r  <- r(G)                        # delete tagged variables and constraints
        for g in ConnectedComponents(G_r):
            feasible, [t_f, t_l] <- BinarySearchTime(g)
            if not feasible:
                return ConvergenceHeuristic(g[t_f, t_l])

With `t` and `n`, one round of the convergence heuristic also runs on an infeasible component
before its time search (`shrink_before_time_search`), which then searches the (smaller,
infeasible) candidate.

Switches as in the paper's GNPP_trng names: `t` double binary search on the time index,
`r` relaxations, `n` convergence heuristic (`g`, the database of solved subgraphs, belongs to
the caller: it is implemented by the injected `check`, see below). Without `t` a whole
infeasible component is returned; without `r` only the full graph is searched; without `n` the
time slice is returned as is. Connected components are always used (Property 4.5: they are
solved independently and the minimal infeasible subgraph is connected).

Feasibility checks go through `check(graph) -> bool | FeasibilityResult`, injected so that the
solve loop can answer from its database of solved subgraphs without calling the solver (the
paper's switch g) and count real NLP solves. Within one call every distinct subgraph is checked
at most once (memo by vertex set). The convergence heuristic needs the optimizer's convergence
point on g[t_f, t_l]; when the check answered with a plain bool, `solve` is called for it.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Callable, Iterable, Sequence

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.nlp.feasibility import FeasibilityResult, FeasibilitySolver
from gnppdsl.nlp.graph import GraphNLP

Check = Callable[[GraphNLP], "bool | FeasibilityResult"]


@dataclass(frozen=True)
class Relaxation:
    """A relaxation rule: drop every variable and constraint carrying one of `dropped` tags."""

    name: str
    dropped: frozenset[str] = frozenset()

    @staticmethod
    def of(name: str, dropped: Iterable[str]) -> "Relaxation":
        return Relaxation(name, frozenset(dropped))


FULL = Relaxation("full")


@dataclass
class SearchStats:
    checks: int = 0                  # distinct subgraphs checked (memo hits excluded)
    solves: int = 0                  # checks answered by the NLP solver (FeasibilityResult)
    heuristic_solves: int = 0        # extra solves to get a convergence point
    rechecks_feasible: int = 0       # time ranges found feasible by `recheck` after failing
    log: list[tuple[str, int, bool]] = field(default_factory=list)   # (graph, |H|, feasible)


@dataclass
class SearchResult:
    """Outcome of Alg. 1: an infeasible subgraph, or the full graph found feasible."""

    subgraph: GraphNLP | None              # None when every component of G is feasible
    relaxation: str | None = None          # the relaxation under which it was found
    time_range: tuple[int, int] | None = None
    values: dict[VarInstance, object] = field(default_factory=dict)  # solution if feasible
    complete_values: bool = False          # every variable of G has a value from a real solve
    stats: SearchStats = field(default_factory=SearchStats)

    @property
    def feasible(self) -> bool:
        return self.subgraph is None


class _Checker:
    """Memoised, counting wrapper around the injected check."""

    def __init__(self, check: Check, stats: SearchStats):
        self.check, self.stats = check, stats
        self.memo: dict[frozenset, bool | FeasibilityResult] = {}

    def result(self, g: GraphNLP) -> bool | FeasibilityResult:
        if g.n_factors == 0:
            return True
        key = g.signature()
        if key not in self.memo:
            r = self.check(g)
            self.stats.checks += 1
            if isinstance(r, FeasibilityResult):
                self.stats.solves += 1
            self.memo[key] = r
            self.stats.log.append((g.name, g.n_factors, _ok(r)))
        return self.memo[key]

    def __call__(self, g: GraphNLP) -> bool:
        return _ok(self.result(g))


def _ok(r: bool | FeasibilityResult) -> bool:
    return r.feasible if isinstance(r, FeasibilityResult) else bool(r)


def _free_value(v: VarInstance, guess) -> np.ndarray:
    """A value for a variable no factor constrains: its guess (or 0, identity quaternions),
    clipped to its bounds."""
    x = np.zeros(v.dim) if guess is None else np.asarray(guess, float).reshape(-1).copy()
    if guess is None and v.space == "SE3":
        x.reshape(max(v.waypoints, 1), -1)[:, 6] = 1.0
    lo = -np.inf if v.lower is None else np.resize(np.asarray(v.lower, float), v.dim)
    hi = np.inf if v.upper is None else np.resize(np.asarray(v.upper, float), v.dim)
    return np.clip(x, lo, hi)


def binary_search_time(graph: GraphNLP, is_feasible: Callable[[GraphNLP], bool],
                       hint: Callable[[GraphNLP], tuple[int, int] | None] | None = None
                       ) -> tuple[bool, tuple[int, int] | None]:
    """Double binary search on the time index (Sec. VI-A), O(log n) feasibility checks.

    Returns (True, None) if `graph` is feasible, else (False, (f, l)) with l the minimum upper
    index such that G[s_lo .. s_l] is infeasible and then f the maximum lower index such that
    G[s_f .. s_l] is infeasible. Correct by monotone infeasibility (Property 4.4): slices grow
    with l and shrink with f, so any choice of pivots finds the same (f, l).

    `hint(g)` (optional) is the step range of the factors violated at the convergence point of
    g's last solve, when known (`violated_steps`). Where the solver left the violation is where
    the contradiction usually is, so the pivot of each bisection is first taken there: G[lo..e]
    with e the last violated step, then G[s..l] with s the first, whenever that slice is no
    larger than the midpoint's. Why: the midpoint halves of a long plan are the largest NLPs of
    the search (Lab 5: the 6-step half of a 10-step mode-switch graph, 3 starts, 19 s) while
    the contradiction sits in 2-3 steps. A hinted pivot whose slice is infeasible shrinks the
    range at least as much as the midpoint; the first one found feasible ends the hints (a
    misleading convergence point), so the search stays within log2(n) + 1 checks per index."""
    steps = graph.steps
    if steps is None or is_feasible(graph):
        return True, None
    lo, hi = steps
    use_hint = hint is not None

    def slice_(first: int, last: int) -> GraphNLP:
        return graph if (first, last) == (lo, hi) else graph.time_slice(first, last)

    a, b = lo, hi                       # invariant: G[lo..b] infeasible
    while a < b:
        mid = (a + b) // 2
        rng = hint(slice_(lo, b)) if use_hint else None
        hinted = rng is not None and a <= rng[1] < mid
        if hinted:
            mid = rng[1]
        if is_feasible(graph.time_slice(lo, mid)):
            a = mid + 1
            use_hint = use_hint and not hinted
        else:
            b = mid
    last = b
    a, b = lo, last                     # invariant: G[a..last] infeasible
    while a < b:
        mid = (a + b + 1) // 2
        rng = hint(slice_(a, last)) if use_hint else None
        hinted = rng is not None and mid < rng[0] <= b
        if hinted:
            mid = rng[0]
        if is_feasible(graph.time_slice(mid, last)):
            b = mid - 1
            use_hint = use_hint and not hinted
        else:
            a = mid
    return False, (a, last)


HINT_SHARE = 0.1    # `violated_steps`: factors violated by at least this share of the worst one


def violated_steps(graph: GraphNLP, result: "bool | FeasibilityResult | None",
                   tolerance: float) -> tuple[int, int] | None:
    """(first, last) step of the factors violated at the convergence point of `result`, the
    solve of `graph`, by at least HINT_SHARE of the largest violation (None without a
    convergence point): the time search's hint. Why the share: a solve stopped on a stall
    leaves residuals of 1e-5..1e-3 all along the plan (Lab 5: placement rows at every step)
    while the contradiction carries the violation (2.8e-2 on the grasp of the step that fails)."""
    if not isinstance(result, FeasibilityResult) or result.feasible:
        return None
    worst = result.max_violation
    if not math.isfinite(worst):
        return None
    floor = max(tolerance, HINT_SHARE * worst)
    fs = [graph.factor(r) for r, v in result.violations.items() if v >= floor and r in graph.graph]
    if not fs:
        return None
    return min(f.step for f in fs), max(f.step + f.span - 1 for f in fs)


def convergence_heuristic(graph: GraphNLP, result: FeasibilityResult,
                          check: Callable[[GraphNLP], "bool | FeasibilityResult"],
                          tolerance: float = 1e-6, rounds: int = 3,
                          max_fraction: float = 1.0) -> GraphNLP:
    """Sec. VI-C: shrink an infeasible `graph` around the factors violated at the convergence
    point x* of its solve. Never returns a feasible graph (every candidate is checked).

    Candidates, each kept only if `check` finds it infeasible:
    - M'_a, the *support* of the infeasibility: the violated factors and those whose
      multipliers at x* show they hold the violated ones off (`FeasibilityResult.active`),
      tried first when the solve reported multipliers. Why: it is the contradiction itself
      (planar p5: the spot's pose, the pick's kinematic switch, the gripper's reach box and the
      violated grasp, 4 of 13 factors), where M'_v also takes every other factor on those
      variables and M' misses the rows on the other side of the contradiction. A feasible
      M'_a says nothing about M'_v (not a subgraph of it), so M'_v is still tried; M' is a
      subgraph of M'_a and is then skipped.
    - M'_v, the subgraph *induced* by the variables of the violated factors (every factor of
      `graph` on those variables, Definition 4.2). Tried first because the violated factors
      alone usually lack the constraints that pin their variables: the elastic optimum puts
      the slack on one side of a contradiction, and that side alone is satisfiable.
    - M', the violated factors alone (the paper's form), tried after M'_v when it is smaller
      and has at least two factors. A single factor is not tried: alone, all its variables
      are free, so it fails only if its template cannot hold for its constants, which the
      time search already isolates (a one-factor time slice).
    Repeated on the result (up to `rounds` times) while the check returns convergence points.
    A candidate inside one found feasible is skipped (a subgraph of a feasible graph is
    feasible, Property 4.4): M' after a feasible M'_v or M'_a.
    `max_fraction` < 1: a candidate keeping more than this fraction of the current graph's
    factors is not checked (it would cost about as much as the graph itself), except M'_a
    when it spans fewer steps than the graph (it then spares the time search's slices).
    """
    cur, r = graph, result
    for _ in range(rounds):
        violated = r.violated(tolerance)
        if not violated:
            break
        xs = {v for ref in violated for v in cur.graph.neighbors(ref)}
        candidates = []                    # (subgraph, exempt from max_fraction)
        support = [ref for ref in r.active(tolerance) if ref in cur.graph]
        if len(support) > len(violated):
            m = cur.subgraph(factors=support, suffix="{a}")
            candidates.append((m, _spans_fewer_steps(m, cur)))
        candidates.append((cur.subgraph(variables=xs, suffix="{v}"), False))
        if len(violated) > 1:
            candidates.append((cur.subgraph(factors=violated, suffix="{n}"), False))
        progressed = False
        feasible: list[frozenset] = []     # factor sets of candidates found feasible
        for m, exempt in candidates:
            if m.n_factors == 0 or m.n_factors >= cur.n_factors or m.signature() == cur.signature() \
                    or (m.n_factors > max_fraction * cur.n_factors and not exempt):
                continue
            refs = frozenset(m.factor_refs)
            if any(refs <= f for f in feasible):
                continue                   # a subgraph of a feasible candidate is feasible
            verdict = check(m)
            if _ok(verdict):
                feasible.append(refs)
                continue
            cur, progressed = m, True
            if not isinstance(verdict, FeasibilityResult):
                return cur                 # no convergence point to go on from
            r = verdict
        if not progressed:
            break
    return cur


def _spans_fewer_steps(m: GraphNLP, g: GraphNLP) -> bool:
    return m.steps is not None and g.steps is not None and m.steps[1] - m.steps[0] < g.steps[1] - g.steps[0]


SHRINK_FRACTION = 0.5     # `shrink_before_time_search` tries candidates up to this share of factors


def shrink_before_time_search(comp: GraphNLP, check: "_Checker", tolerance: float) -> GraphNLP:
    """One round of the convergence heuristic on a whole infeasible component, before the
    time search: the support of its convergence point or the subgraph induced by the variables
    of the factors violated there, if infeasible (checked like any other), else the component.

    Why first and not only after the time search (Alg. 1 as written): on a long plan the time
    search solves halves and quarters of the component before the heuristic sees it, and
    those are the largest NLPs of the whole search (Lab 5: a 245-factor slice of a 437-factor
    mode-switch graph, 3 starts, 51 s; then 123 factors, 18 s), while the factors violated at
    the component's convergence point usually sit in the one or two steps of the
    contradiction. The time search then runs on the small candidate (its slices are slices
    of the component, so they are found the same way) and the heuristic ends the search as
    before. Sound either way: the candidate is kept only when its check says infeasible, and
    a feasible candidate costs one small solve. A candidate with more than half the
    component's factors is not tried (SHRINK_FRACTION): its check, restarts included, costs
    about what the component's did (Lab 5 seed 1: a 388-factor candidate of a 444-factor
    component, 60 s, whose random restarts drove the arms deep into objects, where each
    distance is an EPA penetration query), and the time search halves the component anyway."""
    r = check.result(comp)
    if not isinstance(r, FeasibilityResult) or r.feasible or comp.steps is None \
            or comp.steps[0] == comp.steps[1]:
        return comp
    return convergence_heuristic(comp, r, check.result, tolerance, rounds=1, max_fraction=SHRINK_FRACTION)


def _strict_slices_feasible(g: GraphNLP, rng: tuple[int, int] | None, checker: "_Checker") -> bool:
    """The time search kept the multi-step range `rng` = (f, l) of g, and its strict slices
    G[f..l-1] and G[f+1..l] are known feasible: checked (memo), or inside a slice checked
    feasible (Property 4.4). The search itself provides both: G[f..l-1] lies in G[lo..l-1],
    the feasible slice that fixed l, and G[f+1..l] is the feasible slice that fixed f."""
    if rng is None or g.steps is None or rng[1] <= rng[0]:
        return False
    lo, (f, l) = g.steps[0], rng

    def known(*ranges: tuple[int, int]) -> bool:
        # _ok(None) is False: a slice never checked does not count as feasible
        return any(_ok(checker.memo.get(g.time_slice(a, b).signature())) for a, b in dict.fromkeys(ranges))

    return known((f, l - 1), (lo, l - 1)) and known((f + 1, l))


def find_infeasible_subgraph(graph: GraphNLP, relaxations: Sequence[Relaxation] = (),
                             switches: str = "trn", check: Check | None = None,
                             solver: FeasibilitySolver | None = None,
                             tolerance: float | None = None,
                             recheck: Check | None = None,
                             recheck_above: int = 0) -> SearchResult:
    """Algorithm 1. `relaxations` are tried loose to tight, the full graph last (added if
    missing). `check` defaults to `solver.solve` with warm starts from earlier feasible
    solutions; `solver` also provides convergence points when `check` returns bools.

    `recheck` (optional) is the second opinion on the range [f, l] the time search ends with
    when it spans several steps: G[f..l] failed, but its two strict slices G[f..l-1] and
    G[f+1..l] are feasible. That is what a solver failing on a large, feasible graph looks
    like (a local minimum from every start it had), so before G[f..l] becomes a conflict it
    is solved again, warm-started from those slices' solutions (`recheck` must use them).
    Only a real solution turns the verdict (sound either way): then the search goes on from
    its memo with that verdict, and so on until a range holds its second opinion or the
    component is feasible. Why every range and not only a whole component's: on Lab 5 the
    false conflicts were 5-8-step slices (G[0..4] of a 10-step plan, infeasible from three
    starts after 482 iterations, 11 s, while G[0..3] and G[1..4] solved at once and another
    seed solved the whole plan), each one learnt as a conflict that cut off feasible plans.
    A range short of the whole component gets it only when it has more than `recheck_above`
    factors: a small NLP's verdict from several starts is reliable, and there the second
    opinion is one more NLP before the same conflict (planar p5: 6 -> 7 NLPs).
    Without `recheck` the range is returned as infeasible, as Alg. 1 has it."""
    unknown = set(switches) - set("trng")
    if unknown:
        raise ValueError(f"unknown switches {''.join(sorted(unknown))!r} (allowed: t, r, n, g)")
    solver = solver or FeasibilitySolver()
    tol = solver.options.tolerance if tolerance is None else tolerance
    warm: dict[VarInstance, object] = {}

    def default_check(g: GraphNLP) -> FeasibilityResult:
        r = solver.solve(g, warm_start=warm)
        if r.feasible:
            warm.update(r.values)
        return r

    stats = SearchStats()
    checker = _Checker(check or default_check, stats)
    rules = list(relaxations) if "r" in switches else []
    rules = [r for r in rules if r.dropped] + [FULL]

    def time_search(g: GraphNLP, component: GraphNLP) -> tuple[bool, tuple[int, int] | None]:
        """Alg. 1's BinarySearchTime on g (the component or a candidate inside it), with the
        second opinion on a kept multi-step range (whatever its size only if it is the whole
        component)."""
        def hint(s: GraphNLP) -> tuple[int, int] | None:
            return violated_steps(s, checker.memo.get(s.signature()), tol)

        feasible, rng = binary_search_time(g, checker, hint)
        rechecked: set = set()
        while not feasible and recheck is not None and rng not in rechecked \
                and _strict_slices_feasible(g, rng, checker):
            rechecked.add(rng)
            kept = g if rng == g.steps else g.time_slice(*rng)
            if kept.signature() != component.signature() and kept.n_factors <= recheck_above:
                break
            second = recheck(kept)
            if not _ok(second):
                break
            checker.memo[kept.signature()] = second
            stats.rechecks_feasible += 1
            # the memo now holds a feasible G[f..l]: the search resumes above it (every other
            # verdict is reused), ending at a larger range or at g feasible
            feasible, rng = binary_search_time(g, checker, hint)
        return feasible, rng

    for rule in rules:
        g_r = graph.apply_relaxation(rule.dropped, rule.name) if rule.dropped else graph
        values: dict[VarInstance, object] = {}
        complete = True
        for comp in g_r.connected_components():
            target = comp                      # what the time search and the heuristic shrink
            if "t" in switches:
                if "n" in switches:
                    target = shrink_before_time_search(comp, checker, tol)
                feasible, rng = time_search(target, comp)
                if feasible and target is not comp:
                    # the candidate turned out feasible on its second opinion: search the
                    # component itself, as Alg. 1 has it (never take its verdict for comp's)
                    target = comp
                    feasible, rng = time_search(comp, comp)
            else:
                feasible = checker(comp)
                rng = None if feasible else comp.steps
            if feasible:
                r = checker.result(comp)
                if isinstance(r, FeasibilityResult):
                    values.update(r.values)
                else:
                    complete = False
                continue
            g_s = target.time_slice(*rng) if "t" in switches else comp
            if "n" in switches:
                r = checker.result(g_s)
                if not isinstance(r, FeasibilityResult):
                    r = solver.solve(g_s, warm_start=warm)
                    stats.heuristic_solves += 1
                g_s = convergence_heuristic(g_s, r, checker.result, tol)
            return SearchResult(g_s, rule.name, rng, stats=stats)
        if rule is FULL:
            for v in graph.variables:          # unconstrained vertices: any value in bounds
                if v not in values and graph.graph.degree(v) == 0:
                    values[v] = _free_value(v, graph.initial_guess.get(v))
            covered = all(v in values for v in graph.variables)
            return SearchResult(None, None, None, values, complete and covered, stats)
    raise AssertionError("unreachable: the full graph is always the last rule")
