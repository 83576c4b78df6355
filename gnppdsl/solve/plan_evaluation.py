"""Fig. 3, step 3 on one plan: its graph-NLP checked level by level (relaxations loose -> tight, the
full graph, in the order `full_first`, `relaxed_first` or `staged`), and Algorithm 1
(`gnppdsl.nlp.subgraph.find_infeasible_subgraph`) on the components of an infeasible level, its
result confirmed before it becomes the conflict.
"""
from __future__ import annotations

from typing import TYPE_CHECKING, Callable

from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.feasibility_check import LAZY_MAX_FACTORS, FeasibilityCheck
from gnppdsl.solve.options import overridden
from gnppdsl.solve.plan_graph import TRAJ
from gnppdsl.solve.run import Run

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.subgraph import Relaxation

Level = tuple["Relaxation | None", GraphNLP]
"""One level of a plan's evaluation: its relaxation (None: the full graph) and its graph."""


# order "staged": a relaxation level is solved before the full graph when it has at most this
# fraction of the factors of the plan's mode-switch graph (the full graph without trajectories)
STAGED_FRACTION = 0.5


LAZY_RETRIES = 1
"""Repeats of Alg. 1's search that keep one-start verdicts after `confirm` overturned one (the
overturned subgraph's solution is then in the memo); the next repeat gives every subgraph all
its starts."""


class PlanEvaluation(Run):
    """A solve that evaluates plans' graph-NLPs (Fig. 3, step 3; see the module docstring)."""

    def evaluate(self, graph: GraphNLP, use_db: bool, known: dict | None = None) -> tuple:
        """Algorithm 1 on one plan's graph-NLP.

        Order "full_first" (default, Fig. 3 step 3): solve the full graph-NLP first; only when it
        is infeasible search for a conflict, relaxations loose -> tight. "relaxed_first": the
        relaxations before the full graph, as Alg. 1 is written. "staged": the small relaxation
        levels, then the full graph, the large levels only to locate a conflict (`staged`).
        Relaxation levels whose factor set equals an earlier level's or the full graph's are
        skipped (same verdict); after an infeasible full graph, levels that nearly hold at its
        convergence point are skipped too (`nearly_holds`: no verdict, so no conflict).
        Each relaxed graph G_r is first checked as a whole (one NLP; by Property 4.5 it is
        feasible iff all its components are), and only an infeasible G_r is searched component
        by component with the double binary search on time and the convergence heuristic
        (`find_infeasible_subgraph`). Same verdicts as Alg. 1.
        `known`: values of graph's variables from the caller (an active-set round's failed
        repair, `coverage`): the checker's first values, i.e. warm starts, and a feasible verdict
        only where numpy finds they satisfy a graph (`known_solution`); never an infeasible one.
        Returns ("solution", values) | ("conflict", factors, relaxation) | ("inconsistent", why).
        """
        from gnppdsl.nlp.feasibility import FeasibilityResult
        from gnppdsl.nlp.subgraph import find_infeasible_subgraph

        sw = self.options.switches
        solver = self.new_solver()
        checker = FeasibilityCheck(self, solver, graph, use_db=use_db)
        if known:
            variables = set(graph.variables)
            checker.values.update({v: x for v, x in known.items() if v in variables})
        rules = [r for r in self.compiled.relaxations if r.dropped] if "r" in sw else []
        levels: list[Level] = []
        full_key = frozenset(graph.factor_refs)
        seen: set = set()
        for rule in rules:
            g_r = graph.apply_relaxation(rule.dropped, rule.name)
            key = frozenset(g_r.factor_refs)
            if g_r.n_factors == 0 or key in seen or key == full_key:
                continue
            seen.add(key)
            levels.append((rule, g_r))
        levels.append((None, graph))
        if self.options.order == "full_first" and len(levels) > 1:
            levels.insert(0, (None, graph))
        elif self.options.order == "staged" and len(levels) > 1:
            levels = self.staged(graph, levels, solver.iteration_cost)
        x_star: dict | None = None            # convergence point of the infeasible full graph
        full_seen = False
        for index, (rule, g_r) in enumerate(levels):
            if g_r.n_factors == 0:
                continue
            if rule is not None and x_star is not None and self.nearly_holds(g_r, x_star):
                self.stats.screened_levels += 1
                continue
            # levels before the full graph warm-start it: their first solve stays near its
            # start (`FeasibilityCheck.local_solve`). The full graph's first solve too: an infeasible
            # verdict there only starts Alg. 1, so it is kept unconfirmed (one start, no random
            # restarts) and gets the restarts only if the search returns a subgraph carrying it
            # (`confirm`); a feasible graph the one start missed has feasible components, which
            # the search then joins (planar p7: 102 -> 88 ipopt runs, p5: 18 -> 14)
            # (the full graph again at the end: its cached verdict, or, when that was its
            # keyframes' and they proved feasible since (`overturned`), a new one-start solve)
            with overridden(checker, local_first=not full_seen or rule is None):
                verdict = checker(g_r)
            full_seen = full_seen or rule is None
            feasible = verdict.feasible if hasattr(verdict, "feasible") else bool(verdict)
            if feasible:
                if rule is not None:
                    continue
                if hasattr(verdict, "values") and all(v in verdict.values for v in graph.variables):
                    return ("solution", verdict.values)
                r = checker.solve(graph)          # the database said feasible: get the values
                if r.feasible:
                    return ("solution", r.values)
                if use_db:                        # the solver disagrees with the database
                    return self.evaluate(graph, use_db=False, known=known)
                return ("inconsistent", "the full graph-NLP failed after a feasible verdict")
            if rule is None and index < len(levels) - 1:
                x_star = getattr(verdict, "values", None) or None
                continue                          # full graph infeasible: look for a conflict
            # Alg. 1 on the components of G_r; it returns the first infeasible one, so those
            # holding factors violated at G_r's convergence point are searched first.
            violated = set(verdict.violated(self.options.tolerance)) if hasattr(verdict, "violated") else set()
            comps = sorted(g_r.connected_components(),      # deterministic: no set order
                           key=lambda c: (not any(ref in violated for ref in c.factor_refs),
                                          c.steps or (0, 0), min(c.factor_refs)))

            def search_components(lazy: bool, lazy_large: bool) -> GraphNLP | None:
                with overridden(checker, lazy=lazy, lazy_large=lazy_large):
                    for comp in comps:
                        search = find_infeasible_subgraph(comp, (), sw.replace("r", "").replace("g", ""),
                                                          check=checker, solver=solver,
                                                          tolerance=self.options.tolerance,
                                                          recheck=checker.recheck,
                                                          recheck_above=LAZY_MAX_FACTORS)
                        self.stats.rechecks_feasible += search.stats.rechecks_feasible
                        self.heuristic_solves += search.stats.heuristic_solves
                        if search.subgraph is not None:
                            return search.subgraph
                    return None

            found = search_components(self.options.lazy_search, self.options.lazy_large)
            retries = 0
            while found is not None and not checker.confirm(found):
                # a one-start verdict led the search to a feasible subgraph (now in the memo
                # with its solution): search again without the one-start verdicts. The first
                # LAZY_RETRIES repeats keep one start for large subgraphs, the last one gives
                # every subgraph all its starts (the behaviour without lazy_search/lazy_large),
                # whose verdicts need no confirmation, so the loop ends. Why not all starts at
                # once: Lab 5 seed 6, a 76-factor slice failed one start and was solved by a
                # restart of `confirm`; the repeated search with restarts then spent 50 s on
                # each 360-factor slice and timed out.
                retries += 1
                strict = retries > LAZY_RETRIES
                self.say(f"  {found.name}: feasible from a restart; searching {g_r.name} again"
                         + (" with restarts" if strict else ""))
                self.stats.lazy_retries += 1
                checker.forget_unconfirmed()
                found = search_components(self.options.lazy_search and not strict,
                                          self.options.lazy_large and not strict)
            if found is None:
                # Every component is feasible, so G_r is (Property 4.5): the solver missed the
                # joint solution. The union of the components' solutions is one; never turn a
                # failed solve into a conflict.
                self.say(f"  {g_r.name}: components feasible, the whole solve failed; joining the components")
                values: dict = {}
                for comp in comps:
                    r = checker.solve(comp)
                    if not r.feasible:
                        return ("inconsistent", f"{comp.name} is feasible and infeasible in two solves")
                    values.update(r.values)
                if rule is None:
                    return ("solution", values)
                checker.values.update(values)
                checker.results[g_r.signature()] = FeasibilityResult(
                    True, values, {ref: 0.0 for ref in g_r.factor_refs}, 0.0, 0.0, 0.0, 0,
                    "its components are feasible", 0)
                continue
            return ("conflict", tuple(found.factor_instances), rule.name if rule is not None else "")
        return ("solution", {})

    @staticmethod
    def staged(graph: GraphNLP, levels: list[Level],
               cost: Callable[[GraphNLP], float] = lambda g: g.n_factors) -> list[Level]:
        """Order "staged": the small relaxation levels (an ipopt iteration on them costs at most
        STAGED_FRACTION of one on the mode-switch graph, by `cost`: the loop passes
        `FeasibilitySolver.iteration_cost`, distance rows weighted; the default counts factors),
        then the full graph, then the other levels (only the mode-switch graph among them when
        it is one), then the full graph again (its cached verdict: Alg. 1 searches it when no
        level gives a conflict).

        Why (measured on Lab 4, two Panda arms): the cost of an ipopt iteration grows with the
        collision factors between robot links and objects, ~0.1 s on a 6-step mode-switch graph
        against ~0.005 s without them, and a cold-started infeasible full graph cost 60-145 s
        (restarts included) before the relaxations found the conflict in 1-3 s. The small
        levels (no robot, no collisions) are cheap, find the kinematic and placement conflicts,
        and their solutions warm-start the full graph; the large ones cost about as much as the
        full graph and only help to locate a conflict once it is infeasible. Same verdicts as
        Alg. 1: every level is still a relaxation of the plan's graph."""
        full = levels[-1]
        modes_graph = graph.apply_relaxation({TRAJ}, "modes")
        modes = cost(modes_graph if modes_graph.n_factors else graph)
        small = [lv for lv in levels[:-1] if cost(lv[1]) <= STAGED_FRACTION * modes]
        large = [lv for lv in levels[:-1] if cost(lv[1]) > STAGED_FRACTION * modes]
        # When a large level is the mode-switch graph itself (the full graph without motions),
        # it alone is searched: the full graph's check already solved it (no new NLP before
        # Alg. 1 starts on its slices), while every other large level costs a whole new solve
        # of about the full graph's size (Lab 5: 145 s for no_time_traj, 3 starts).
        key = frozenset(modes_graph.factor_refs)
        same = [lv for lv in large if frozenset(lv[1].factor_refs) == key]
        if same and modes_graph.n_factors < graph.n_factors:
            large = same
        return [*small, full, *large, full] if large else [*small, full]

    def nearly_holds(self, g_r: GraphNLP, x_star: dict) -> bool:
        """Screening of a relaxation level by the full graph's convergence point x*: when every
        factor and bound of G_r holds at x* within `screen_tolerance` (looser than the verdict
        tolerance), G_r is taken as not the place of the conflict and its NLP is skipped. Why:
        an infeasible solve stops early, leaving residuals of ~1e-5 on factors that are not part
        of the contradiction; solving such a level only confirms it feasible. Sound either way:
        a skipped level gives no conflict and no verdict, the conflict then comes from a tighter
        level and is still confirmed by an NLP."""
        tol = self.options.screen_tolerance
        if tol <= 0 or any(v not in x_star for v in g_r.variables):
            return False
        return self.violation(g_r.factor_instances, {v: x_star[v] for v in g_r.variables},
                              g_r.variables) <= tol
