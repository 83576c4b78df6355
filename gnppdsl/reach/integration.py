"""How R-LGP's graph meets the rest of the solver (paper 002, Alg. 1): pure functions for the
solve loop's owner.

- `build_from_problem(problem, block_name)`: the graph of a problem's `reachability` block.
- `operator_targets(problem, task, block)`: the end-effector target of each ground operator
  the block's `heuristic` lines cover (`heuristic pick(o, r, from) : travel(r, o)`: the scene
  position of o for every ground pick of the block's robot).
- `heuristic_pair_costs(task, targets, graph)`: Alg. 1's heuristicCost as integer costs per pair
  of consecutive operators, for `SASTask.pair_costs`, so the clingo planner's optimal plans
  prefer short end-effector travel.
- `warmstart_waypoints(graph, q_start, q_goal, n)`: Alg. 1's getWaypoints, the graph path
  resampled to a trajectory's waypoint count, angles unwrapped (`unwrap_waypoints`).

Why pair costs: the travel of an action depends on where the end effector was after the
previous action, i.e. on the pair (previous operator, operator); `SASTask.pair_costs` carries
exactly that, and the planner adds it to the operator costs. Known approximation: a target is
the object's *scene* position (an object moved by an earlier action is still costed at its
start), and between two operators of which the first has no target nothing is added.
"""
from __future__ import annotations

import math
from typing import Mapping

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.reach.graph import ReachabilityGraph
from gnppdsl.reach.settings import ReachSettings

DEFAULT_SCALE = 100          # pair cost = round(scale * Eq. 3 path cost): centimetre-like units
DEFAULT_UNREACHABLE = 10**6  # cost of a pair whose travel has no path in the graph
DEFAULT_CLEARANCE = 0.05     # a static place is targeted this far above its top face


# ---- building -----------------------------------------------------------------------------------
def select_block(problem, block_name: str | None = None):
    """The problem's reachability block named `block_name`, or its only/first block."""
    blocks = tuple(getattr(problem, "reachability", ()) or ())
    if not blocks:
        raise UserError(f"problem '{problem.name}' has no `reachability` block (its domain declares none)")
    if block_name is None:
        return blocks[0]
    for b in blocks:
        if b.name == block_name:
            return b
    raise UserError(f"problem '{problem.name}' has no reachability block '{block_name}' "
                    f"(blocks: {', '.join(b.name for b in blocks)})")


def settings_from_problem(problem, block_name: str | None = None, **overrides) -> ReachSettings:
    """Map the block's settings (frame and workspace default to the scene robot's `ee` and the
    scene's `workspace`); keyword overrides win (e.g. samples=50 for a quick run)."""
    block = select_block(problem, block_name)
    scene = problem.scene
    if scene is None:
        raise UserError(f"problem '{problem.name}': the reachability graph needs a scene (`scene \"file.yaml\"`)")
    if getattr(scene, "dimension", 3) != 3:
        raise UserError(f"reachability '{block.name}': the graph needs a 3-D scene with a URDF robot, "
                        f"scene '{scene.name}' is planar")
    return ReachSettings.from_block(block, scene, **overrides)


def build_from_problem(problem, block_name: str | None = None, build: bool = True, **overrides) -> ReachabilityGraph:
    """The reachability graph of a loaded problem (`gnppdsl.ir.load_problem`) for one of its
    `reachability` blocks, built (sampled and connected) unless `build=False`."""
    settings = settings_from_problem(problem, block_name, **overrides)
    return ReachabilityGraph.from_scene(problem.scene, settings, build=build)


# ---- targets ---------------------------------------------------------------------------------
def target_position(scene, name: str, clearance: float = DEFAULT_CLEARANCE) -> np.ndarray | None:
    """Where the end effector goes to act on scene entity `name`: a movable object's centre; a
    static object (a table, a tray, a pad) is a place to put things, so the point `clearance`
    above the centre of its top face. None for entities without a position (robots)."""
    o = scene.objects.get(name)
    if o is None:
        return None
    p = np.asarray(o.pose[:3], dtype=float)
    if not o.static or o.shape.kind == "none":
        return p
    from gnppdsl.geometry.robots import se3_to_matrix
    from gnppdsl.geometry.shapes import coal_shape, shape_vertices
    s = coal_shape(o.shape, False)
    T = se3_to_matrix(o.pose)
    top = float((shape_vertices(s) @ T[:3, :3].T + T[:3, 3])[:, 2].max())
    return np.array([p[0], p[1], top + clearance])


def operator_arguments(name: str) -> tuple[str, tuple[str, ...]]:
    """"pick(b1, g, s1)" -> ("pick", ("b1", "g", "s1"))."""
    head, _, rest = name.partition("(")
    rest = rest.rstrip().rstrip(")")
    return head.strip(), tuple(a.strip() for a in rest.split(",") if a.strip())


def operator_targets(problem, task, block=None, clearance: float = DEFAULT_CLEARANCE) -> dict[int, np.ndarray]:
    """Operator index -> end-effector target, for every ground operator of an action the block has
    a `heuristic` for and whose robot argument is the block's robot."""
    block = block if block is not None and not isinstance(block, str) else select_block(problem, block)
    by_action = {h.action: h for h in block.heuristics}
    out: dict[int, np.ndarray] = {}
    for i, op in enumerate(task.operators):
        action, args = operator_arguments(op.name)
        h = by_action.get(action)
        if h is None or len(args) != len(h.params):
            continue
        binding = dict(zip(h.params, args))
        robot, target = binding.get(h.args[0]), binding.get(h.args[1])
        if robot != block.robot or target is None:
            continue
        x = target_position(problem.scene, target, clearance)
        if x is not None:
            out[i] = x
    return out


# ---- Alg. 1: heuristicCost -------------------------------------------------------------------------
def heuristic_pair_costs(task, targets: Mapping[int, np.ndarray], graph: ReachabilityGraph,
                         start=None, scale: float = DEFAULT_SCALE,
                         unreachable_cost: int = DEFAULT_UNREACHABLE) -> dict[tuple[int | None, int], int]:
    """R-LGP travel costs for `SASTask.pair_costs`.

    For every operator `op` with a target and every `prev` that also has one (or `None`, the
    start of the plan: from the position `start`, by default from the robot's home configuration):
    `round(scale * travel(target(prev), target(op)))`, the graph's Eq. 3 path cost. A pair whose
    travel has no path costs `unreachable_cost`. Pairs with an untargeted `prev` are left out
    (cost 0). `task` is only used to check the operator indices. The graph's solution library
    makes the many pairs cheap: only distinct target positions are ever queried.
    """
    n = len(task.operators)
    for i in targets:
        if not 0 <= int(i) < n:
            raise ValueError(f"operator index {i} out of range (task has {n} operators)")

    def scaled(c: float) -> int:
        return int(unreachable_cost) if not math.isfinite(c) else int(round(scale * c))

    def cost(a, b) -> int:
        return scaled(graph.travel_cost(a, b))

    def first(x) -> int:      # from the home configuration itself, or from a given position
        if start is None:
            return scaled(graph.query_from_config(graph.home, x).cost)
        return cost(np.asarray(start, dtype=float), x)

    out: dict[tuple[int | None, int], int] = {}
    for op, x in targets.items():
        c0 = first(x)
        if c0:
            out[(None, int(op))] = c0
        for prev, xp in targets.items():
            c = cost(xp, x)
            if c:
                out[(int(prev), int(op))] = c
    return out


def pair_costs_from_problem(problem, task, graph: ReachabilityGraph | None = None, block_name: str | None = None,
                            scale: float = DEFAULT_SCALE, **overrides) -> dict[tuple[int | None, int], int]:
    """`heuristic_pair_costs` for a problem's block (building the graph if none is given)."""
    block = select_block(problem, block_name)
    graph = graph if graph is not None else build_from_problem(problem, block.name, **overrides)
    return heuristic_pair_costs(task, operator_targets(problem, task, block), graph, scale=scale)


# ---- Alg. 1: getWaypoints -----------------------------------------------------------------------------
def resample_polyline(points: np.ndarray, n: int) -> np.ndarray:
    """n points evenly spaced by arc length along a joint-space polyline (first and last kept)."""
    pts = np.asarray(points, dtype=float)
    if n < 1:
        raise ValueError("n_waypoints must be >= 1")
    if len(pts) == 1:
        return np.repeat(pts, n, axis=0)
    seg = np.linalg.norm(np.diff(pts, axis=0), axis=1)
    s = np.r_[0.0, np.cumsum(seg)]
    if s[-1] <= 0:
        return np.repeat(pts[:1], n, axis=0)
    u = np.linspace(0.0, s[-1], n) if n > 1 else np.array([s[-1] / 2])
    out = np.empty((len(u), pts.shape[1]))
    for j in range(pts.shape[1]):
        out[:, j] = np.interp(u, s, pts[:, j])
    if n > 1:
        out[0], out[-1] = pts[0], pts[-1]
    return out


def warmstart_waypoints(graph: ReachabilityGraph, q_start, q_goal, n_waypoints: int) -> np.ndarray:
    """An (n_waypoints x nq) initial guess for a trajectory from q_start to q_goal: the graph's
    collision-checked path between the two configurations (both become graph nodes), resampled
    evenly by joint-space arc length; row 0 is q_start and the last row q_goal, matching the
    `boundary` template (path[0] = q, path[n-1] = q'). If the graph has no path between them,
    the straight joint-space line (what the NLP would start from without the graph)."""
    return graph_waypoints(graph, q_start, q_goal, n_waypoints)[0]


def graph_waypoints(graph: ReachabilityGraph, q_start, q_goal, n_waypoints: int) -> tuple[np.ndarray, bool]:
    """`warmstart_waypoints` and whether they follow a graph path (False: the straight line),
    for the statistics that show getWaypoints at work (`Stats.reach_warmstarts`)."""
    qa = np.asarray(q_start, dtype=float).ravel()
    qb = np.asarray(q_goal, dtype=float).ravel()
    sol = graph.query_configs(qa, qb)
    used = math.isfinite(sol.cost) and len(sol.path) > 0
    if not used:
        return resample_polyline(np.vstack([qa, qb]), int(n_waypoints)), False
    return unwrap_waypoints(graph.robot, sol.path, qa, qb, int(n_waypoints)), True


def unwrap_waypoints(robot, path, q_start, q_goal, n_waypoints: int) -> np.ndarray:
    """A graph path as n_waypoints trajectory rows from q_start to q_goal, angles continuous.

    Graph nodes hold angles (continuous joints, a planar heading: `RobotModel.angle_mask`) as
    IK left them, anywhere in R, and edges turn the short way round. So the path is unwrapped
    from q_start: each waypoint is the previous one plus the short difference
    (`RobotModel.coord_difference`). The unwrapped end can differ from q_goal's own angles by
    2*pi*k (a keyframe's angle is a number too, not only a point of the circle); that
    remainder is spread linearly over the rows, so the path stays continuous and its last row
    is exactly q_goal (the `boundary` template: path[n-1] = q')."""
    qa = np.asarray(q_start, dtype=float).ravel()
    qb = np.asarray(q_goal, dtype=float).ravel()
    pts = np.asarray(path, dtype=float).reshape(len(path), -1)
    steps = robot.coord_difference(np.vstack([qa, pts[:-1]]), pts)      # row 0: qa -> the first node
    unwrapped = qa[None, :] + np.cumsum(steps, axis=0)
    out = resample_polyline(unwrapped, n_waypoints)
    rest = qb - unwrapped[-1]
    out = out + np.linspace(0.0, 1.0, len(out))[:, None] * rest[None, :] if len(out) > 1 else out
    out[0] = qa
    if len(out) > 1:
        out[-1] = qb
    return out
