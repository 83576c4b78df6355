"""The R-LGP variant of the loop (paper 002): the reachability graphs of the problem's
`reachability` blocks give the planner end-effector travel costs (Alg. 1's heuristicCost) and the
trajectories a block names in `warmstart` their collision-checked paths (getWaypoints).

Action costs that call `travel(r, a, b)` (`gnppdsl.compile.costs`) get the graph's value here, for
every algorithm: the compiled task carries their lower bound `travel_lb`, and
`with_travel_costs` builds the graph of each block whose robot such a cost names and grounds the
costs again with `graph.travel_cost` between the two targets. The numbers are taken once, at the
start of the solve (the lazy graph may change later queries' answers), so the plan costs the
planners minimise, the anytime mode bounds and `Stats.plan_cost` reports are the same numbers.
"""
from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from gnppdsl.compile.factors import VarInstance
from gnppdsl.compile.sas import SASTask
from gnppdsl.errors import UserError
from gnppdsl.solve.compiled import Compiled
from gnppdsl.solve.interpolation import keyframe_of
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.result import Stats

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.ir.model import Reachability
    from gnppdsl.nlp.graph import GraphNLP
    from gnppdsl.reach.graph import ReachabilityGraph


DETOUR = 1.5             # a graph path's base drive beyond DETOUR x the shortest drive + DETOUR_SLACK m
DETOUR_SLACK = 0.5       # is a detour: the trajectory starts on the shortest drive instead
DRIVE_WEIGHT = 2.0       # pair cost per metre of base drive, in Eq. 3's units (`_drive_pair_costs`)


class ReachabilityCosts:
    """The R-LGP part of a solve (`run.Run` derives from it); `reach` maps a robot to its
    reachability graph and the `reachability` block that built it."""

    compiled: Compiled
    options: SolveOptions
    stats: Stats
    reach: dict[str, tuple[ReachabilityGraph, Reachability]]

    def reachability_graph(self, block: Reachability) -> ReachabilityGraph:
        """The graph of `block`'s robot, built once per solve."""
        if block.robot in self.reach:
            return self.reach[block.robot][0]
        from gnppdsl.reach.integration import build_from_problem

        t0 = time.perf_counter()
        graph = build_from_problem(self.compiled.problem, block.name)
        self.stats.reach_time += time.perf_counter() - t0
        self.reach[block.robot] = (graph, block)
        self.say(f"reachability graph '{block.name}' for {block.robot}: {graph.num_samples} samples")
        return graph

    def with_travel_costs(self, task: SASTask) -> SASTask:
        """`task` with the graph's travel in the costs that call `travel(r, a, b)` (the compiled
        task has their lower bound); unchanged when no action cost calls it."""
        from gnppdsl.compile.costs import ground_travel_costs, uses_travel

        problem = self.compiled.problem
        # a Compiled built around a hand-made task (tests' toy problems) has no IR actions
        actions = getattr(getattr(problem, "domain", None), "actions", None) or {}
        if not any(a.cost_expr is not None and uses_travel(a.cost_expr, ("travel",))
                   for a in actions.values()):
            return task
        from gnppdsl.reach.integration import target_position

        blocks = {b.robot: b for b in problem.reachability}

        def travel(robot: str, a: str, b: str) -> float:
            graph = self.reachability_graph(blocks[robot])      # its build time counted there
            t0 = time.perf_counter()
            try:
                return graph.travel_cost(target_position(problem.scene, a), target_position(problem.scene, b))
            finally:
                self.stats.reach_time += time.perf_counter() - t0

        return ground_travel_costs(problem, task, travel)

    def with_reachability_costs(self, task: SASTask) -> SASTask:
        """Build the reachability graph of every `reachability` block (Sec. IV) and return the
        task with its end-effector travel costs as `pair_costs` (Alg. 1's heuristicCost): the
        planner then proposes, among the shortest plans, the one with the least travel."""
        from dataclasses import replace as dc_replace

        from gnppdsl.reach.integration import pair_costs_from_problem

        problem = self.compiled.problem
        blocks = tuple(getattr(problem, "reachability", ()) or ())
        if not blocks:
            raise UserError(f"algorithm rlgp: problem '{self.compiled.name}' has no `reachability` block")
        costs: dict = dict(task.pair_costs)
        for block in blocks:
            graph = self.reachability_graph(block)
            t0 = time.perf_counter()
            for pair, c in pair_costs_from_problem(problem, task, graph, block.name).items():
                costs[pair] = costs.get(pair, 0) + c
            for pair, c in self._drive_pair_costs(task, block).items():
                costs[pair] = costs.get(pair, 0) + c
            self.stats.reach_time += time.perf_counter() - t0
        return dc_replace(task, pair_costs=costs)

    def _drive_pair_costs(self, task: SASTask, block: Reachability) -> dict:
        """For a robot with a planar base: DRIVE_WEIGHT x the base's least drive between the
        placements next to two consecutive targets (`reach.drives.pair_drives`), in the pair
        costs' units (`reach.integration.DEFAULT_SCALE` per metre); empty for any other robot.

        Why: Eq. 3's travel is the end-effector graph's path cost, whose joint term holds the
        base as IK left it (anywhere in the arm's null space), so it does not tell which order
        of picks and drops drives less. sort_random instance 18 (R-LGP): Eq. 3 put blue1 first
        (2979 against 2979 + 128 for red1 first), whose drive round the table (`plan_bases`'
        chain 5.90 m against 4.46) ended at base 5.02 m, while plain GNPP's red-first plan
        drove 3.58 m."""
        from gnppdsl.compile.placement import base_footprint, base_radius
        from gnppdsl.reach.drives import pair_drives
        from gnppdsl.reach.integration import DEFAULT_SCALE, operator_targets

        travel = self._travel_map(block.robot)
        if travel is None:
            return {}
        problem = self.compiled.problem
        spec = problem.scene.robots[block.robot]
        drives = pair_drives(operator_targets(problem, task, block), spec.home, self._base_obstacles(),
                             spec.attributes.get("base_min"), spec.attributes.get("base_max"),
                             radius=base_radius(spec), footprint=base_footprint(spec), travel=travel)
        return {pair: int(round(DRIVE_WEIGHT * DEFAULT_SCALE * d)) for pair, d in drives.items()
                if np.isfinite(d) and round(DRIVE_WEIGHT * DEFAULT_SCALE * d)}

    def reach_keyframe_starts(self, graph: GraphNLP, states) -> None:
        """R-LGP: a keyframe of a robot with a reachability graph starts with its base placed
        next to what it acts on at the step, the free ring points of the plan's shortest drive
        (`compile.placement.restart_guesses` with `reach.drives.plan_bases`; the solver's odd
        restarts take the innermost ring's point nearest the previous base), instead of at the
        robot's home like every other keyframe.

        Why: from home, the NLP puts each keyframe's base on whichever side of the table it
        settles; the travel costs only order the plan and the optimisation phase moves the
        solution locally, so neither brings a base back from the wrong side. Measured
        (pick_place3, seed 0, `gnpp bench --instances 5 --seed 8`): instance 9's first pick,
        red1 0.95 m from the start, was made from the far side of the table (base 10.05 m in
        all; GNPP 4.44 m), instance 11 drove 7.46 m. Over instances 8-12 the mean base path
        went 5.25 -> 2.48 m (GNPP 2.74 m) and the mean CPU 22.5 -> 16.6 s (GNPP 19.2 s), all
        verified; with the innermost ring's placement instead, 2.31 m and 14.5 s, but sort2
        (plan from the travel costs) drove 2.11 m with an active-set round more (1.96 m here,
        2.07 m from home) and sort_random_pr2 instance 0 7.40 m (3.04 m here, 4.10 m from
        home). Plain GNPP keeps the home start (the baseline R-LGP is compared with).

        Open (measured on sort_random_pr2 instances 0-9, seed 0, loaded machine): with these
        starts R-LGP solved 10/10 with a mean base path of 4.42 m against plain GNPP's 3.36 m
        (instances 4, 6, 8: 5.32, 6.10, 7.99 m against 2.20, 2.12, 3.35 m); without them 9/10
        (instance 1 verification_failed after the active set's last round), 3.08 m mean on the
        9 against GNPP's 3.10 m. The placement's footprint and rings were the Panda's (0.3 m);
        they are now the robot's own (`compile.placement.base_radius`: the PR2's 0.45 m, rings
        0.70-1.10 m): instances 1, 4, 6 went 3.87, 5.32, 6.10 -> 4.17, 4.28, 4.97 m, all
        verified. Still above GNPP on 4 and 6: the least-travel side of the second pick is
        west of blue1, from where the NLP slides the base to the north side and the drop is
        made from the north (GNPP makes all four from the south). Choosing per plan (the
        shortest drive over every pick's and put's ring points, not the point nearest the
        previous base) puts that pick south of the table: instance 4 4.28 -> 2.44 m."""
        if self.options.algorithm != "rlgp" or not self.reach:
            return
        from gnppdsl.compile.placement import restart_guesses
        from gnppdsl.reach.drives import plan_bases

        placed = restart_guesses(self.compiled.factory, graph.variables, states, plan=plan_bases)
        for v, q in placed.items():
            if not v.waypoints and v.args and v.args[0] in self.reach:
                graph.initial_guess[v] = np.asarray(q, float)

    def reach_warmstart(self, traj: VarInstance, values: dict) -> np.ndarray | None:
        """Alg. 1's getWaypoints: the graph's collision-checked path between the trajectory's
        keyframes, for trajectories a block names in `warmstart` (None: interpolate instead)."""
        if not traj.args or traj.args[0] not in self.reach or self.remaining() <= 0:
            return None
        graph, block = self.reach[traj.args[0]]
        if not any(w.traj == traj.kind for w in getattr(block, "warmstarts", ())):
            return None
        key = keyframe_of(traj, values.keys())
        by = {(v.key, v.step): v for v in values}
        a, b = by.get((key, traj.step)), by.get((key, traj.step + 1))
        if a is None or b is None:
            return None
        from gnppdsl.reach.integration import graph_waypoints

        t0 = time.perf_counter()
        try:
            pts, used = graph_waypoints(graph, values[a], values[b], traj.waypoints)
        except (ValueError, IndexError):
            return None
        finally:
            self.stats.reach_time += time.perf_counter() - t0
        pts = np.asarray(pts, float)
        if pts.size != traj.dim:
            return None
        if used and self._detour(traj.args[0], pts.reshape(traj.waypoints, -1)):
            pts = self._drive(traj.args[0], values[a], values[b], traj.waypoints)
            used = False
        if used:
            self.stats.reach_warmstarts += 1
            self.stats.reach_waypoints += traj.waypoints
        else:
            self.stats.reach_straight += 1
        return pts.reshape(-1)

    def _travel_map(self, robot: str):
        """The base's drives among the tables (`reach.drives.TravelMap`, the metric of
        `plan_bases`) for a robot with a planar base; None for any other robot."""
        cache = self.__dict__.setdefault("_travel_maps", {})
        if robot not in cache:
            from gnppdsl.compile.placement import base_radius
            from gnppdsl.reach.drives import TravelMap

            scene = self.compiled.problem.scene
            spec = scene.robots.get(robot) if scene is not None else None
            if spec is None or spec.attributes.get("base_joint") != "planar" or len(spec.home) < 3:
                cache[robot] = None
            else:
                cache[robot] = TravelMap(self._base_obstacles(), base_radius(spec),
                                         spec.attributes.get("base_min"), spec.attributes.get("base_max"))
        return cache[robot]

    def _base_obstacles(self) -> list:
        """The scene's static obstacles with a full pose: what a planar base drives round
        (`_travel_map`, `_drive_pair_costs`)."""
        problem = self.compiled.problem
        return [o for o in problem.scene.static_obstacles(problem.objects).values() if len(o.pose) >= 7]

    def _detour(self, robot: str, rows: np.ndarray) -> bool:
        """Does the graph path `rows` drive the base more than DETOUR times the base's shortest
        drive between its ends, plus DETOUR_SLACK metres?

        Why: the graph's nodes are end-effector positions, its edge cost Eq. 3's (position,
        joints, node cost): for a mobile base the joints hold the base, which IK places
        anywhere in its null space, and the lazy checks remove the edges through the gaps
        between the tables. Its paths then drove round the far side of the central table:
        pick_place3_pr2 instance 18, the motion from the red tray to blue1's pick (1.0 m west
        of the table) went east round the table and back, 3.8 m, and the optimisation phase
        moved the pick's base along it to the east end (6.48 m in all, plain GNPP 1.39 m);
        with straight-line starts 1.94 m, instance 12 8.25 -> 1.46 m, 10 7.10 -> 3.20 m."""
        travel = self._travel_map(robot)
        if travel is None or len(rows) < 2:
            return False
        along = float(np.linalg.norm(np.diff(rows[:, :2], axis=0), axis=1).sum())
        drive = float(travel.distances(rows[:1, :2], rows[-1:, :2])[0, 0])
        return np.isfinite(drive) and along > DETOUR * drive + DETOUR_SLACK

    def _drive(self, robot: str, qa, qb, n: int) -> np.ndarray:
        """The trajectory start along the base's shortest drive (`reach.drives.drive_waypoints`)."""
        from gnppdsl.reach.drives import drive_waypoints

        return drive_waypoints(self._travel_map(robot), qa, qb, n).reshape(-1)

    def reach_statistics(self) -> None:
        """The graphs' own counters in `stats` (Sec. IV at work): queries and solution-library
        hits, lazy edge checks and the edges they removed, enhancement samples."""
        s = self.stats
        s.reach_samples = s.reach_queries = s.reach_library_hits = 0
        s.reach_edge_checks = s.reach_edges_removed = s.reach_enhanced_nodes = s.reach_restored = 0
        s.reach_contact_ends = 0
        for graph, _ in self.reach.values():
            graph.keep_checks()               # its edge checks' outcomes, for later runs (`reach.persist`)
            g = graph.stats
            s.reach_samples += graph.num_samples
            s.reach_restored += g.restored
            s.reach_queries += g.queries
            s.reach_library_hits += graph.library.hits
            s.reach_edge_checks += g.edge_checks
            s.reach_edges_removed += g.edges_removed
            s.reach_enhanced_nodes += g.enhanced_nodes
            s.reach_contact_ends += g.contact_ends
