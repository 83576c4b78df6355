"""Verdicts without an NLP (paper 000, Property 4.5 and Definition 4.3, plus certificates): a
subgraph whose factors hold at values already known is feasible; the only violated component of
an infeasible graph is infeasible; a subgraph certified at a cheap graph's convergence point is
infeasible (`gnppdsl.nlp.certificate`). Counted as `inferred_verdicts` / `reused_solutions` /
`certified_verdicts`, never as NLP solves.
"""
from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.check_memory import CheckMemory
from gnppdsl.solve.plan_graph import bound_violation, is_trajectory

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.feasibility import FeasibilityResult


# a subgraph starts from an earlier convergence point only when that violates it by less than
# this (and less than the earlier solutions do): see `FeasibilityCheck.solve`
CLOSE_START = 1e-3


class InferredVerdicts(CheckMemory):
    """The feasibility check's verdicts that need no NLP (see the module docstring)."""

    def certify(self, g: GraphNLP) -> FeasibilityResult | None:
        """An infeasible verdict on g without an NLP: g is a proper subgraph of a cheap graph
        whose one-start solve ended infeasible, and that convergence point is a strict local
        minimum of g's own elastic NLP with the same violation (`certify_infeasible`). The
        verdict is one-start evidence like the lazy search's (unconfirmed): if g becomes the
        conflict, `confirm` gives it the restarts, as the graph's restarts when they certify g
        too. Why: the convergence heuristic's support (Sec. VI-C) is usually exactly such a
        subgraph, and solving it repeated what the graph's solve had shown (planar p5, per
        failed plan: the plan's NLP and the support's NLP, now the plan's alone)."""
        from gnppdsl.nlp.certificate import certify_infeasible

        refs = frozenset(g.factor_refs)
        for parent_refs, parent, point in self.parents:
            if not refs < parent_refs:
                continue
            r = certify_infeasible(self.solver, g, point, parent)
            if r is None:
                continue
            key = g.signature()
            self.results[key] = r
            self.parent_of[key] = parent
            self.unconfirmed.add(key)
            self.run.stats.certified_verdicts += 1
            return r
        return None

    def infer_components(self, g: GraphNLP, r: FeasibilityResult) -> None:
        """Verdicts on the components of an infeasible g without an NLP (Property 4.5).

        Components share no variables, so the convergence point x* restricted to a component
        whose factors (and bounds) all hold at x* is a solution of it: feasible. If exactly
        one component is violated at x* and every other one is feasible that way, the
        infeasibility of g lies in it: infeasible, with x* as its convergence point (what
        Alg. 1 would solve it for next)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        comps = g.connected_components()
        if len(comps) < 2 or not r.values:
            return
        tol = self.run.options.tolerance
        bad, good = [], 0
        for c in comps:
            per = {ref: r.violations.get(ref, np.inf) for ref in c.factor_refs}
            vals = {v: r.values[v] for v in c.variables if v in r.values}
            worst = max(per.values(), default=0.0)
            if worst <= tol and len(vals) == len(c.variables) and bound_violation(c.variables, vals) <= tol:
                good += 1
                self.results.setdefault(c.signature(), FeasibilityResult(
                    True, vals, per, worst, 0.0, 0.0, 0, f"holds at the convergence point of {g.name}", 0))
                self.values.update(vals)
            else:
                bad.append((c, per, vals, worst))
        if len(bad) == 1 and good == len(comps) - 1:
            c, per, vals, worst = bad[0]
            if g.signature() in self.unconfirmed:
                self.unconfirmed.add(c.signature())
                self.parent_of.setdefault(c.signature(), g)
                self.components.add(c.signature())
            if c.signature() not in self.results:
                activity = getattr(r, "activity", {})
                self.results[c.signature()] = FeasibilityResult(
                    False, vals, per, worst, r.slack, 0.0, 0, f"the only violated component of {g.name}", 0,
                    {ref: activity[ref] for ref in c.factor_refs if ref in activity})
                self.run.stats.inferred_verdicts += 1

    def known_solution(self, g: GraphNLP) -> FeasibilityResult | None:
        """A feasible verdict without an NLP: when the values of earlier feasible solves of this
        plan's subgraphs, or the convergence point of an earlier infeasible solve, or the start
        an NLP would be given (those values, the factory's initial guess for the others) cover
        every variable of g and satisfy all its factors and bounds (evaluated independently
        with numpy), g is feasible (Definition 4.3) and those values are a solution. Typical
        cases: a time slice inside a feasible relaxation; a relaxation without the factors
        violated at the full graph's convergence point; a slice whose factors the initial
        guess already satisfies (a block resting on its spot, a gripper at home), which ipopt
        would confirm in 0 iterations but which would count as an NLP (planar p7: 42 -> 30
        NLPs, p5: 9 -> 6)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        # (values, why they would do, whether they are a convergence point rather than the
        # start the NLP would be given)
        sources = [(self.values, "earlier solutions satisfy it", False),
                   *((p, "an earlier convergence point satisfies it", True) for p in self.points),
                   (self.start_point(g), "its start (earlier solutions and the initial guess) satisfies it",
                    False)]
        self.closest_point = None
        own = np.inf                      # violation at the start the NLP would be given
        best = (np.inf, None)             # the convergence point closest to satisfying g
        for point, why, converged in sources:
            if not point or any(v not in point for v in g.variables):
                continue
            values = {v: point[v] for v in g.variables}
            worst = self.run.violation(g.factor_instances, values, g.variables)
            if not worst <= self.run.options.tolerance:
                if not converged:
                    own = min(own, worst)
                elif worst < best[0]:
                    best = (worst, values)
                continue
            self.run.stats.reused_solutions += 1
            per = {r: 0.0 for r in g.factor_refs}
            return FeasibilityResult(True, values, per, worst, 0.0, 0.0, 0, why, 0)
        if best[0] < min(own, CLOSE_START):
            self.closest_point = best[1]
        return None

    def start_point(self, g: GraphNLP) -> dict | None:
        """The values of this plan's earlier feasible solves, completed by the initial guess of
        the plan's graph; None when it adds nothing to those values for g (already tried), or
        when it would complete a trajectory: a certified graph's values join `self.values`,
        where a trajectory means "solved", so `solve` would then skip the keyframes-first
        machinery for every later graph holding it (lab5 seed 8: three slices of 370-640
        factors solved jointly, 135 s, where their motions had been solved phase by phase)."""
        guess = self.graph.initial_guess
        missing = [v for v in g.variables if v not in self.values]
        if not missing or any(v not in guess or is_trajectory(v) for v in missing):
            return None
        return {**{v: guess[v] for v in missing}, **{v: self.values[v] for v in g.variables if v in self.values}}
