"""Evaluating one graph-NLP: the feasibility check that Algorithm 1 (paper 000) calls for the
subgraphs of one plan's graph. It answers from the subgraph database (switch g) or without an
NLP when it can (`inferred_verdicts`), solves the keyframes before the motions (Appendix C,
`motions`), warm-starts every NLP from the plan's earlier solutions, keeps one-start verdicts
unconfirmed until they become a conflict (`confirmation`), counts NLPs and enforces the deadline.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.conflicts.database import names_of
from gnppdsl.conflicts.mapping import to_partial_states
from gnppdsl.ir.expr import Slot
from gnppdsl.nlp.graph import Graph, GraphNLP, connected_components
from gnppdsl.solve.confirmation import Confirmation
from gnppdsl.solve.deadline import TimeUp
from gnppdsl.solve.inferred_verdicts import InferredVerdicts
from gnppdsl.solve.interpolation import interpolate_trajectories
from gnppdsl.solve.motions import TrajectoryPhase
from gnppdsl.solve.screening import CollisionScreen
from gnppdsl.solve.options import overridden
from gnppdsl.solve.plan_graph import TRAJ, is_trajectory

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.feasibility import FeasibilityResult


# a one-start verdict (the plan's graph, a level warm-starting it) is polished after its start
# only when it ends closer to feasible than this; farther points are polished by `confirm`
LOCAL_POLISH_BELOW = 1e-2


# graphs whose ipopt iteration costs at most this (`FeasibilitySolver.iteration_cost`, in plain
# rows) keep the polish of their one-start verdicts and certify their subgraphs: see `FeasibilityCheck.certify`
CERTIFY_MAX_COST = 500.0


LAZY_MAX_FACTORS = 40
"""Small and large subgraphs of Alg. 1's search (factors). Small ones are solved from one start
only with `lazy_search`: on Lab 3 (subgraphs of at most 26 factors) no one-start verdict was
ever overturned by the restarts. Large ones are solved from one start with `lazy_large`
(default): their restarts (random points, the initial guess) cost 10-20 s each on Lab 5 and
seldom succeed where the warm start failed, and the range the time search ends with gets a
second opinion from its sub-slices' solutions instead (`recheck`, given to ranges above this
size; session 7 without that second opinion: trusting one start on a 123-factor slice sent
the search to another conflict, seed 0: 28 NLPs and 157 s instead of 24 NLPs and 37 s)."""


class FeasibilityCheck(CollisionScreen, TrajectoryPhase, Confirmation, InferredVerdicts):
    """The feasibility check handed to Algorithm 1 for one plan's graph-NLP.

    - switch g: answer from the database of solved subgraphs when it knows (no NLP);
    - graphs with trajectories: solve their mode switches first, warm start the trajectories
      by interpolation, then solve everything jointly;
    - count NLPs, remember feasible values for warm starts, enforce the deadline.
    """

    def solve(self, g: GraphNLP) -> FeasibilityResult:
        run = self.run
        if time.perf_counter() >= run.deadline:
            raise TimeUp()
        key = g.signature()
        if key in self.results and not self.overturned(key):
            return self.results[key]
        known = self.known_solution(g)
        if known is not None:
            self.results[key] = known
            self.values.update(known.values)      # a solution like any other: warm starts
            return known
        trajs = [v for v in g.variables if is_trajectory(v)]
        if self.lazy and not trajs and run.options.certify:
            certified = self.certify(g)
            if certified is not None:
                return certified
        warm = self.warm_start(g)
        if self.closest_point is not None and not trajs:
            # an earlier convergence point that nearly satisfies g (CLOSE_START), and better
            # than the earlier solutions (with the initial guess) do, is the better start:
            # typically x* of a graph g is a slice of, whose solve stopped with small residuals
            # on g's factors while the contradiction lies elsewhere. Not a point that violates
            # g more: that is the local minimum g's solve should get a second chance to avoid
            # (Lab 1: the keyframes stalled at 2e-2 on a grasp, and their time slice started
            # there failed again; it failed from the warm start too, and only the restart from
            # the initial guess, `FeasibilitySolver._perturbed`, avoided the false conflict)
            warm.update(self.closest_point)
        if trajs and any(v not in self.values for v in trajs):
            modes = g.apply_relaxation({TRAJ}, "modes")
            if modes.n_factors:
                # the keyframes first: every factor at the mode switches (a relaxation of g),
                # also when relaxations already gave them values (they may lack collisions).
                # For the plan's own graph (not a subgraph Alg. 1 checks): one run from the
                # warm start, no random restarts. An infeasible verdict here only
                # starts the conflict search, whose subgraphs are solved with restarts (and a
                # whole multi-step component gets a second opinion), so it never becomes a
                # conflict by itself; random restarts of a 10-step Lab graph cost 100+ s.
                # The final polish of a point far from feasible is skipped there too (`local_solve`).
                local = {"restarts": 0, **self.far_polish(modes)} if key == self.graph.signature() else {}
                one_start = bool(local) and self.solver.options.restarts > 0 \
                    and modes.signature() not in self.results
                # never lazy: g takes this verdict as its own, and g's key is not marked
                # unconfirmed (`confirm` would pass a one-start verdict on)
                # (screened only above SCREEN_KEYFRAMES_MIN collision factors, `screening`: on
                # clutter_4 the screened keyframes of its last plan led to 2351 active-set pairs
                # instead of 1670 and 264 s CPU against 103; stack_32's whole NLP gave no verdict)
                with overridden(self.solver.options, **local), \
                        overridden(self, lazy=False, lazy_large=False,
                                   screen=self.screen or (bool(local) and self.huge(modes))):
                    r0 = self.solve(modes)
                if one_start and not r0.feasible and r0.starts > 0:
                    # ... but the verdict of `local`'s one start is unconfirmed: the search can
                    # return the mode-switch graph itself (a relaxation level with its factors,
                    # e.g. no_time_traj where no factor is tagged `time`, or its only component),
                    # and `confirm` must then give it the restarts it skipped. Without this, a
                    # one-start keyframe verdict became a conflict with no restart at all
                    # (sort_random with a 74-degree object: the base stalled south of the table,
                    # 1 cm short of a grasp that the west and north sides allow)
                    self.unconfirmed.add(modes.signature())
                if not r0.feasible:
                    self.results[key] = r0
                    self.derived[key] = modes.signature()
                    if modes.signature() in self.unconfirmed:
                        self.unconfirmed.add(key)      # as final as the relaxation's verdict
                    return r0          # a relaxation is infeasible, so g is (Property 4.4)
                self.consistent_keyframes(modes, r0)
            warm.update(self.warm_start(g))
            todo = [v for v in trajs if v not in self.values]
            if run.reach:
                for v in list(todo):
                    pts = run.reach_warmstart(v, self.values)
                    if pts is not None:
                        warm[v] = pts
                        todo.remove(v)
            warm.update(interpolate_trajectories(
                todo, self.values,
                lambda v: [x for h in self.graph.graph.neighbors(v) for x in self.graph.graph.neighbors(h)]))
            if modes.n_factors and len({v.step for v in trajs}) > 1:
                known = self.motions_between_keyframes(g, trajs, warm)
                if known is not None:
                    self.results[key] = known
                    return known
        r = None
        if self.local_first and self.solver.options.restarts > 0:
            r = self.local_solve(g, warm)
            if not r.feasible:
                # a one-start verdict (`confirm`): Alg. 1 goes on to search g's slices, each
                # solved with restarts, and only if the subgraph it returns carries this verdict
                # does that get the restarts. Why not the restarts now: g is a whole relaxation
                # level, the largest NLP of the search (Lab 5: 130 factors over 8 steps, 3
                # starts 8-9 s) and its slices find the conflict anyway (0.4-1 s each).
                self.unconfirmed.add(key)
        if r is None:
            # many collision factors: first with only the near ones (a feasible result only
            # when numpy finds every factor of g holds; else g is solved whole, below)
            r = self.screened(g, warm)
        if r is None:
            # ipopt's wall-time limit is fixed when a graph's NLP is assembled: give it what is left
            opts = self.solver.options
            opts.time_limit = max(0.05, run.remaining())
            lazy = self.lazy if g.n_factors <= LAZY_MAX_FACTORS else self.lazy_large
            # a one-start verdict: no restarts, and the polish of a point far from feasible
            # left to `confirm` too (as for the plan's own graph, `local_solve`)
            one_start = {"restarts": 0, **self.far_polish(g)}
            with overridden(opts, **(one_start if lazy else {})):
                r = self.solver.solve(g, warm_start=warm, seed=run.options.seed)
            run.nlp_calls += 1
            if lazy and not r.feasible and opts.restarts > 0:
                self.unconfirmed.add(key)
        if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
            # cut short by the time limit: not a verdict (never a conflict, never stored)
            raise TimeUp()
        self.results[key] = r
        if r.feasible:
            self.values.update(r.values)
        else:
            # an infeasible graph's convergence point x* may still satisfy a relaxation or a
            # subgraph of it (e.g. everything but the collision factors)
            self.points = [r.values, *self.points][:self.max_points]
            self.infer_components(g, r)
            if r.duals is not None and run.options.certify and self.cheap(g):
                self.parents = [(frozenset(g.factor_refs), g, r), *self.parents][:self.max_points]
        return r

    def cheap(self, g: GraphNLP) -> bool:
        """Does an ipopt iteration on g cost at most CERTIFY_MAX_COST plain rows? (Planar plans:
        44-119; Lab mode-switch graphs: 2300-13000, their distance rows weighted.)"""
        return self.solver.iteration_cost(g) <= CERTIFY_MAX_COST

    def far_polish(self, g: GraphNLP) -> dict:
        """Solver options of a one-start verdict on g: the final polish of a point far from
        feasible is left to `confirm` (LOCAL_POLISH_BELOW), unless g is cheap. Why keep it
        there: the polish (the pull 1e-4 weaker) leaves multipliers only on the rows of the
        contradiction, which is what lets `certify` decide g's subgraphs without solving them
        (planar p5: ~1e-8 outside the support after it, ~4e-3 before)."""
        return {} if self.run.options.certify and self.cheap(g) else {"final_polish_below": LOCAL_POLISH_BELOW}

    def warm_start(self, g: GraphNLP) -> dict:
        """The start of g's NLP from this plan's earlier solutions (`self.values`), made
        consistent along g's equality factors (`a == b` between two variables, e.g. an object's
        pose while its parent stays): in each chain of them, the variables set by an earlier
        solve than the newest one take its value. (Values of one solve are left as they are:
        a relaxation without the equalities may hold different values along a chain, and its
        own values are the better start there: Lab 4, 2.2 against 4.2 s for its keyframes.)

        Why: `self.values` holds the latest solution of every variable, so consecutive steps
        can come from different solves, and where an equality crosses that seam the two values
        may be far apart. Lab 5 seed 2: a held block's relative pose at step 2 came from a
        subgraph's solution, at step 3 from a relaxation's, 180 degrees apart about its
        symmetry axis (both grasps valid); every slice across the seam then stopped at that
        local minimum (1.4 on the `same` row) until a random restart, 6 NLPs and 13 s. The
        chain takes the newest value: it comes from the graph solved last, which carried the
        most of the plan's factors that matter now."""
        warm = {v: self.values[v] for v in g.variables if v in self.values}
        chains = Graph()
        for ref in g.factor_refs:
            pair = equality_pair(g.factor(ref))
            if pair is not None and all(v in warm for v in pair):
                chains.add_edge(*pair)
        for chain in connected_components(chains):
            newest = max(chain, key=lambda v: (self.values.stamp[v], -v.step))
            for v in chain:
                if self.values.stamp[v] < self.values.stamp[newest]:
                    warm[v] = self.values[newest]
        return warm

    def overturned(self, key: frozenset) -> bool:
        """Was the cached verdict of this graph its mode-switch graph's infeasible one, which a
        later solve has turned to feasible (the search's second opinion, a restart of
        `confirm`, the union of its components)? Then the verdict is dropped and the graph is
        solved again. Why: Lab 5 seed 3, the plan's keyframes failed one start, Alg. 1 found
        the mode-switch level feasible, and the full graph, still holding the keyframes'
        verdict, was searched slice by slice with its motions (590-factor joint solves of
        40-80 s each, time-out), where the keyframes now known needed only its motions."""
        modes = self.derived.get(key)
        if modes is None or not getattr(self.results.get(modes), "feasible", False):
            return False
        del self.derived[key]
        self.results.pop(key, None)
        self.unconfirmed.discard(key)
        return True

    def local_solve(self, g: GraphNLP, warm: dict) -> FeasibilityResult:
        """The warm start and the polish, without random restarts: a feasible result, or an
        infeasible verdict from one start (the caller marks it unconfirmed, see `confirm`).

        Why: a level solved to warm-start the full graph should end near its start. The
        solver's random restarts come before its polish, so a first run that stops at a tiny
        residual (Lab 1, no_col_traj: 2.7e-5 on a placement row) was restarted from a random
        point and came back with a feasible but far-off configuration, from which the motions
        of the full graph did not converge; the polish alone solves it near the start.
        (Also the one-start solve of `consistent_keyframes` and `keyframes_with_motions`.)
        A run cut short by the time limit raises TimeUp: it is no verdict."""
        run = self.run
        opts = self.solver.options
        # On the plan's graph the final polish of a point far from feasible is left to
        # `confirm` too: it is a second run of the largest NLP of the plan (Lab 5: 77
        # iterations, 5 s on a 10-step mode-switch graph ending at 2.6e-2) that does not turn
        # such a verdict; a stall closer than LOCAL_POLISH_BELOW is still polished (Lab 2's
        # keyframes stall at 1.6e-3 and the polish solves them). The small levels solved
        # before it keep their polish: it is cheap, and their convergence point shapes the
        # conflict search (Lab 4: two more NLPs without it).
        with overridden(self, screen=self.screen or self.plan_level(g)):
            screened = self.screened(g, warm)      # verified on every factor, or None
        if screened is not None:
            return screened
        polish = self.far_polish(g) if g.signature() == self.graph.signature() else {}
        opts.time_limit = max(0.05, run.remaining())
        with overridden(opts, restarts=0, **polish):
            r = self.solver.solve(g, warm_start=warm, seed=run.options.seed)
        run.nlp_calls += 1
        if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
            raise TimeUp()
        return r

    def __call__(self, g: GraphNLP) -> bool | FeasibilityResult:
        run = self.run
        if self.use_db and run.db is not None:
            # its semantic graph built at most once, for the lookup and the record added after
            # the solve, and only when a record could match it (`lazy_database`)
            verdict = run.db.lookup(g)
            if verdict is not None:
                if verdict:
                    run.stats.db_feasible_hits += 1
                else:
                    run.stats.db_infeasible_hits += 1
                return verdict
        r = self.solve(g)
        if self.use_db and run.db is not None and (r.feasible or g.signature() not in self.unconfirmed):
            conflict = None
            if not r.feasible:
                try:
                    conflict = names_of(run.task, to_partial_states(g))
                except ValueError:
                    conflict = None
            run.db.add(g, r.feasible, conflict)
        return r


def equality_pair(f: FactorInstance) -> tuple[VarInstance, VarInstance] | None:
    """The two variables of a factor whose only constraint is `x0 == x1` between its two
    variables of the same kind of space (e.g. `same(pose(o), pose(o)')`), else None."""
    if len(f.variables) != 2 or len(f.body) != 1:
        return None
    c, (a, b) = f.body[0], f.variables
    if c.op != "==" or {c.lhs, c.rhs} != {Slot(0), Slot(1)} or (a.space, a.dim) != (b.space, b.dim):
        return None
    return a, b
