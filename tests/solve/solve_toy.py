"""A hand-made 1-D PNTC (task + factory) to test the loop without the language front end.

Blocks are discs of radius R on a line; `pose(b)` is the world position of b. Places: spots
(fixed points) and regions (intervals). A gripper `g` picks a block from a spot or region and
places it in a region. Factors (generator = the facts they depend on, as the real factory):
  on(b, s)       parent(b) = s                           pose(b) == x_s
  inside(b, r)   parent(b) = r                           c_r - h_r + R <= pose(b) <= c_r + h_r - R
  stay(b, P)     parent(b) = P -> parent(b) = P  (P a place)   pose(b) == pose(b)'
  apart(b1, b2)  always                                  (pose(b1) - pose(b2))^2 >= (2R)^2
Region `target` fits one block; b2 rests on spot s2 in its middle, so the shortest logical
plan (pick b1, place b1 in target) fails geometrically: N0 = 2, N = 4 (move b2 first).
"""
from __future__ import annotations

from types import SimpleNamespace

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.compile.sas import Effect, Operator, PartialState, SASTask, SASVariable
from gnppdsl.ir.expr import Call, Constraint, Num, Slot
from gnppdsl.nlp.subgraph import Relaxation
from gnppdsl.solve.compiled import Compiled

R = 0.05


def _sub(a, b):
    return Call("sub", (a, b))


def _sq(a):
    return Call("mul", (a, a))


class ToyFactory:
    def __init__(self, task: SASTask, spots: dict[str, float], regions: dict[str, tuple[float, float]],
                 blocks: list[str]):
        self.task, self.spots, self.regions, self.blocks = task, spots, regions, blocks
        self.pvar = {b: task.var_index(f"parent({b})") for b in blocks}

    def var(self, b: str, i: int) -> VarInstance:
        return VarInstance("pose", (b,), i, "R", 1, frozenset({"object"}))

    def parent(self, s, b) -> str:
        v = self.pvar[b]
        return self.task.variables[v].values[s[v]]

    def objectives(self, states) -> list[FactorInstance]:
        """The toy domain has no `minimize` terms (GraphNLPFactory.objectives)."""
        return []

    def factors(self, states) -> list[FactorInstance]:
        out = []
        for i, s in enumerate(states):
            for b in self.blocks:
                p = self.parent(s, b)
                gen = (PartialState.of({self.pvar[b]: s[self.pvar[b]]}),)
                if p in self.spots:
                    out.append(FactorInstance("toy.on", "on", (("o", b), ("s", p)), frozenset({"place"}), i, 1, gen,
                                              (self.var(b, i),),
                                              (Constraint(Slot(0), "==", Num(self.spots[p])),)))
                elif p in self.regions:
                    c, h = self.regions[p]
                    out.append(FactorInstance("toy.inside", "inside", (("o", b), ("r", p)), frozenset({"place"}), i,
                                              1, gen, (self.var(b, i),),
                                              (Constraint(Slot(0), "<=", Num(c + h - R)),
                                               Constraint(Slot(0), ">=", Num(c - h + R)))))
                if i + 1 < len(states) and p != "g" and self.parent(states[i + 1], b) == p:
                    out.append(FactorInstance("toy.same", "stay", (("o", b), ("P", p)), frozenset({"time"}), i, 2,
                                              (gen[0], gen[0]), (self.var(b, i), self.var(b, i + 1)),
                                              (Constraint(Slot(0), "==", Slot(1)),)))
            for a in self.blocks:
                for b in self.blocks:
                    if a < b:
                        out.append(FactorInstance("toy.apart", "apart", (("a", a), ("b", b)),
                                                  frozenset({"collision"}), i, 1, (PartialState(),),
                                                  (self.var(a, i), self.var(b, i)),
                                                  (Constraint(_sq(_sub(Slot(0), Slot(1))), ">=",
                                                              Num((2 * R) ** 2)),)))
        if self.waypoints:
            out += self.traj_factors(states)
        return out

    def variables(self, states) -> list[VarInstance]:
        out = [self.var(b, i) for i in range(len(states)) for b in self.blocks]
        if self.waypoints:
            out += [self.path(b, i) for i in range(len(states) - 1) for b in self.blocks]
        return out

    # ---- optional trajectories: path(b)@i moves pose(b)@i to pose(b)@i+1 in bounded steps ----
    waypoints = 0
    max_step = 0.3

    def path(self, b: str, i: int) -> VarInstance:
        return VarInstance("path", (b,), i, "R", self.waypoints, frozenset({"traj"}), waypoints=self.waypoints)

    def traj_factors(self, states) -> list[FactorInstance]:
        out = []
        W = self.waypoints
        for i in range(len(states) - 1):
            for b in self.blocks:
                gen = (PartialState(), PartialState())
                wp = lambda k: Call("waypoint", (Slot(0), Num(k)))
                out.append(FactorInstance("toy.ends", "ends", (("o", b),), frozenset({"traj"}), i, 2, gen,
                                          (self.path(b, i), self.var(b, i), self.var(b, i + 1)),
                                          (Constraint(wp(0), "==", Slot(1)), Constraint(wp(W - 1), "==", Slot(2)))))
                out.append(FactorInstance("toy.smooth", "smooth", (("o", b),), frozenset({"traj"}), i, 1,
                                          (PartialState(),), (self.path(b, i),),
                                          tuple(Constraint(_sq(_sub(wp(k + 1), wp(k))), "<=", Num(self.max_step ** 2))
                                                for k in range(W - 1))))
        return out

    def initial_guess(self, v: VarInstance, states=None):
        return None


def toy_task(blocks, spots, regions, init: dict[str, str], goal: dict[str, str]) -> SASTask:
    places = list(spots) + list(regions)
    variables = [SASVariable(f"parent({b})", tuple(places + ["g"])) for b in blocks]
    variables.append(SASVariable("holding(g)", tuple(["none"] + blocks)))
    H = len(blocks)

    def val(v, x):
        return variables[v].values.index(x)

    ops = []
    for bi, b in enumerate(blocks):
        for p in places:
            ops.append(Operator(f"pick({b}, g, {p})", ((bi, val(bi, p)), (H, 0)),
                                (Effect(bi, val(bi, "g")), Effect(H, val(H, b)))))
        for r in regions:
            ops.append(Operator(f"place({b}, g, {r})", ((bi, val(bi, "g")),),
                                (Effect(bi, val(bi, r)), Effect(H, 0))))
    initial = tuple([val(i, init[b]) for i, b in enumerate(blocks)] + [0])
    g = PartialState.of({blocks.index(b): val(blocks.index(b), x) for b, x in goal.items()})
    return SASTask(variables, initial, g, ops, name="toy")


def occupied_problem(name: str = "toy_occupied", target_half: float = 0.06, waypoints: int = 0) -> Compiled:
    blocks = ["b1", "b2"]
    spots = {"s1": 0.0, "s2": 1.0}
    regions = {"target": (1.0, target_half), "side": (2.0, 0.3)}
    task = toy_task(blocks, spots, regions, {"b1": "s1", "b2": "s2"}, {"b1": "target"})
    factory = ToyFactory(task, spots, regions, blocks)
    factory.waypoints = waypoints
    problem = SimpleNamespace(name=name, domain=SimpleNamespace(name="toy"), settings=None)
    relax = (Relaxation.of("no_col_traj", {"collision", "traj"}), Relaxation.of("no_time_traj", {"time", "traj"}),
             Relaxation.of("no_traj", {"traj"}))
    return Compiled(problem, task, factory, None, relax, fingerprint="toy-v1")


def unsolvable_problem() -> Compiled:
    """The goal region is narrower than a block: no plan is geometrically feasible."""
    blocks = ["b1"]
    spots = {"s1": 0.0}
    regions = {"slot": (1.0, 0.03)}
    task = toy_task(blocks, spots, regions, {"b1": "s1"}, {"b1": "slot"})
    problem = SimpleNamespace(name="toy_unsolvable", domain=SimpleNamespace(name="toy"), settings=None)
    return Compiled(problem, task, ToyFactory(task, spots, regions, blocks),
                    None, (Relaxation.of("no_col", {"collision"}),), fingerprint="toy-v1")
