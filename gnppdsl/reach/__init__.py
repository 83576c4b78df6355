"""gnppdsl.reach: the reachability graph of R-LGP (paper 002, Sec. IV).

Modules (import them directly; this package imports nothing heavy):
- `settings`: `ReachSettings` (robot, frame, workspace, samples, k, Eq. 3 weights, L, IK, seed)
- `collision`: `CollisionChecker` (one robot vs the static scene, pinocchio + coal)
- `ik_validation`: `validate_position` (Eq. 2: g_prec, position IK, collision rejection)
- `library`: `SolutionLibrary` (Eq. 4: solved paths keyed by their sorted ends)
- `graph`: `ReachabilityGraph` (LazyPRM: k-NN edges with Eq. 3 costs, lazy checks, Dijkstra,
  Gaussian enhancement; `path`, `travel_cost`, `query`, `query_configs`)
- `integration`: `build_from_problem`, `operator_targets`, `heuristic_pair_costs`,
  `warmstart_waypoints` (what the solve loop calls; Alg. 1's heuristicCost and getWaypoints)
"""
