"""The trajectory phase of Appendix C: motions solved between fixed keyframes, phase by phase
(keyframes first, in `feasibility_check`; trajectories warm-started by interpolation), idle
motions held on their straight line, a failing motion joined with the keyframes, and the joint
re-solve of every motion when that fails. Never a verdict: a motion that fails between fixed
keyframes says nothing about the graph.
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING, Sequence

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.check_memory import CheckMemory
from gnppdsl.solve.deadline import TimeUp
from gnppdsl.solve.interpolation import keyframe_of, straight_line, via_line
from gnppdsl.solve.options import overridden
from gnppdsl.solve.plan_graph import bound_violation

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.feasibility import FeasibilityResult


MAX_JOINED_MOTIONS = 3
"""Motions solved together with the keyframes (`FeasibilityCheck.motions_between_keyframes`) before the
joint solve of every motion is tried instead."""


MOTION_MAX_ITER = 150
"""ipopt iterations per run of one phase's NLP between fixed keyframes (`solve_motion`). Why a
cap below the loop's 1000 (`SolveOptions.max_iter`): such a phase is never a verdict, and one that fails goes on to be
joined with its keyframes anyway. Measured (seed 0/1, CPU): the motions that were solved took
0-59 iterations (lab1_paper, lab3_paper, lab4_paper, work1); the ones that failed crept towards
a violation of 1e-5 without reaching the tolerance for 221-927 iterations (work1 seed 0, the
active set's repair of motion 2: 10.8 s with the idle arms fixed, then 4.2 s free, before
the joined solve found it in 4.8 s; capped: 2.1 s, then 3.7 s). It is also each
`solve_motion`'s budget for all its runs together (`SolverOptions.iteration_budget`): with
`kinematic_curvature` auto and the polish one call was up to three runs (work1 seed 1, motion 2
free: 150 + 150 + 150 iterations, 7.9 s, the last a repeat of the polish, now skipped); the
phase is then at most two calls (idle arms fixed, then free) of 150 iterations before it is
joined with its keyframes. Measured on work1 (seed 0/1), the motion-2 failure that the join
repairs: 630 / 683 iterations, 8.2 / 10.1 s CPU before the budget, 4.3 s on both seeds
with it (whole solve 28.3 -> 24.6 s and 28.7 -> 22.8 s, same NLPs and plans)."""


IDLE_MOTION = 1e-3
"""Largest keyframe change (per coordinate) of a trajectory that `motions_between_keyframes`
first tries with the straight line fixed (a waiting arm); if that phase fails it is solved
again with the trajectory free, so this is a speed setting, never a restriction."""


class GraphNLPView:
    """Helpers that build graph-NLPs the nlp layer reads, without changing its classes."""

    @staticmethod
    def with_variables(g: GraphNLP, replacements: dict[VarInstance, VarInstance]) -> GraphNLP:
        """A copy of g whose variable vertices are the given replacement objects (equal to the
        originals, e.g. with other bounds, which do not take part in equality): the solver
        reads bounds from the graph's vertices and maps factor slots to them by equality."""
        h = g.graph.relabelled({v: r for v, r in replacements.items() if v in g.graph})
        return type(g)(g.factors, h, g.name, g.initial_guess, g.restart_guess)


def _fixed(v: VarInstance, value: np.ndarray) -> VarInstance:
    """v with lower = upper bound = value: equal to v (bounds do not take part in equality),
    so it replaces v in a graph-NLP's vertex set for a solve with v held fixed."""
    x = tuple(float(t) for t in np.asarray(value, float).reshape(-1))
    return replace(v, lower=x, upper=x)


class TrajectoryPhase(CheckMemory):
    """The feasibility check's motions between keyframes (see the module docstring)."""

    def consistent_keyframes(self, modes: GraphNLP, r0: FeasibilityResult) -> None:
        """Make the keyframes in `self.values` a solution of `modes` (the mode switches of a
        graph about to get its motions) before the motions are fixed between them.

        `self.values` collects the latest solution of every variable, so the keyframes of a
        slice may come from different solves (Lab 5 seed 3: steps 0-6 from a joint solve of
        G[0..6] with its motions, steps 7-8 from the mode-switch graph's solve), which need not
        agree at the seam (0.17 on a `same` row there), and every motion across it then fails
        with its keyframes fixed. When they do not satisfy `modes`, its NLP is solved once from
        them (one start: it stays near the keyframes whose motions were found) and, if that
        fails, `r0`'s solution of `modes` is taken."""
        run = self.run
        point = {v: self.values[v] for v in modes.variables if v in self.values}
        if len(point) == len(modes.variables) and \
                run.violation(modes.factor_instances, point, modes.variables) <= run.options.tolerance:
            return
        r = self.local_solve(modes, point)
        self.values.update(r.values if r.feasible else
                           {v: x for v, x in r0.values.items() if v in modes.variables})

    def motions_between_keyframes(self, g: GraphNLP, trajs: Sequence[VarInstance], warm: dict,
                                  max_joined: int | None = None) -> FeasibilityResult | None:
        """The motions of g phase by phase with the keyframes fixed at the mode-switch solution:
        one small NLP per phase i, the time slice g[i..i+1] without other phases' motions, whose
        keyframe variables have lower = upper bound = their value. When every phase is solved,
        the union satisfies every factor of g (checked by `known_solution`, numpy) and is
        returned; else None, and the motions solved so far warm-start the joint solve of g.

        Why (measured on Lab 4 / Lab 5, two Panda arms, 20-waypoint motions): an ipopt
        iteration of the joint graph costs the sum of its phases, ~0.7 s with 6 phases and
        ~2.9 s with 10, and the joint solve iterates until the hardest motion converges (Lab 5:
        97 iterations, 281 s, not converged); with fixed keyframes the phases are independent
        and each takes only its own iterations.

        A phase that fails with its keyframes fixed joins the keyframes (`keyframes_with_motions`:
        the mode switches and that motion in one NLP, the keyframes free), and the other phases
        are solved again between the keyframes that NLP returns; up to MAX_JOINED_MOTIONS
        phases (`max_joined`, default MAX_JOINED_MOTIONS), then the joint solve of g. Never a verdict: a phase that fails here says
        nothing about g (the keyframes may have to move differently), so nothing here is
        stored as a result or becomes a conflict."""
        if any(v not in self.values for v in g.variables if not v.waypoints):
            return None
        fixed_values: dict = {}
        joined: list[int] = []
        while True:
            failed = self.phases_between_keyframes(g, trajs, warm, fixed_values, joined)
            if failed is None:
                break
            if len(joined) >= (MAX_JOINED_MOTIONS if max_joined is None else max_joined):
                self.run.say(f"  {g.name}: motion {failed} not found with fixed keyframes; "
                             "solving all motions jointly")
                warm.update(fixed_values)
                return None
            joined.append(failed)
            r = self.keyframes_with_motions(g, joined, {**warm, **fixed_values})
            if not r.feasible:
                self.run.say(f"  {g.name}: keyframes with motions {joined} failed "
                             f"(violation {r.max_violation:.2g}); solving all motions jointly")
                warm.update(fixed_values)
                return None
            self.values.update({v: x for v, x in r.values.items() if not v.waypoints})
            fixed_values.update({v: x for v, x in r.values.items() if v.waypoints})
        warm.update(fixed_values)
        if not fixed_values:
            return None
        point = {**self.values, **fixed_values}
        self.points = [point, *self.points][:self.max_points]
        known = self.known_solution(g)
        if known is not None:
            self.values.update(known.values)
        return known

    def phases_between_keyframes(self, g: GraphNLP, trajs: Sequence[VarInstance], warm: dict,
                                 fixed_values: dict, joined: Sequence[int]) -> int | None:
        """Solve each phase of g not in `joined` between its fixed keyframes (`self.values`),
        adding the motions to `fixed_values`; the first phase that fails, or None."""
        for i in sorted({v.step for v in trajs}):
            if i in joined:
                continue
            s = g.time_slice(i, i + 1)
            s = s.subgraph(variables=[v for v in s.variables if not (v.waypoints and v.step != i)],
                           suffix=f"{{motion {i}}}")
            frozen = {v: _fixed(v, self.values[v]) for v in s.variables if not v.waypoints}
            if not frozen or not any(v.waypoints for v in s.variables):
                continue
            r = None
            idle = self.idle_motions(s, i)
            detour = None
            for held in ([idle] if idle else []) + [{}]:
                r = self.solve_motion(s, frozen, held, warm, fixed_values)
                if r is not None and r.feasible:
                    break
                if r is not None and detour is None:
                    # once per phase: the straight line's failure may be its start (a hand
                    # through the table), not the keyframes
                    detour = self.detour_start(s, i, {**warm, **fixed_values, **held,
                                                      **{v: self.values[v] for v in frozen}})
                    if detour:
                        self.run.say(f"  {g.name}: motion {i} failed from the straight line; "
                                     f"again through keyframes of {sorted(v.key for v in detour)}")
                        r = self.solve_motion(s, frozen, held, {**warm, **detour}, fixed_values)
                        if r is not None and r.feasible:
                            break
            if not r.feasible:
                self.run.say(f"  {g.name}: motion {i} not found with fixed keyframes "
                             f"(violation {r.max_violation:.2g})")
                return i
            fixed_values.update({v: x for v, x in r.values.items() if v.waypoints})
        return None

    def keyframes_with_motions(self, g: GraphNLP, phases: Sequence[int], warm: dict) -> FeasibilityResult:
        """One NLP: g's mode switches with the motions of `phases`, every keyframe free (the
        subgraph of g induced by its keyframes and those trajectories), from one start.

        Why: a motion that fails between fixed keyframes usually needs its keyframes moved a
        little (Lab 5 seed 3: a detour 1.3e-2 over the velocity budget), and moving them moves
        the keyframes they are tied to (a held block's pose, the other arm's grasp) all along
        the plan, so the keyframes are solved together with that motion only. Its iteration
        costs the mode switches plus one motion, against every motion in the joint solve of
        g (Lab 5: 40-80 s for 8-10 phases)."""
        m = g.subgraph(variables=[v for v in g.variables if not v.waypoints or v.step in phases],
                       suffix="{keyframes+motions " + ",".join(map(str, phases)) + "}")
        start = {v: warm[v] for v in m.variables if v in warm}
        start.update({v: self.values[v] for v in m.variables if v in self.values and not v.waypoints})
        with overridden(self, screen=True):          # solved keyframes and one motion (`screening`)
            return self.local_solve(m, start)

    def idle_motions(self, s: GraphNLP, i: int) -> dict[VarInstance, np.ndarray]:
        """The trajectories of phase i whose keyframes at i and i+1 are equal up to IDLE_MOTION
        (an arm that does not move in this phase), each with the straight line between them as
        its fixed value.

        Why: with two arms, one usually waits while the other moves, and the waiting arm's
        20 waypoints carried as many collision rows as the moving one's (Lab 4: half of each
        phase's distance queries and Hessian blocks for a path whose straight-line start is
        already its solution)."""
        idle = {}
        for v, _, space, xa, xb in self.phase_ends(s, i):
            if np.max(np.abs(xa - xb), initial=0.0) <= IDLE_MOTION:
                # the straight line: its end points are exactly the keyframes, which the
                # solver moved by ~1e-8 although nothing asked the arm to move
                idle[v] = straight_line(xa, xb, v.waypoints, space)
        return idle

    def phase_ends(self, s: GraphNLP, i: int) -> list[tuple[VarInstance, str, str, np.ndarray, np.ndarray]]:
        """Phase i's trajectories of s whose keyframes at i and i+1 have values, each with its
        keyframes' key and space and their values at i and i+1 (flat, of the trajectory's point
        size), in s's order."""
        by = {(v.key, v.step): v for v in self.values if not v.waypoints}
        ends = []
        for v in s.variables:
            if not v.waypoints or v.step != i:
                continue
            key = keyframe_of(v, s.variables, [x for h in s.graph.neighbors(v) for x in s.graph.neighbors(h)])
            a, b = by.get((key, i)), by.get((key, i + 1))
            if a is None or b is None:
                continue
            xa = np.asarray(self.values[a], float).reshape(-1)
            xb = np.asarray(self.values[b], float).reshape(-1)
            if xa.size == v.point_dim:
                ends.append((v, key, a.space, xa, xb))
        return ends

    def detour_start(self, s: GraphNLP, i: int, start: dict) -> dict[VarInstance, np.ndarray]:
        """Starts of phase i's moving trajectories through another keyframe of the same
        variable (`via_line`), where that start's collision factors are violated by less than
        at `start` (their summed positive margins, numpy); {} when `start` breaks no collision
        factor or no such keyframe does better. Trajectories are chosen one after the other,
        each against the others' choices; among equal scores the shorter path.

        Why: the straight line between two keyframes can pass through an obstacle, and the
        phase NLP from it then stalls in collision. Work_5 seed 5, motion 8: arm_n carries b2
        from the stick's tip to pad_n, the straight line in joint space puts the hand 10 cm
        into the table; ipopt ended at violation 0.014 after 150 iterations, twice (idle arms
        held, then free), the keyframes joined with that motion failed too, and the plan went
        to the joint solve of every motion (86 s CPU for the seed). Through arm_n's home
        keyframe (summed penetration 0.19 -> 0.086 m) the same NLP is solved in 16 iterations
        (0.1 s). A keyframe of the plan is a configuration its factors accepted, which the
        home pose above the table typically is."""
        from gnppdsl.nlp.evaluate import factor_margins

        collision = [s.factor(ref) for ref in s.factor_refs if "collision" in s.factor(ref).tags]
        if not collision or any(v not in start for v in s.variables):
            return {}
        point = {v: start[v] for v in s.variables}
        geometry = self.run.compiled.geometry

        def score(pt: dict) -> float:
            try:
                margins = factor_margins(collision, pt, geometry)
            except Exception:
                return np.inf
            return float(sum(max(0.0, m) for m in margins if m == m)) + \
                (np.inf if any(m != m for m in margins) else 0.0)

        best_score = score(point)
        if not best_score > self.run.options.tolerance:
            return {}
        by = {(v.key, v.step): v for v in self.values if not v.waypoints}
        out: dict[VarInstance, np.ndarray] = {}
        for v, key, space, xa, xb in sorted(self.phase_ends(s, i), key=lambda e: e[0].key):
            if np.max(np.abs(xa - xb), initial=0.0) <= IDLE_MOTION:
                continue
            seen = {np.round(xa, 3).tobytes(), np.round(xb, 3).tobytes()}
            choice = None
            for (k, step), u in sorted(by.items(), key=lambda t: t[0][1]):
                xv = np.asarray(self.values[u], float).reshape(-1)
                if k != key or xv.size != xa.size or np.round(xv, 3).tobytes() in seen:
                    continue
                seen.add(np.round(xv, 3).tobytes())
                p = via_line(xa, xv, xb, v.waypoints, space)
                rank = (score({**point, v: p}), np.linalg.norm(xv - xa) + np.linalg.norm(xb - xv))
                if rank[0] < best_score - 1e-9 and (choice is None or rank < choice[0]):
                    choice = (rank, p)
            if choice is not None:
                best_score = choice[0][0]
                point[v] = out[v] = choice[1]
        return out

    def solve_motion(self, s: GraphNLP, frozen: dict, idle: dict, warm: dict, fixed_values: dict
                     ) -> FeasibilityResult | None:
        """One phase's NLP with its keyframes (`frozen`) and the `idle` trajectories fixed; the
        factors whose variables are then all fixed are checked once with numpy instead of
        being carried through every ipopt iteration, and so is the whole phase at its start
        (when the straight lines already clear everything, no NLP is built: measured on Lab 2,
        three of four phases, 0.2-0.8 s of assembly each for an ipopt run of 0 iterations).
        None when a fixed factor is violated (the caller solves the phase again with the idle
        trajectories free)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        run = self.run
        fixed = {**frozen, **{v: _fixed(v, x) for v, x in idle.items()}}
        start = {**warm, **fixed_values, **idle, **{v: self.values[v] for v in frozen}}
        m = s
        const = [ref for ref in s.factor_refs if all(u in fixed for u in s.graph.neighbors(ref))]
        if const and run.violation([s.factor(ref) for ref in const], start) <= run.options.tolerance:
            # the factors on fixed variables only (the keyframes' own factors, with the idle
            # trajectories' rows) hold: checked once here, not carried through every
            # iteration. Why also without idle trajectories: the active set's repair solves
            # each motion with its keyframes' factors (stack_16: 417-458 factors per motion,
            # ~40 of them on the motion), its first motion 9 s for 120 iterations
            dropped = set(const)
            m = s.subgraph(factors=[ref for ref in s.factor_refs if ref not in dropped],
                           suffix="{moving}")
        elif idle:
            return None
        margins = None
        if all(v in start for v in m.variables):
            point = {v: start[v] for v in m.variables}
            # per factor (signed), also what `screened_motion` selects the near collisions by
            margins = self._margins(m.factor_instances, point)
            worst = np.inf if margins is None else \
                max(max(margins, default=0.0), 0.0, bound_violation(m.variables, point))
            if worst <= run.options.tolerance:
                run.stats.reused_solutions += 1
                return FeasibilityResult(True, {**point, **idle}, {r: 0.0 for r in m.factor_refs}, worst,
                                         0.0, 0.0, 0, "its start satisfies it", 0)
        def solve(sub: GraphNLP, at: dict) -> FeasibilityResult:
            # a solver of its own: assembled NLPs are cached by vertex set, which ignores bounds
            solver = run.new_solver()
            solver.options.restarts, solver.options.polish = 0, True
            solver.options.max_iter = min(solver.options.max_iter, MOTION_MAX_ITER)
            solver.options.iteration_budget = MOTION_MAX_ITER      # for all its runs together
            solver.options.time_limit = max(0.05, run.remaining())
            r = solver.solve(GraphNLPView.with_variables(sub, {v: f for v, f in fixed.items() if v in sub}),
                             warm_start=at, seed=run.options.seed)
            run.nlp_calls += 1
            if time.perf_counter() >= run.deadline:
                raise TimeUp()
            return r

        # many collision factors (one per resting block): first with the near ones (`screening`)
        r = self.screened_motion(m, start, solve, margins)
        if r is None:
            r = solve(m, start)
        if r.feasible:
            r.values.update({v: x for v, x in idle.items() if v not in r.values})
        return r
