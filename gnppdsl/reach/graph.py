"""The reachability graph of R-LGP (paper 002, Sec. IV): a LazyPRM over end-effector positions.

- Nodes n(x, q, c): end-effector positions x drawn uniformly in the workspace box, each
  validated by Eq. 2 (`ik_validation`): q reaches x, is within the joint limits and collision-free
  against the static scene; c is the optimal Eq. 2 cost.
- Edges: each node to its k nearest neighbours (by position), *not* collision-checked when added
  (lazy), with the cost of Eq. 3: w_x |x1 - x2| + w_q |q1 - q2| + w_c (c1 + c2).
- Queries (Sec. IV-B2): the two ends become nodes (IK-solved, or given configurations) whose
  edges are checked at once; Dijkstra (`_dijkstra`) finds the cheapest path; only the unchecked
  edges of that path are checked (L interpolated joint-space configurations); an edge that
  collides is removed and Dijkstra runs again. An end that cannot connect, a pair of ends in
  different components, or a node that loses all its edges triggers *enhancement*: Gaussian
  samples with shrinking covariance around it, validated and connected with checked edges.
- Solved paths go into the solution library keyed by their (sorted) ends.

The graph only grows more correct: an edge is removed only after a failed check and a checked
edge is never unchecked, so every returned path consists of checked, collision-free edges and
its cost is the shortest-path cost of the current graph (checked + still unchecked edges).
Everything random comes from one `numpy.random.Generator` seeded by `settings.seed`.
"""
from __future__ import annotations

import hashlib
import heapq
import itertools
import math
import time
from dataclasses import dataclass, field, fields
from typing import Callable, Hashable, Iterator

import numpy as np

from gnppdsl.errors import UserError
from gnppdsl.geometry.robots import RobotModel
from gnppdsl.nlp.graph import Graph
from gnppdsl.reach.collision import CollisionChecker, static_obstacles
from gnppdsl.reach.ik_validation import NodeValidation, ValidationStats, validate_position
from gnppdsl.reach.library import Solution, SolutionLibrary
from gnppdsl.reach.settings import ReachSettings

SAMPLE, QUERY, ENHANCE = "sample", "query", "enhance"
CONTACT = "contact"     # a query's end configuration that is itself in collision (`attach_config`)
CONTACT_SHARE = 0.5     # share of an edge from a contact end that may still collide (`leaves_contact`)
CONTACT_SIGMA = 0.05    # first joint-space spread around a contact end (`_free_near`), doubled each round


@dataclass
class PathResult:
    """A collision-checked path: graph nodes, their configurations (n x nq) and positions (n x 3)."""

    cost: float
    nodes: tuple[int, ...]
    waypoints: np.ndarray
    positions: np.ndarray


@dataclass
class GraphStats:
    draws: int = 0
    build_time: float = 0.0
    validation: ValidationStats = field(default_factory=ValidationStats)
    edge_checks: int = 0
    edges_removed: int = 0
    enhanced_nodes: int = 0
    replaced_nodes: int = 0
    contact_ends: int = 0       # query ends in collision, joined by segments leaving the contact
    queries: int = 0
    dijkstra_runs: int = 0
    query_time: float = 0.0
    restored: bool = False      # the pre-built graph came from the store (`reach.persist`)
    stored_checks: int = 0      # edge checks answered by the store's outcomes (`check_edge`)


class LazyGraph(Graph):
    """The graph of the LazyPRM: `nlp.graph.Graph` (networkx's semantics, without importing
    networkx: ~0.12 s CPU of every R-LGP solve, a third of the sort2 graph's queries) with the
    removals and attribute views this module and its tests use (`remove_node`, `remove_edge`,
    `number_of_edges`, `edges(data=KEY)`; `nodes(data=KEY)` is the base's), and Dijkstra's search in
    networkx's order (`_dijkstra`: the same heap ties, so the same paths)."""

    __slots__ = ()

    def edges(self, data: bool | str = False) -> Iterator:
        seen: set = set()
        for u, nbrs in self._adj.items():
            for v, d in nbrs.items():
                if v not in seen:
                    yield (u, v, d.get(data)) if isinstance(data, str) else (u, v, d) if data else (u, v)
            seen.add(u)

    def remove_node(self, n: Hashable) -> None:
        if n not in self._node:
            raise KeyError(n)
        self.remove_nodes_from((n,))

    def remove_edge(self, u: Hashable, v: Hashable) -> None:
        del self._adj[u][v]
        if u != v:
            del self._adj[v][u]

    def number_of_edges(self) -> int:
        return sum(len(nbrs) + (u in nbrs) for u, nbrs in self._adj.items()) // 2

    def component(self, u: Hashable) -> set:
        """u's connected component (`networkx.node_connected_component`)."""
        comp, todo = {u}, [u]
        while todo:
            for m in self._adj[todo.pop()]:
                if m not in comp:
                    comp.add(m)
                    todo.append(m)
        return comp

    def has_path(self, s: Hashable, t: Hashable) -> bool:
        return t in self.component(s)


def _segment_key(qa: np.ndarray, qb: np.ndarray) -> str:
    """The store's key of the edge check from configuration qa to qb (their exact floats)."""
    h = hashlib.blake2b(digest_size=16)
    h.update(np.ascontiguousarray(qa, dtype=float).tobytes())
    h.update(b"|")
    h.update(np.ascontiguousarray(qb, dtype=float).tobytes())
    return h.hexdigest()


def _dijkstra(G: LazyGraph, s: Hashable, t: Hashable) -> tuple[float, list] | None:
    """The cheapest path s -> t by the edges' `cost` (cost, nodes), None when there is none:
    `networkx.single_source_dijkstra(G, s, t, weight="cost")`'s algorithm (a heap of (distance,
    insertion count, node), neighbours in insertion order), hence its choice among equal paths."""
    adj = G.adj
    dist: dict = {}
    seen = {s: 0.0}
    paths = {s: [s]}
    count = itertools.count()
    fringe = [(0.0, next(count), s)]
    while fringe:
        d, _, v = heapq.heappop(fringe)
        if v in dist:
            continue
        dist[v] = d
        if v == t:
            break
        for u, e in adj[v].items():
            vu = d + e["cost"]
            if u in dist:
                continue
            if u not in seen or vu < seen[u]:
                seen[u] = vu
                heapq.heappush(fringe, (vu, next(count), u))
                paths[u] = paths[v] + [u]
    if t not in dist:
        return None
    return dist[t], paths[t]


class ReachabilityGraph:
    """R-LGP reachability graph for one robot. Build with `ReachabilityGraph.from_scene(...)`
    (or the constructor + `build()`), then ask `path`, `travel_cost`, `query`, `query_configs`."""

    def __init__(self, robot: RobotModel, settings: ReachSettings, checker: CollisionChecker,
                 home: np.ndarray | None = None):
        self.robot = robot
        self.settings = settings
        self.frame = settings.frame or robot.ee
        if self.frame is None:
            raise UserError(f"reachability for '{robot.name}': no end-effector frame (set `frame` or the scene `ee`)")
        robot.frame_id(self.frame)     # raises a UserError for an unknown frame
        self.checker = checker
        self.home = np.asarray(home, dtype=float) if home is not None else robot.home_coords()
        self.G = LazyGraph()
        self.library = SolutionLibrary()
        self.stats = GraphStats()
        self.rng = np.random.default_rng(settings.seed)
        self._invalid: set[frozenset] = set()   # edges that failed a check: never re-added
        self._next_id = 0
        self._n_samples = 0
        self._ids: list[int] = []
        self._contact: set[int] = set()          # the temporary ends of the current query
        self._X: np.ndarray = np.zeros((0, 3))
        self._Q: np.ndarray | None = None        # the nodes' configurations, in `_ids` order
        self._lo = np.asarray(settings.workspace[0], dtype=float)
        self._hi = np.asarray(settings.workspace[1], dtype=float)
        self._key: str | None = None             # the store's key (`build`)
        self._checks: dict[str, bool] = {}       # segment -> free: stored and this run's (`check_edge`)
        self._new_checks = 0                     # outcomes not in the store yet (`keep_checks`)

    # ---- construction -----------------------------------------------------------------------
    @classmethod
    def from_scene(cls, scene, settings: ReachSettings, build: bool = True, models: dict | None = None
                   ) -> "ReachabilityGraph":
        """Graph of `settings.robot` in a loaded scene (`gnppdsl.ir.scene_model.Scene`); the
        obstacles are the scene's static objects unless `settings.obstacles` names others."""
        from gnppdsl.geometry.robots import load_robot
        spec = scene.robots.get(settings.robot)
        if spec is None:
            raise UserError(f"reachability: robot '{settings.robot}' is not in scene '{scene.name}' "
                            f"(robots: {', '.join(scene.robots) or 'none'})")
        if spec.kind != "urdf":
            raise UserError(f"reachability: robot '{settings.robot}' has no kinematic model (kind '{spec.kind}'); "
                            "the reachability graph needs a URDF robot")
        robot = (models or {}).get(settings.robot) or load_robot(spec)
        obstacles = static_obstacles(scene, settings.robot, settings.obstacles)
        fixed_base = spec.attributes.get("base_joint") in (None, "fixed")
        checker = CollisionChecker(robot, obstacles, settings.margin, settings.self_collision,
                                   frozenset(frozenset(p) for p in scene.ignore_collisions), fixed_base)
        g = cls(robot, settings, checker, robot.home_coords(spec.home))
        if build:
            from gnppdsl.reach import persist
            g.build(persist.graph_key(settings, spec, robot, g.home, obstacles, scene,
                                      frozenset(frozenset(p) for p in scene.ignore_collisions), fixed_base))
        return g

    def build(self, key: str | None = None) -> "ReachabilityGraph":
        """Sample N_node validated nodes (at most `settings.draws` draws), then k-NN edges (lazy).
        `key` (`reach.persist.graph_key`): the nodes are restored from the store when it holds
        this key, and stored after a build when it does not."""
        from gnppdsl.reach import persist

        s = self.settings
        t0 = time.perf_counter()
        stored = persist.load(key) if key is not None and not self._ids else None
        if key is not None:
            self._key = key
            self._checks = persist.load_checks(key)
        if stored is not None and self._restore(stored):
            self.stats.restored = True
        else:
            while self.num_samples < s.samples and self.stats.draws < s.draws:
                self.stats.draws += 1
                x = self.rng.uniform(self._lo, self._hi)
                v = self._validate(x)
                if v is not None:
                    self._add_node(v, SAMPLE)
            if key is not None:
                persist.save(key, self._built())
        for u in list(self._ids):
            self._connect(u, check=False)
        self.stats.build_time += time.perf_counter() - t0
        return self

    def _built(self) -> dict:
        """What the sampling drew (`reach.persist`): the nodes in order, the generator's state
        after the draws, the statistics of the draws."""
        return {"nodes": [[self.G.nodes[u]["x"].tolist(), self.G.nodes[u]["q"].tolist(), self.G.nodes[u]["c"]]
                          for u in self._ids],
                "rng": self.rng.bit_generator.state, "draws": self.stats.draws,
                "validation": {f.name: getattr(self.stats.validation, f.name)
                               for f in fields(self.stats.validation)}}

    def _restore(self, data: dict) -> bool:
        """The sampling's outcome from `_built`'s record, on a graph without nodes; False (and
        the graph untouched) when the record does not fit this robot."""
        try:
            nodes = [(np.asarray(x, dtype=float), np.asarray(q, dtype=float), float(c)) for x, q, c in data["nodes"]]
            if any(x.shape != (3,) or q.shape != (self.robot.nc,) for x, q, _ in nodes):
                return False
            draws = int(data["draws"])
            counts = {f.name: int(data["validation"][f.name]) for f in fields(self.stats.validation)}
            rng = np.random.default_rng()
            rng.bit_generator.state = data["rng"]          # validated on a spare generator first
        except (KeyError, TypeError, ValueError):
            return False
        self.rng = rng
        for x, q, c in nodes:
            self._add_node(NodeValidation(x, q, c, 0), SAMPLE)
        self.stats.draws = draws
        for name, n in counts.items():
            setattr(self.stats.validation, name, n)
        return True

    @property
    def num_samples(self) -> int:
        """Pre-built (uniformly sampled) nodes currently in the graph."""
        return self._n_samples

    def _validate(self, x, extra_seeds=()) -> NodeValidation | None:
        seeds = list(extra_seeds)
        for u in self.nearest(x, 2):
            seeds.append(self.G.nodes[u]["q"])
        seeds.append(self.home)
        return validate_position(self.robot, self.checker, self.frame, x, self.rng, seeds,
                                 self.settings.ik_restarts, self.settings.ik_tolerance, self.stats.validation)

    def _add_node(self, v: NodeValidation, kind: str) -> int:
        nid = self._next_id
        self._next_id += 1
        self.G.add_node(nid, x=np.asarray(v.x, dtype=float), q=np.asarray(v.q, dtype=float), c=float(v.cost), kind=kind)
        self._ids.append(nid)
        self._n_samples += kind == SAMPLE
        self._X = np.vstack([self._X, np.asarray(v.x, dtype=float)[None, :]])
        q = np.asarray(v.q, dtype=float).reshape(1, -1)
        self._Q = q if self._Q is None else np.vstack([self._Q, q])
        return nid

    def _remove_node(self, nid: int) -> None:
        i = self._ids.index(nid)
        self._n_samples -= self.G.nodes[nid]["kind"] == SAMPLE
        self._contact.discard(nid)
        self._ids.pop(i)
        self._X = np.delete(self._X, i, axis=0)
        self._Q = np.delete(self._Q, i, axis=0)
        self.G.remove_node(nid)

    def nearest(self, x, k: int, exclude=()) -> list[int]:
        """The k nodes nearest to position x (brute force: a few thousand nodes at most)."""
        if not self._ids:
            return []
        d = np.linalg.norm(self._X - np.asarray(x, dtype=float)[None, :], axis=1)
        order = np.argsort(d, kind="stable")
        out = []
        for i in order:
            nid = self._ids[i]
            if nid in exclude:
                continue
            out.append(nid)
            if len(out) == k:
                break
        return out

    def edge_cost(self, u: int, v: int) -> float:
        """Eq. 3; |q1 - q2| takes angles the short way round (`RobotModel.coord_difference`),
        as the edge check interpolates them."""
        a, b = self.G.nodes[u], self.G.nodes[v]
        wx, wq, wc = self.settings.weights
        return float(wx * np.linalg.norm(a["x"] - b["x"])
                     + wq * np.linalg.norm(self.robot.coord_difference(a["q"], b["q"]))
                     + wc * (a["c"] + b["c"]))

    def _connect(self, u: int, check: bool) -> int:
        """Edges from u to its k nearest nodes; with `check`, only those passing the collision
        check are kept (and marked checked). Returns the number of edges u gained or kept."""
        n = 0
        for v in self.nearest(self.G.nodes[u]["x"], self.settings.neighbours, exclude={u} | self._contact):
            e = frozenset((u, v))
            if e in self._invalid:
                continue
            if self.G.has_edge(u, v):
                if check and not self.G[u][v]["checked"] and not self.check_edge(u, v):
                    continue
                n += 1
                continue
            self.G.add_edge(u, v, cost=self.edge_cost(u, v), checked=False)
            if check and not self.check_edge(u, v):
                continue
            n += 1
        return n

    # ---- lazy edge checks ---------------------------------------------------------------------
    def check_edge(self, u: int, v: int) -> bool:
        """Collision-check edge (u, v) now: mark it checked, or remove it (for good).

        The outcome of the segment q_u -> q_v (exactly these configurations, in this order) is
        kept with the pre-built graph (`keep_checks`, `reach.persist`), whose key covers all the
        check reads (code, robot, obstacles, settings), so a later run asks the store instead of
        coal: the same answer, the same graph, paths and results. Why: the lazy checks of the
        travel costs and warm starts were most of a solve's graph time (sort2, R-LGP, seed 0: 98
        checks, ~1600 collision queries, ~0.25 s of ~2.2 s CPU), and a run of the same scene
        (another seed, instance or algorithm setting) checks the same segments again."""
        self.stats.edge_checks += 1
        qa, qb = self.G.nodes[u]["q"], self.G.nodes[v]["q"]
        key = _segment_key(qa, qb)
        ok = self._checks.get(key)
        if ok is None:
            ok = self.checker.segment_free(qa, qb, self.settings.interpolation, self.settings.max_joint_step)
            self._checks[key] = ok
            self._new_checks += 1
        else:
            self.stats.stored_checks += 1
        if ok:
            self.G[u][v]["checked"] = True
        else:
            self.G.remove_edge(u, v)
            self._invalid.add(frozenset((u, v)))
            self.stats.edges_removed += 1
        return ok

    def keep_checks(self) -> bool:
        """Store this run's edge-check outcomes with the graph's (`reach.persist.save_checks`);
        False when there is nothing new or no store."""
        if self._key is None or not self._new_checks:
            return False
        from gnppdsl.reach import persist

        self._new_checks = 0
        return persist.save_checks(self._key, self._checks)

    # ---- enhancement (Gaussian sampling, Sec. IV-B2) ------------------------------------------
    def _anchored(self, u: int) -> bool:
        """Does u's component contain a pre-built sample node (other than u)?"""
        return any(self.G.nodes[w]["kind"] == SAMPLE and w != u for w in self.G.component(u))

    def _enhance(self, center, goal: Callable[[], bool], seed_q=None) -> bool:
        """Gaussian samples around `center` (standard deviation shrinking each round), each
        validated and connected with checked edges, until `goal()` holds."""
        s = self.settings
        sigma = s.enhance_sigma
        center = np.asarray(center, dtype=float)
        for _ in range(s.enhance_rounds):
            for _ in range(s.enhance_samples):
                x = np.clip(self.rng.normal(center, sigma), self._lo, self._hi)
                v = self._validate(x, [seed_q] if seed_q is not None else [])
                if v is None:
                    continue
                nid = self._add_node(v, ENHANCE)
                self.stats.enhanced_nodes += 1
                self._connect(nid, check=True)
                if goal():
                    return True
            sigma *= s.enhance_decay
        return goal()

    def _replace_isolated(self, w: int) -> None:
        """A node that lost all its edges is replaced by enhancement around it: the new node
        that connect to the graph stay, the rest are dropped (paper: keeps the graph connected)."""
        x, q = self.G.nodes[w]["x"], self.G.nodes[w]["q"]
        self._remove_node(w)
        self.stats.replaced_nodes += 1
        before = set(self._ids)
        self._enhance(x, lambda: any(self.G.degree(n) > 0 for n in set(self._ids) - before), seed_q=q)
        new = [n for n in set(self._ids) - before]
        connected = [n for n in new if self.G.degree(n) > 0]
        if connected:   # keep the best connected replacement, drop the other isolated samples
            for n in new:
                if self.G.degree(n) == 0:
                    self._remove_node(n)

    # ---- ends of a query -------------------------------------------------------------------------
    def _find(self, x=None, q=None) -> int | None:
        for u in self.nearest(x, 1) if x is not None else []:
            if np.linalg.norm(self.G.nodes[u]["x"] - x) <= 1e-9:
                return u
        if q is not None and self._ids and q.shape == self._Q.shape[1:]:
            # the first node (in `_ids` order) within 1e-9 in every coordinate (np.allclose with
            # rtol 0), one array operation: a loop of allclose calls over the nodes cost ~6 ms
            # a query end (sort2: 12 ends, 200+ nodes)
            hit = np.flatnonzero(np.all(np.abs(self._Q - q[None, :]) <= 1e-9, axis=1))
            if len(hit):
                return self._ids[int(hit[0])]
        return None

    def attach_position(self, x) -> int | None:
        """A node at end-effector position x (an existing one at x or within `snap_radius`, or a
        new IK-solved one connected with checked edges, enhanced if it cannot connect); None if
        x is unreachable."""
        x = np.asarray(x, dtype=float).ravel()
        u = self._find(x=x)
        if u is not None:
            return u
        if self.settings.snap_radius > 0:
            near = self.nearest(x, 1)
            if near and np.linalg.norm(self.G.nodes[near[0]]["x"] - x) <= self.settings.snap_radius:
                return near[0]
        v = self._validate(x)
        if v is None:
            return None
        u = self._add_node(v, QUERY)
        self._attach(u)
        return u

    def attach_config(self, q) -> int:
        """A node for a given configuration (e.g. a trajectory's start): its position comes from
        pinocchio forward kinematics; the configuration is taken as given (not re-validated)."""
        q = np.asarray(q, dtype=float).ravel()
        u = self._find(x=self.fk_position(q), q=q)
        if u is not None and np.allclose(self.G.nodes[u]["q"], q, atol=1e-9, rtol=0):
            return u
        if not self.checker.config_free(q):
            return self._attach_contact(q)
        u = self._add_node(NodeValidation(self.fk_position(q), q, 0.0, 0), QUERY)
        self._attach(u)
        return u

    def _attach_contact(self, q) -> int:
        """A node for an end configuration that is itself in collision (a keyframe the NLP put
        in contact with a pair its graph-NLP does not constrain yet: the active set adds such
        pairs only in later rounds). Every edge checked from it would fail at its first
        configuration, and the enhancement around it would add dozens of nodes before the query
        gave up (sort_random_pr2 instance 2: 3 of 4 motions, 175 enhancement nodes). Instead it
        joins its k nearest free nodes by segments that leave the contact (`leaves_contact`):
        the graph's path is collision-free after the first segment's colliding start, and the
        NLP moves the rest. The node is temporary (`_solve` removes it after the query), so no
        other path runs through a colliding configuration."""
        u = self._add_node(NodeValidation(self.fk_position(q), q, 0.0, 0), CONTACT)
        self._contact.add(u)
        self.stats.contact_ends += 1
        for v in self.nearest(self.G.nodes[u]["x"], self.settings.neighbours, exclude=self._contact | {u}):
            self.stats.edge_checks += 1
            if self.leaves_contact(q, self.G.nodes[v]["q"]):
                self.G.add_edge(u, v, cost=self.edge_cost(u, v), checked=True)
        if self.G.degree(u) == 0:
            free = self._free_near(q)
            if free is not None:
                w = self._add_node(NodeValidation(self.fk_position(free), free, 0.0, 0), QUERY)
                self.G.add_edge(u, w, cost=self.edge_cost(u, w), checked=True)
                self._attach(w)
        return u

    def _free_near(self, q) -> np.ndarray | None:
        """A free configuration a short segment from a colliding q leads to (`leaves_contact`):
        Gaussian joint-space perturbations of q, the spread growing from CONTACT_SIGMA. Why:
        the graph's nodes are other IK branches (sort_random_pr2 instance 2: the nearest node
        1.9-2.6 rad away in joint space, every segment to it colliding over most of its length),
        so a keyframe in contact reaches none of them directly."""
        sigma = CONTACT_SIGMA
        for _ in range(self.settings.enhance_rounds):
            for _ in range(self.settings.enhance_samples):
                qf = np.clip(q + self.rng.normal(0.0, sigma, q.shape), self.robot.lower, self.robot.upper)
                if self.checker.config_free(qf) and self.leaves_contact(q, qf):
                    return qf
            sigma *= 2.0
        return None

    def leaves_contact(self, q_contact, q_free) -> bool:
        """Does the straight segment from a colliding q_contact to a free node leave the contact
        for good: its configurations may collide at first, over at most CONTACT_SHARE of the
        segment, and are free from the first free one on?"""
        qs = self.checker.segment_configs(q_contact, q_free, self.settings.interpolation,
                                          self.settings.max_joint_step)
        limit = int(np.ceil(CONTACT_SHARE * len(qs)))
        i = 0
        while i < len(qs) and not self.checker.config_free(qs[i]):
            i += 1
            if i > limit:
                return False
        return all(self.checker.config_free(c) for c in qs[i + 1:][::-1])


    def _attach(self, u: int) -> None:
        self._connect(u, check=True)
        if not self._anchored(u):
            self._enhance(self.G.nodes[u]["x"], lambda: self._anchored(u), seed_q=self.G.nodes[u]["q"])

    def fk_position(self, q) -> np.ndarray:
        """World position of the graph's frame at configuration q (pinocchio)."""
        import pinocchio as pin
        data = self.robot.model.createData()
        pin.framesForwardKinematics(self.robot.model, data, self.robot.to_pin_q(q))
        T = self.robot.base @ np.array(data.oMf[self.robot.frame_id(self.frame)].homogeneous)
        return T[:3, 3].copy()

    @property
    def start_position(self) -> np.ndarray:
        """End-effector position at the home configuration. (The first action's travel is
        costed from the home configuration itself, `query_from_config`, not from this point.)"""
        return self.fk_position(self.home)

    # ---- queries ------------------------------------------------------------------------------
    def shortest_path(self, s: int, t: int, enhance: bool = True) -> PathResult | None:
        """Lazy shortest path between two nodes: Dijkstra, check the path's unchecked edges,
        remove colliding ones and repeat; enhance once around the ends if they are disconnected."""
        enhanced = not enhance
        while True:
            self.stats.dijkstra_runs += 1
            found = _dijkstra(self.G, s, t)
            if found is None:
                if enhanced:
                    return None
                enhanced = True
                for end in (s, t):
                    if self.G.nodes[end]["kind"] != CONTACT and not self.G.has_path(s, t):
                        self._enhance(self.G.nodes[end]["x"], lambda: self.G.has_path(s, t),
                                      seed_q=self.G.nodes[end]["q"])
                continue
            cost, nodes = found
            bad = None
            for u, v in zip(nodes, nodes[1:]):
                if not self.G[u][v]["checked"] and not self.check_edge(u, v):
                    bad = (u, v)
                    break
            if bad is None:
                return PathResult(float(cost), tuple(nodes),
                                  np.array([self.G.nodes[n]["q"] for n in nodes]).reshape(len(nodes), -1),
                                  np.array([self.G.nodes[n]["x"] for n in nodes]).reshape(len(nodes), 3))
            for w in bad:
                if w not in (s, t) and self.G.degree(w) == 0:
                    self._replace_isolated(w)

    def _solve(self, key_a, key_b, attach_a, attach_b) -> Solution | None:
        self.stats.queries += 1
        hit = self.library.get(key_a, key_b)
        if hit is not None:
            return hit
        t0 = time.perf_counter()
        try:
            s = attach_a()
            t = attach_b()
            if s is None or t is None:
                sol = Solution((key_a, key_b), np.zeros((0, self.robot.nc)), math.inf)
            else:
                r = self.shortest_path(s, t)
                sol = (Solution((key_a, key_b), r.waypoints, r.cost, r.nodes) if r is not None
                       else Solution((key_a, key_b), np.zeros((0, self.robot.nc)), math.inf))
        finally:
            for n in list(self._contact):        # temporary ends (`_attach_contact`)
                self._remove_node(n)
            self.stats.query_time += time.perf_counter() - t0
        self.library.put(key_a, key_b, sol)
        return sol

    def query(self, a, b) -> Solution:
        """Path between two end-effector positions (cost inf and an empty path if none)."""
        a, b = np.asarray(a, dtype=float).ravel(), np.asarray(b, dtype=float).ravel()
        return self._solve(self.library.end("x", a), self.library.end("x", b),
                           lambda: self.attach_position(a), lambda: self.attach_position(b))

    def query_configs(self, qa, qb) -> Solution:
        """Path between two configurations (used to warm-start trajectories)."""
        qa, qb = np.asarray(qa, dtype=float).ravel(), np.asarray(qb, dtype=float).ravel()
        return self._solve(self.library.end("q", qa), self.library.end("q", qb),
                           lambda: self.attach_config(qa), lambda: self.attach_config(qb))

    def query_from_config(self, q, x) -> Solution:
        """Path from a configuration (e.g. the robot's home at the start of a plan) to a position."""
        q, x = np.asarray(q, dtype=float).ravel(), np.asarray(x, dtype=float).ravel()
        return self._solve(self.library.end("q", q), self.library.end("x", x),
                           lambda: self.attach_config(q), lambda: self.attach_position(x))

    def path(self, from_position, to_position) -> tuple[float, np.ndarray]:
        """(cost, waypoints in joint space, n x nq) of the cheapest collision-checked path between
        two end-effector positions; (inf, empty array) if an end is unreachable or disconnected."""
        sol = self.query(from_position, to_position)
        return sol.cost, sol.path

    def travel_cost(self, a, b) -> float:
        """Heuristic cost h of moving the end effector from position a to position b."""
        return self.query(a, b).cost

    # ---- inspection ------------------------------------------------------------------------------
    def nodes(self, kind: str | None = None) -> list[int]:
        return [n for n, k in self.G.nodes(data="kind") if kind is None or k == kind]

    def summary(self) -> str:
        v = self.stats.validation
        return (f"reachability graph {self.robot.name}/{self.frame}: {self.G.number_of_nodes()} nodes "
                f"({self.num_samples} samples from {self.stats.draws} draws, IK success {v.success_rate:.0%}), "
                f"{self.G.number_of_edges()} edges ({sum(1 for *_, c in self.G.edges(data='checked') if c)} checked, "
                f"{self.stats.edges_removed} removed), built in {self.stats.build_time:.2f} s")
