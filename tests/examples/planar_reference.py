"""An independent reference model of examples/planar (domain planar_blocks).

Why: expected.yaml records N0 and N for each planar problem, and other helpers' tests (planner,
brute force, benchmarks) rely on those numbers. This module re-derives them WITHOUT the gnppdsl
front end or compiler: the logic of the domain is hand-coded (pick / place / handover), the
problem and scene files are read with a few regular expressions and yaml, and the graph-NLP of
a plan is written directly in casadi from the semantics documented in examples/README.md
(keyframe per step, relative poses, time consistency, kinematic switch, grasp, inside,
no_overlap, reach box, home). A plan is feasible if an elastic NLP (slack on every constraint)
reaches zero slack from one of several starts.
"""
from __future__ import annotations

import itertools
import math
import re
from dataclasses import dataclass
from pathlib import Path

import yaml

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


def raw_scene(path: Path) -> dict:
    """A scene YAML as plain data with its `include:`s merged (robots and objects of the
    included files first), read with PyYAML alone: the tests compare the files' numbers with
    the paper's without going through the project's loader."""
    data = yaml.safe_load(Path(path).read_text()) or {}
    inc = data.pop("include", [])
    merged: dict = {"robots": {}, "objects": {}}
    for rel in [inc] if isinstance(inc, str) else inc:
        sub = raw_scene(Path(path).parent / rel)
        for key in ("robots", "objects"):
            merged[key].update(sub.pop(key, {}) or {})
        merged.update({k: v for k, v in sub.items() if k not in merged})
    for key in ("robots", "objects"):
        merged[key].update(data.pop(key, {}) or {})
    merged.update(data)
    return merged
PLANAR = EXAMPLES / "planar"
GRASP_TOL = 0.01          # stdlib/planar.pntc: const grasp_tol


# ----------------------------------------------------------------------------------- files
@dataclass
class PlanarProblem:
    name: str
    objects: dict[str, str]                  # object -> type
    init: dict[str, str]                     # "parent(b1)" -> "s1"
    goal: dict[str, str]
    scene: dict
    max_horizon: int | None

    def of_type(self, t: str) -> list[str]:
        return [o for o, ty in self.objects.items() if ty == t]


def _section(text: str, name: str) -> str:
    m = re.search(rf"\b{name}\s*\{{([^}}]*)\}}", text)
    return m.group(1) if m else ""


def read_problem(path: Path) -> PlanarProblem:
    text = re.sub(r"#[^\n]*", "", path.read_text())
    name = re.search(r"\bproblem\s+(\w+)", text).group(1)
    scene_file = re.search(r'\bscene\s+"([^"]+)"', text).group(1)
    objects: dict[str, str] = {}
    for names, ty in re.findall(r"([\w\s,]+?)\s*:\s*(\w+)", _section(text, "objects")):
        for n in names.replace(",", " ").split():
            objects[n] = ty
    lits = lambda sec: dict(re.findall(r"(\w+\(\w+\))\s*=\s*(\w+)", _section(text, sec)))
    mh = re.search(r"max_horizon\s*=\s*(\d+)", _section(text, "solver"))
    scene = yaml.safe_load((path.parent / scene_file).read_text())
    return PlanarProblem(name, objects, lits("init"), lits("goal"), scene,
                         int(mh.group(1)) if mh else None)


def expected_comment(path: Path) -> tuple[int, int | None]:
    """The `# expect: N0 = a, N = b` line of a problem file."""
    m = re.search(r"#\s*expect:\s*N0\s*=\s*(\d+)\s*,\s*N\s*=\s*(\w+)", path.read_text())
    assert m, f"{path}: no '# expect: N0 = .., N = ..' comment"
    return int(m.group(1)), (None if m.group(2) == "none" else int(m.group(2)))


# ----------------------------------------------------------------------------------- logic
State = tuple  # (parents: tuple[str, ...] per block, holding: tuple[str, ...] per gripper)


class Logic:
    """The SAS+ semantics of domain planar_blocks, hand-coded."""

    def __init__(self, p: PlanarProblem):
        self.p = p
        self.blocks = p.of_type("block")
        self.grippers = p.of_type("gripper")
        self.regions = p.of_type("region")
        self.places = p.of_type("spot") + self.regions

    def initial(self) -> State:
        par = tuple(self.p.init[f"parent({b})"] for b in self.blocks)
        hold = tuple(self.p.init.get(f"holding({g})", "none") for g in self.grippers)
        return (par, hold)

    def is_goal(self, s: State) -> bool:
        par, hold = s
        val = {f"parent({b})": v for b, v in zip(self.blocks, par)}
        val.update({f"holding({g})": v for g, v in zip(self.grippers, hold)})
        return all(val[k] == v for k, v in self.p.goal.items())

    def successors(self, s: State):
        par, hold = s
        for bi, b in enumerate(self.blocks):
            for gi, g in enumerate(self.grippers):
                if par[bi] in self.places and hold[gi] == "none":            # pick(b, g, from)
                    yield (("pick", b, g, par[bi]), self._set(s, bi, g, {gi: b}))
                if par[bi] == g:
                    for r in self.regions:                                   # place(b, g, r)
                        yield (("place", b, g, r), self._set(s, bi, r, {gi: "none"}))
                    for hi, h in enumerate(self.grippers):                   # handover(b, g, h)
                        if h != g and hold[hi] == "none":
                            yield (("handover", b, g, h), self._set(s, bi, h, {gi: "none", hi: b}))

    @staticmethod
    def _set(s: State, bi: int, parent: str, hold_changes: dict[int, str]) -> State:
        par, hold = list(s[0]), list(s[1])
        par[bi] = parent
        for k, v in hold_changes.items():
            hold[k] = v
        return (tuple(par), tuple(hold))

    def shortest_length(self, limit: int = 20) -> int | None:
        """Breadth-first search: N0."""
        frontier, seen = [self.initial()], {self.initial()}
        for depth in range(limit + 1):
            if any(self.is_goal(s) for s in frontier):
                return depth
            nxt = []
            for s in frontier:
                for _, t in self.successors(s):
                    if t not in seen:
                        seen.add(t)
                        nxt.append(t)
            frontier = nxt
        return None

    def plans(self, length: int):
        """All action sequences of exactly `length` that end in a goal state (with states)."""
        def rec(s, acts, states):
            if len(acts) == length:
                if self.is_goal(s):
                    yield list(acts), list(states)
                return
            for a, t in self.successors(s):
                yield from rec(t, acts + [a], states + [t])
        s0 = self.initial()
        yield from rec(s0, [], [s0])


# ----------------------------------------------------------------------------------- geometry
def plan_graph(p: PlanarProblem, states: list[State]):
    """The graph-NLP of a state sequence, written from examples/README.md's semantics:
    (variables {("pose", block, i) | ("q", gripper, i): SX[3]}, stacked x, h (== 0), g (<= 0))."""
    import casadi as ca

    lg = Logic(p)
    sc = p.scene
    n = len(states) - 1
    objs, robots = sc["objects"], sc["robots"]

    def frame_pose(name):
        pz = objs[name]["pose"]
        return [float(v) for v in pz]

    opti_vars = []
    pose = {}     # (block, i) -> SX[3]
    q = {}
    for i in range(n + 1):
        for b in lg.blocks:
            pose[b, i] = ca.SX.sym(f"pose_{b}_{i}", 3)
            opti_vars.append(pose[b, i])
        for g in lg.grippers:
            q[g, i] = ca.SX.sym(f"q_{g}_{i}", 3)
            opti_vars.append(q[g, i])

    def compose(a, b):
        c, s = ca.cos(a[2]), ca.sin(a[2])
        return ca.vertcat(a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2])

    def inv(a):
        c, s = ca.cos(a[2]), ca.sin(a[2])
        return ca.vertcat(-c * a[0] - s * a[1], s * a[0] - c * a[1], -a[2])

    def parent_of(b, i):
        return states[i][0][lg.blocks.index(b)]

    def world(x, i):
        if x in lg.grippers:
            return q[x, i]
        if x in lg.blocks:
            return compose(world(parent_of(x, i), i), pose[x, i])
        return ca.DM(frame_pose(x))

    eq, ineq = [], []       # eq: h == 0 ; ineq: g <= 0
    for g in lg.grippers:
        rob = robots[g]
        eq.append(q[g, 0] - ca.DM(rob["home"]))
        for i in range(n + 1):
            ineq.append(ca.DM(rob["reach_min"]) - q[g, i][:2])
            ineq.append(q[g, i][:2] - ca.DM(rob["reach_max"]))
    for i in range(n + 1):
        for b in lg.blocks:
            par = parent_of(b, i)
            if p.objects.get(par) == "spot":
                eq.append(pose[b, i])
            if par in lg.grippers:
                rel = compose(inv(world(par, i)), world(b, i))
                ineq.append(ca.sumsqr(rel[:2]) - GRASP_TOL ** 2)
            if p.objects.get(par) == "region":
                rel = compose(inv(world(par, i)), world(b, i))[:2]
                he = ca.DM(objs[par]["half_extent"])
                r = float(objs[b]["radius"])
                ineq.append(rel - (he - r))
                ineq.append((r - he) - rel)
        for a, c in itertools.combinations(lg.blocks, 2):
            ra, rc = float(objs[a]["radius"]), float(objs[c]["radius"])
            d = world(a, i)[:2] - world(c, i)[:2]
            ineq.append((ra + rc) ** 2 - ca.sumsqr(d))
    for i in range(n):
        for b in lg.blocks:
            p0, p1 = parent_of(b, i), parent_of(b, i + 1)
            if p0 == p1:
                eq.append(pose[b, i + 1] - pose[b, i])
            else:
                new = world(b, i + 1)
                old = compose(world(p0, i + 1), compose(inv(world(p0, i)), world(b, i)))
                eq.append(new - old)

    x = ca.vertcat(*opti_vars)
    h = ca.vertcat(*eq) if eq else ca.DM.zeros(0)
    gi = ca.vertcat(*ineq) if ineq else ca.DM.zeros(0)
    named = {("pose", b, i): pose[b, i] for (b, i) in pose} | {("q", g, i): q[g, i] for (g, i) in q}
    return named, opti_vars, x, h, gi


def states_of_plan(p: PlanarProblem, actions: list[str]) -> list[State]:
    """The state sequence of a plan given as `pick(b1, g, s1)` strings, by the hand-coded logic
    (a step that is not applicable raises: the plan is invalid)."""
    lg = Logic(p)
    s = lg.initial()
    out = [s]
    for text in actions:
        name, args = re.fullmatch(r"\s*(\w+)\((.*)\)\s*", text).groups()
        want = (name, *[a.strip() for a in args.split(",")])
        nxt = [t for a, t in lg.successors(s) if a == want]
        assert nxt, f"{text} is not applicable in {s}"
        s = nxt[0]
        out.append(s)
    assert lg.is_goal(s), f"the plan ends in {s}, not a goal state"
    return out


def solution_violation(p: PlanarProblem, actions: list[str], values: dict) -> float:
    """Max violation of the reference graph-NLP of `actions` at `values`
    ({("pose"|"q", object, step): [x, y, theta]}): a solution check that shares nothing with
    the project's factory, compiler or evaluator."""
    import casadi as ca
    import numpy as np

    named, opti_vars, x, h, gi = plan_graph(p, states_of_plan(p, actions))
    order = {id(v): k for k, v in enumerate(opti_vars)}
    xs = np.zeros(x.shape[0])
    offsets = np.cumsum([0] + [v.shape[0] for v in opti_vars])
    for key, sym in named.items():
        k = order[id(sym)]
        assert key in values, f"no value for {key}"
        xs[offsets[k]:offsets[k + 1]] = np.asarray(values[key], float).reshape(-1)
    hv, gv = (np.array(v).ravel() for v in ca.Function("f", [x], [h, gi])(xs))
    return float(max([0.0] + list(np.abs(hv)) + list(np.maximum(gv, 0.0))))


def plan_feasible(p: PlanarProblem, states: list[State], starts: int = 3, seed: int = 0) -> bool:
    """Is the graph-NLP of this state sequence feasible? (elastic NLP, multi-start)"""
    import casadi as ca
    import numpy as np

    _, _, x, h, gi = plan_graph(p, states)
    ne, ni = h.shape[0], gi.shape[0]
    sp = ca.SX.sym("sp", ne)
    sm = ca.SX.sym("sm", ne)
    si = ca.SX.sym("si", ni)
    z = ca.vertcat(x, sp, sm, si)
    cons = ca.vertcat(h - sp + sm, gi - si)
    obj = ca.sum1(sp) + ca.sum1(sm) + ca.sum1(si) + 1e-6 * ca.sumsqr(x)
    solver = ca.nlpsol("s", "ipopt", {"x": z, "f": obj, "g": cons},
                       {"ipopt.print_level": 0, "print_time": False, "ipopt.sb": "yes",
                        "ipopt.max_iter": 500, "ipopt.tol": 1e-10})
    nx = x.shape[0]
    lbz = [-math.inf] * nx + [0.0] * (2 * ne + ni)
    lbg = [0.0] * ne + [-math.inf] * ni
    ubg = [0.0] * (ne + ni)
    rng = np.random.default_rng(seed)
    for k in range(starts):
        x0 = rng.uniform(-1, 1, nx) if k else np.zeros(nx)
        sol = solver(x0=np.concatenate([x0, np.zeros(2 * ne + ni)]), lbx=lbz, lbg=lbg, ubg=ubg)
        zsol = np.array(sol["x"]).ravel()
        xs = zsol[:nx]
        f = ca.Function("f", [x], [h, gi])
        hv, gv = (np.array(v).ravel() for v in f(xs))
        viol = max([0.0] + list(np.abs(hv)) + list(np.maximum(gv, 0.0)))
        if viol < 1e-6:
            return True
    return False


def shortest_feasible(p: PlanarProblem, lo: int, hi: int) -> tuple[int | None, dict]:
    """The smallest length L in lo..hi with a feasible logical plan, and statistics."""
    lg = Logic(p)
    stats = {"plans": 0, "feasible": 0}
    for length in range(lo, hi + 1):
        for acts, states in lg.plans(length):
            stats["plans"] += 1
            if plan_feasible(p, states):
                stats["feasible"] += 1
                stats["plan"] = acts
                return length, stats
    return None, stats
