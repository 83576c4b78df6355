"""Collision screening of a large graph-NLP: solve it with only the collision factors that are
near at its start, re-check every factor with numpy, add the ones that came near, repeat.

Why: on the scalability families the collision factors at keyframes grow with the square of
the objects (`apart`: every pair of blocks at every step; `arm_object`: six link rows per arm,
block and step). stack_16's mode-switch graph has 3386 factors, 2590 of them collisions;
stack_32's about four times as many apart pairs. An ipopt iteration evaluates every distance
row and its derivatives, yet at a start that already solves the plan without collisions (the
relaxation level no_col_traj, which `order = staged` solves first) nearly all of those pairs
are centimetres to metres apart: blocks resting in their rows, an arm reaching one of them.
Measured (before this module): stack_32's keyframe NLP from no_col_traj's solution ran > 80 s
CPU without a verdict, the 32-action plan's whole budget; stack_16's repair joined motion 4
with its keyframes in one NLP of 3438 factors, 21 s.

Soundness: a feasible verdict comes only from the numpy evaluator on every factor and bound
of the whole graph at the returned point (`Run.violation`, as `known_solution`). A screened
NLP that fails is no verdict: the caller goes on to solve the whole graph as before (so an
infeasible verdict, and a conflict, still come from the full NLP and Algorithm 1's machinery;
the screened graph is a relaxation of it, but its one failed start proves nothing here).
"""
from __future__ import annotations

import time
from dataclasses import replace
from typing import TYPE_CHECKING

from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.check_memory import CheckMemory
from gnppdsl.solve.deadline import TimeUp
from gnppdsl.solve.options import overridden
from gnppdsl.solve.plan_graph import TRAJ, bound_violation, is_trajectory

if TYPE_CHECKING:  # pragma: no cover  (casadi)
    from gnppdsl.nlp.feasibility import FeasibilityResult


SCREEN_MIN_FACTORS = 200
"""Collision factors a graph needs before it is screened: below this an ipopt iteration is
cheap and a second NLP (a screened one that misses) costs more than it saves (the planar
problems have 17-120 factors in all)."""

SCREEN_DISTANCE = 0.05
"""A collision factor joins the screened NLP when one of its rows is within this of active
(h > -SCREEN_DISTANCE, metres for distance rows) at the start or at a round's solution. Why 5
cm: a warm-started keyframe NLP moves an arm by a few centimetres; pairs farther than that
stay out, those that do come near are caught by the next round's re-check."""

SCREEN_KEEP_FRACTION = 0.5
"""Screening is skipped when more than this fraction of the collision factors is near at the
start (nothing much to leave out: the whole NLP is solved at once)."""

SCREEN_ROUNDS = 4
"""Screened NLPs per graph before the whole graph is solved instead."""

SCREEN_KEYFRAMES_MIN = SCREEN_MIN_FACTORS
"""Collision factors of a plan's own mode-switch graph (its keyframes, solved after the
relaxations) above which it is screened too: since issue 24's Field rows (29 Nov, helper
fieldproof) as low as any screened graph. Field_3's last plan (8 steps, two arms, three objects)
has 248 collision factors of 338; solved whole from no_col_traj's point its keyframes took 52
iterations, 6.0 s CPU (a third of the seed-1 solve, 0.1 s per iteration), screened (10 of 248
near, one round) 14 iterations, 0.4 s, and every factor holds (numpy); Field_4's 302: 15 near.
The Lab's and Workshop's rows measured side by side: unchanged (their keyframes are reused or
solved by other paths). The history of the larger threshold follows. (A session before,
clutter_4, 1665 pairs: screened keyframes led to more active-set pairs and 264 s CPU against
103; see below). stack_32's has 18356
(stack_16: 2588, the Lab problems a few hundred): solved whole, its NLP ran > 100 s CPU
without a verdict (21354 factors); screened, 1308 of them are near at the relaxation's point.
clutter_6's last plan has 2897 (3652 factors): solved whole from the relaxations' point it
failed its one start (156 iterations, 46 s CPU), and Alg. 1 then searched the no_traj level
slice by slice until every component proved feasible (~120 s CPU more, a 22-step slice alone
failing 253 iterations, 46 s); screened (173 of 2897 near) it is solved in 14 iterations,
0.9 s, and every factor holds (numpy). Hence 2500, not 5000 (clutter_6 230 -> 113 s CPU;
clutter_4 and stack_16 below it, unchanged).

Then 1000 (clutter_4's 1665 screened too), once the relaxation levels before the full graph
are screened (`plan_level`): from the screened no_robot_time_traj level's point clutter_4's
last keyframes took 363 iterations solved whole (84.5 s CPU; 197 iterations, 26.7 s from the
whole level's point), screened (118 of 1665 near, 3 rounds) 14.5 s. The active set then adds
more pairs (218 against 154, the repair 9.8 s against 2.0), but the solve is shorter: clutter_4
83.6 -> 67.0 s CPU (base, level screening alone 122.3); stack_16 24.2 -> 24.6, Lab 1 and Lab 4
(a few hundred) unchanged."""


SCREEN_DEEP = 0.03
"""A screened graph (not a relaxation level) whose start has a collision row this deep (metres:
the largest signed margin of its collision factors, a penetration depth for distance rows) is
solved with the distance rows' curvature first and linearised second (`screened_solve`), the
order a solve otherwise takes only after the exact Hessian has rescued one screened NLP
(`Run.screen_curved`). Why (issue 19): stack_32's keyframes start with a hand 2.65 cm and a
finger 1.1 cm inside the tower built one step before (row 0.0365); linearised, ipopt stalled
there (60 iterations, 11.6 s CPU, failed) before the exact Hessian solved them (105 iterations,
42.8 s), every solve. clutter_6's keyframes start at most 2.24 cm deep and are solved
linearised (59 iterations, 1.8 s, two rounds); its relaxation levels (up to 5.9 cm) keep their
one linearised run (`plan_level`). Either order tries the same two runs from the same point,
and neither failure is a verdict: the threshold only orders them."""


MOTION_SCREEN_MIN = 8
"""Collision factors of one phase's motion NLP between fixed keyframes (`solve_motion`) from
which it is screened too (each factor is a whole motion's rows against one body: `path_clear`
is 6 distance rows at each of 18 waypoints). stack_16's motions have 18-36 (a `path_clear`
per resting block and the table, a `carry_clear` per block when carrying), of which the
interpolated start comes within SCREEN_DISTANCE of 2-6; a problem with a few objects has fewer
than this and is not screened.

8, not 16 (issue 19): clutter_6's arm reaching for a block has 14 (a `path_clear` per resting
object, the table, `paths_apart`) and was solved whole in 25-65 ipopt iterations (0.5-2.3 s
CPU each, 6.3 s for the 8 such motions of its last plan); screened, 1-17. clutter_6 68.9 ->
62.7 s CPU (motions 12.2 -> 7.8 s, same plan); clutter_4 (10 per motion) 67.0 -> 70.6: its
motions 9.6 -> 5.0 s, but the active set then needed a third round (235 pairs against 220);
lab4_paper 11.5 -> 10.7 s (41 NLPs against 42), lab1_paper unchanged (19 NLPs)."""


class CollisionScreen(CheckMemory):
    """`screened`: the feasibility check's collision screening (see the module docstring).

    Only where the caller sets `screen` (with `overridden`): the keyframes joined with a motion
    (`keyframes_with_motions`) and the active set's repair of a round with few pairs
    (`coverage`) -- starts that solve all but (some of) the collisions -- a plan's own
    keyframes after its relaxations when they are `huge` (SCREEN_KEYFRAMES_MIN), and the
    relaxation levels without trajectories solved before the full graph (`plan_level`). Not
    keyframes below SCREEN_KEYFRAMES_MIN: on clutter_4 that run took 264 s CPU against 103 (its
    last plan's screened keyframes led to 2351 active-set pairs instead of 1670). Why not every graph: Algorithm 1's slices are
    solved to find a conflict, mostly infeasible, where a screened NLP only adds a failed run
    and moves the convergence points the search goes on from (clutter_4 with every graph
    screened: a screened no_robot_time_traj level of the first, infeasible plan failed and
    was solved whole; the solve took longer than without screening)."""

    screen = False                       # set around the solves that may be screened

    def plan_level(self, g: GraphNLP) -> bool:
        """Is g a relaxation level of the plan's graph without trajectories that `evaluate`
        solves once before the full graph (`local_first`), other than its mode-switch graph
        (screened only when `huge`)? Such a level is screened (`local_solve`).

        Why: clutter_6's last plan (24 steps, 6 obstacles set down beside the pads) has a
        no_robot_time_traj level of 2418 factors, 1986 of them `apart` pairs; from
        no_col_traj's point (obstacles set down overlapping blocks, 138 rows violated) the
        whole NLP stalled at 1.9e-6 after 300 iterations (15.5 s CPU), its components were
        then searched and joined (~1 s). Screened (149 of 1986 near) it is solved in one NLP of
        236 iterations, 2.7 s, and numpy finds every factor of the level holds. A level that
        is infeasible costs one more NLP of the screened size before its whole solve (which
        gives the verdict, as before)."""
        if not self.local_first or any(is_trajectory(v) for v in g.variables):
            return False
        key = g.signature()
        if key == self.graph.signature():
            return False
        modes = getattr(self, "_modes_key", None)
        if modes is None:
            modes = self._modes_key = self.graph.apply_relaxation({TRAJ}, "modes").signature()
        return key != modes

    @staticmethod
    def huge(g: GraphNLP) -> bool:
        """Has g at least SCREEN_KEYFRAMES_MIN collision factors (a plan's own keyframes that
        are screened, `FeasibilityCheck.solve`)?"""
        n = 0
        for r in g.factor_refs:
            n += "collision" in g.factor(r).tags
            if n >= SCREEN_KEYFRAMES_MIN:
                return True
        return False

    def screened(self, g: GraphNLP, warm: dict) -> FeasibilityResult | None:
        """A feasible result of g from NLPs with only its near collision factors, verified on
        every factor of g with numpy; None when screening does not apply or does not succeed
        (no verdict: the caller solves g whole). One start per NLP (no restarts), warm-started
        from `warm` (completed by the initial guess) and then from each round's solution."""
        run = self.run
        if not (self.screen and run.options.screen_collisions):
            return None
        collision = [r for r in g.factor_refs if "collision" in g.factor(r).tags]
        if len(collision) < SCREEN_MIN_FACTORS:
            return None
        guess = g.initial_guess or {}
        point = {v: warm[v] if v in warm else guess.get(v) for v in g.variables}
        if any(x is None for x in point.values()):
            return None

        # a relaxation level (`plan_level`) gets one screened run: its whole solve follows a
        # failure anyway, and a level that fails screened is mostly an infeasible plan's
        # (clutter_6's first plan: linearised 0.75 s, then curved 1.6 s, both failed, before
        # its whole solve gave the verdict); the second try is for the keyframes (stack_32)
        level = self.plan_level(g)
        instances = [g.factor(r) for r in g.factor_refs]
        margins = self._margins(instances, point)
        if margins is None:
            return None
        is_collision = set(collision)
        depth = max((m for r, m in zip(g.factor_refs, margins) if r in is_collision), default=0.0)
        # a start this deep in collision (not a level): the exact Hessian first (SCREEN_DEEP)
        deep = not level and depth >= SCREEN_DEEP

        def solve(sub: GraphNLP, at: dict) -> FeasibilityResult:
            if self.solver.options.distance_curvature:
                return self.screened_solve(sub, at)
            # linearised distance rows first, the exact Hessian second (`screened_solve`); once
            # the exact one has rescued a screened NLP of this solve, or when the start is
            # SCREEN_DEEP in collision, the other way round
            first = run.screen_curved or deep
            r = self.screened_solve(sub, at, distance_curvature=first)
            if not r.feasible and not level:
                run.stats.screened_solves += 1
                second = self.screened_solve(sub, at, distance_curvature=not first)
                run.screen_curved |= second.feasible and not first
                r = replace(second, iterations=r.iterations + second.iterations,
                            starts=r.starts + second.starts)
            return r

        return self.screen_rounds(g, point, collision, solve, margins)

    def screened_motion(self, m: GraphNLP, start: dict, solve, margins: list | None = None
                        ) -> FeasibilityResult | None:
        """`screen_rounds` for one phase's motion NLP m between fixed keyframes
        (`TrajectoryPhase.solve_motion`; `solve(sub, start)` runs the caller's solver with the
        keyframes held) when it has MOTION_SCREEN_MIN collision factors or more; None when it
        does not apply or does not succeed (the caller solves m whole). `margins`: the factors'
        margins at the start when the caller has them (its check of the start).

        Why: each motion carries a `path_clear` of its arm against every resting block, and
        an ipopt iteration evaluates all of them (stack_32: a moving arm took 65-70 ipopt
        iterations over ~3500 distance rows), where the interpolated start passes within
        SCREEN_DISTANCE of a handful of blocks (stack_16: 4-16 iterations screened). A motion is never a
        verdict, and its answer is accepted only after numpy checks every factor of m."""
        if not self.run.options.screen_collisions:
            return None
        collision = [r for r in m.factor_refs if "collision" in m.factor(r).tags]
        if len(collision) < MOTION_SCREEN_MIN or any(v not in start for v in m.variables):
            return None
        return self.screen_rounds(m, {v: start[v] for v in m.variables}, collision, solve, margins)

    def screen_rounds(self, g: GraphNLP, point: dict, collision: list, solve,
                      margins: list | None = None) -> FeasibilityResult | None:
        """The rounds of `screened` on g from `point` (a value for every variable of g), given
        its collision factors: `solve(sub, start)` solves a subgraph of g with the collision
        factors near so far (one NLP, or a second try); a result is returned only when numpy
        finds every factor and bound of g holds at its point. None: screening leaves out too
        little, a screened NLP failed, or the rounds ran out (no verdict)."""
        from gnppdsl.nlp.feasibility import FeasibilityResult

        run = self.run
        refs = g.factor_refs
        is_collision = set(collision)
        t0 = time.perf_counter()
        tol = run.options.tolerance
        point = dict(point)
        instances = [g.factor(r) for r in refs]
        if margins is None:       # else given by the caller, at this point, in the order of refs
            margins = self._margins(instances, point)
        if margins is None:
            return None
        near = {r for r, m in zip(refs, margins) if r in is_collision and m > -SCREEN_DISTANCE}
        if len(near) > SCREEN_KEEP_FRACTION * len(collision):
            return None
        others = [r for r in refs if r not in is_collision]
        iters = starts = 0
        for round_ in range(SCREEN_ROUNDS):
            sub = g.subgraph(variables=g.variables, factors=[*others, *sorted(near)],
                             suffix=f"{{screened {len(near)}/{len(collision)}}}")
            r = solve(sub, point)
            iters += r.iterations
            starts += r.starts
            run.stats.screened_solves += 1
            run.stats.screened_dropped += len(collision) - len(near)
            if not r.feasible:
                run.say(f"  {g.name}: screened NLP ({len(near)} of {len(collision)} collision factors) "
                        f"failed (violation {r.max_violation:.2g}); solving it whole")
                return None
            point.update({v: x for v, x in r.values.items() if v in point})
            margins = self._margins(instances, point)
            if margins is None:
                return None
            worst = max(max(margins, default=0.0), 0.0)
            worst = max(worst, bound_violation(g.variables, point))
            if worst <= tol:
                run.remember_held(instances, point, worst)     # checked here: `Run.violation`
                run.stats.reused_solutions += 1
                return FeasibilityResult(True, dict(point), {ref: 0.0 for ref in refs}, worst, 0.0,
                                         time.perf_counter() - t0, iters,
                                         f"screened ({round_ + 1} NLPs, {len(near)} of {len(collision)} "
                                         "collision factors); every factor re-checked", starts)
            came = {r for r, m in zip(refs, margins) if m > -SCREEN_DISTANCE and r in is_collision} - near
            if not came:         # a kept factor or a bound the NLP's tolerance left: not ours to fix
                return None
            near |= came
        return None

    def _margins(self, instances: list, point: dict) -> list[float] | None:
        """`factor_margins` of the factors at the point (numpy), counted in reuse_time; None when
        a primitive cannot be evaluated there."""
        from gnppdsl.nlp.evaluate import factor_margins

        run = self.run
        t0 = time.perf_counter()
        try:
            return factor_margins(instances, point, run.compiled.geometry)
        except Exception:
            return None
        finally:
            run.stats.reuse_time += time.perf_counter() - t0

    def screened_solve(self, sub: GraphNLP, point: dict, distance_curvature: bool = False) -> FeasibilityResult:
        """One screened NLP from `point`: one start (no restarts), as `local_solve`.

        `distance_curvature`: with the signed-distance rows' second derivatives in ipopt's
        Hessian (a solver of its own: assembled NLPs are cached by vertex set, not by that
        option), the second try of a screened NLP that failed with them linearised (the
        setting `distance_curvature = false`). Why: the screened keyframes of stack_32 have a
        hand 2.7 cm inside the tower built one step before (the relaxation without collisions
        picks the next block right beside it); linearised, ipopt stalled there (180 iterations,
        37.7 s CPU, violation 0.0365 unchanged; its slice of steps 11-14 alone: 180 iterations,
        28.5 s), with the exact Hessian the slice is solved in 18 iterations (6.4 s). A failed
        screened NLP is no verdict either way; a second run costs one more NLP of the screened
        size where the alternative is the whole graph.

        Once such a second try has succeeded in a solve (`Run.screen_curved`), its later
        screened NLPs are run with the exact Hessian first and linearised second: stack_32's
        screened keyframes spent 12 s CPU on a linearised run that failed before the exact one
        solved them, on each graph of that size. Either order tries the same two runs from the
        same point; neither failure is a verdict."""
        run = self.run
        solver = self.solver
        if distance_curvature:
            solver = getattr(self, "_curved_solver", None)
            if solver is None:
                solver = self._curved_solver = run.new_solver()
                solver.options.distance_curvature = True
        opts = solver.options
        opts.time_limit = max(0.05, run.remaining())
        with overridden(opts, restarts=0):
            r = solver.solve(sub, warm_start=point, seed=run.options.seed)
        run.nlp_calls += 1
        if not r.feasible and (time.perf_counter() >= run.deadline or "walltime" in str(r.status).lower()):
            raise TimeUp()           # cut short by the time limit: no verdict, as `local_solve`
        return r


__all__ = ["CollisionScreen", "MOTION_SCREEN_MIN", "SCREEN_DEEP", "SCREEN_DISTANCE", "SCREEN_KEYFRAMES_MIN", "SCREEN_MIN_FACTORS"]
