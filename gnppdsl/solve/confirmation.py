"""Confirming one-start verdicts: an infeasible verdict from one start (Alg. 1's lazy search, a
certificate, an inferred component) becomes a conflict only after the restarts it skipped
(`confirm`), or the restarts of the cheap graph it was decided at (`confirm_by_parent`); a range
the time search ends with gets a second opinion from its slices' solutions (`recheck`); confirmed
verdicts go into the subgraph database.
"""
from __future__ import annotations

import math
import time
from typing import TYPE_CHECKING

import numpy as np

from gnppdsl.conflicts.database import names_of
from gnppdsl.conflicts.mapping import to_partial_states
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.check_memory import CheckMemory
from gnppdsl.solve.deadline import TimeUp
from gnppdsl.solve.options import overridden

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.feasibility import FeasibilityResult


COLD_MAX_COST = 2000.0
"""`Confirmation.cold_refutes`: the largest ipopt iteration cost (`FeasibilitySolver.iteration_cost`,
plain rows) of a graph that gets a start from its initial guess before it becomes a conflict."""


class Confirmation(CheckMemory):
    """The feasibility check's confirmations of one-start verdicts (see the module docstring)."""

    def confirm(self, g: GraphNLP) -> bool:
        """Is the infeasible verdict on g final? A verdict from one start (Alg. 1's search runs
        `lazy`) gets the random restarts it skipped (the same NLP, not a new one), so a
        conflict is learnt from exactly the evidence it was before: every start infeasible.

        Why lazy: the restarts of every intermediate infeasible verdict of the time search and
        the convergence heuristic were two thirds of Lab 3's NLP time (3 starts of 60-110
        iterations each, ~1-4 s per subgraph), while only the subgraph that becomes the
        conflict needs them. False means a restart found g feasible: the one-start verdicts
        that led to it are suspect (the caller forgets them and searches again with restarts)."""
        key = g.signature()
        if key not in self.unconfirmed:
            return not self.cold_refutes(g)
        self.unconfirmed.discard(key)
        run = self.run
        parent = self.parent_of.get(key)
        if parent is not None:
            verdict = self.confirm_by_parent(g, parent)
            if verdict is not None:
                return verdict and not self.cold_refutes(g)
        if getattr(self.results.get(key), "starts", 1) == 0:
            # no ipopt run behind the verdict (certified, or inferred at a graph's x*): these
            # restarts are g's first solve, an NLP
            run.nlp_calls += 1
        opts = self.solver.options
        opts.time_limit = max(0.05, run.remaining())
        r = self.solver.solve(g, warm_start={v: self.values[v] for v in g.variables if v in self.values},
                              seed=run.options.seed, first_attempt=1)
        if r is not None and not r.feasible and (time.perf_counter() >= run.deadline
                                                 or "walltime" in str(r.status).lower()):
            raise TimeUp()
        if r is None or not r.feasible:
            if self.cold_refutes(g):
                return False
            self.remember_infeasible(g)
            return True
        self.results[key] = r
        self.values.update(r.values)
        return False

    def cold_refutes(self, g: GraphNLP) -> bool:
        """Is g, about to become a conflict, feasible from its own initial guess (the factory's
        start: objects where the plan's facts put them, arms at home), solved once with no
        warm start? Then the infeasible verdict came from the plan's earlier solutions, and g's
        result becomes that solution (the caller searches again). Only for graphs whose ipopt
        iteration costs at most COLD_MAX_COST plain rows (object-only levels; the Lab's
        keyframe graphs with arms cost 2300-13000), each once per plan, and only on a plan
        where a one-start verdict has already been overturned by a restart (`misled`, set by
        `forget_unconfirmed`): there the plan's solutions are known to mislead, elsewhere the
        start would be an NLP more per conflict (planar p5: one NLP per failed plan).

        Why: every start of a verdict but the random ones leans on the warm start, the first
        as it is, the odd restarts the initial guess moved by `restart_noise`. On a cluttered
        table with six obstacles (clutter_6 --seed 5 of examples/scalability/generate.py) the
        last state of a 24-step plan, five blocks on pads and six moved obstacles on the table
        (102 factors, no robot), failed from the warm start and both restarts, and became a
        17-fact conflict that lifting could not generalise (~60 s of the 75 s solve); from
        the initial guess it is feasible in 0.1 s."""
        key = g.signature()
        if not self.misled or key in self.cold_checked or self.solver.iteration_cost(g) > COLD_MAX_COST:
            return False
        self.cold_checked.add(key)
        run = self.run
        opts = self.solver.options
        opts.time_limit = max(0.05, run.remaining())
        with overridden(opts, restarts=0):
            r = self.solver.solve(g, seed=run.options.seed)
        run.nlp_calls += 1
        if r is None or not r.feasible:
            return False
        run.say(f"  {g.name}: feasible from its initial guess; searching again")
        run.stats.cold_refutations += 1
        self.results[key] = r
        self.values.update(r.values)
        return True

    def confirm_by_parent(self, g: GraphNLP, parent: GraphNLP) -> bool | None:
        """`confirm` for a g decided at the convergence point of a cheap `parent` (`certify`,
        `infer_components`): the parent's random restarts, each polished, are g's restarts
        when each decides g at its own convergence point: a certified subgraph is certified
        there again (each point a strict local minimum of g's NLP that violates it), a
        component is violated there (components share no variables: the parent's NLP is the
        sum of theirs, its local minima theirs). Evidence from as many starts as g's own solve.
        True: confirmed (the parent failed from every start too); False: the parent, so g, is
        feasible (now in the memo); None: a restart did not decide g, the parent is not cheap
        or had its restarts already (only its best point is known): g needs its own. Why the
        parent's and not g's: the parent's NLP is cheap and already counted, so a failed plan
        costs one NLP, as in One-way, with a conflict smaller than the plan."""
        pkey = parent.signature()
        if pkey not in self.unconfirmed or not self.cheap(parent):
            return None
        from gnppdsl.nlp.certificate import certify_infeasible

        component = g.signature() in self.components
        run, opts, tol = self.run, self.solver.options, self.run.options.tolerance
        warm = {v: self.values[v] for v in parent.variables if v in self.values}
        for k in range(1, max(0, opts.restarts) + 1):
            opts.time_limit = max(0.05, run.remaining())
            with overridden(opts, restarts=k, final_polish_below=math.inf):
                r = self.solver.solve(parent, warm_start=warm, seed=run.options.seed, first_attempt=k)
            if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
                raise TimeUp()
            if r.feasible:
                self.unconfirmed.discard(pkey)
                self.results[pkey] = r
                self.values.update(r.values)
                return False
            if component:
                if not max(r.violations.get(ref, np.inf) for ref in g.factor_refs) > tol:
                    return None
            elif certify_infeasible(self.solver, g, r, parent) is None:
                return None
        self.unconfirmed.discard(pkey)    # the parent failed from every start as well
        self.remember_infeasible(g)
        return True

    def remember_infeasible(self, g: GraphNLP) -> None:
        """A confirmed infeasible g into the database (skipped while unconfirmed)."""
        run = self.run
        if self.use_db and run.db is not None:
            try:
                run.db.add(g, False, names_of(run.task, to_partial_states(g)))
            except ValueError:
                run.db.add(g, False, None)

    def forget_unconfirmed(self) -> None:
        """Drop every one-start infeasible verdict (after one of them proved wrong), and the
        certificates drawn from them. The plan's warm starts are then known to mislead
        (`misled`: conflicts get a start from their initial guess, `cold_refutes`)."""
        self.misled = True
        for key in self.unconfirmed:
            self.results.pop(key, None)
            self.parent_of.pop(key, None)
        self.parents = [p for p in self.parents if p[1].signature() not in self.unconfirmed]
        self.unconfirmed.clear()

    def recheck(self, g: GraphNLP) -> FeasibilityResult:
        """Second opinion on an infeasible g whose large strict time slices are feasible (see
        `find_infeasible_subgraph`): forget its verdict and solve it again, now warm-started
        from every value known in this plan (the slices' solutions among them), from that one
        start: g's verdict had its restarts, or gets them from `confirm` if it becomes the
        conflict (`lazy_large`), and a failed second opinion of a 5-step Lab slice costs 2-5 s
        this way, 10-40 s with restarts. A feasible answer is a real solution (re-evaluated by
        the solver's verdict); an infeasible one stands as before."""
        key = g.signature()
        old = self.results.pop(key, None)
        self.run.say(f"  {g.name}: infeasible, but its slices without the first or the last step are "
                     f"feasible; solving it again from their solutions")
        with overridden(self.solver.options, restarts=0):
            r = self.solve(g)
        if not r.feasible and old is not None:
            self.results[key] = old
            return old
        return r
