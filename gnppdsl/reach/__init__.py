"""gnppdsl.reach: the reachability graph of R-LGP (paper 002, Sec. IV).

Modules (imported on demand, so `import gnppdsl.reach` stays cheap):
- `settings`: `ReachSettings` (robot, frame, workspace, samples, k, Eq. 3 weights, L, IK, seed)
- `collision`: `CollisionChecker` (one robot vs the static scene, pinocchio + coal)
- `ik_validation`: `validate_position` (Eq. 2: g_prec, position IK, collision rejection)
- `library`: `SolutionLibrary` (Eq. 4: solved paths keyed by their sorted ends)
- `graph`: `ReachabilityGraph` (LazyPRM: k-NN edges with Eq. 3 costs, lazy checks, Dijkstra,
  Gaussian enhancement; `path`, `travel_cost`, `query`, `query_configs`)
- `integration`: `build_from_problem`, `operator_targets`, `heuristic_pair_costs`,
  `warmstart_waypoints` (what the solve loop calls; Alg. 1's heuristicCost and getWaypoints)
- `drives`: `TravelMap` (a base's drives among the tables' grown footprints, `route`), `plan_bases`
  (the keyframe bases of a plan's least drive: R-LGP's keyframe starts), `drive_waypoints` (a
  trajectory start along the base's shortest drive, where a graph path is a detour)

Typical use by the solve loop (R-LGP, `algorithm = rlgp`):

    graph = build_from_problem(problem)                      # once per problem
    task.pair_costs = heuristic_pair_costs(task, operator_targets(problem, task), graph)
    planner = IncrementalPlanner(task); plan = planner.optimal_plan(horizon)
    init = warmstart_waypoints(graph, q_i, q_next, waypoints)   # per `warmstart path(r)` phase
"""
from __future__ import annotations

from gnppdsl.lazy import lazy_getattr

_EXPORTS = {
    "ReachSettings": "gnppdsl.reach.settings",
    "ReachabilityGraph": "gnppdsl.reach.graph",
    "build_from_problem": "gnppdsl.reach.integration",
    "operator_targets": "gnppdsl.reach.integration",
    "heuristic_pair_costs": "gnppdsl.reach.integration",
    "pair_costs_from_problem": "gnppdsl.reach.integration",
    "warmstart_waypoints": "gnppdsl.reach.integration",
    "TravelMap": "gnppdsl.reach.drives",
    "plan_bases": "gnppdsl.reach.drives",
}

__all__ = sorted(_EXPORTS)


__getattr__ = lazy_getattr(__name__, _EXPORTS)
