"""Hand-built stage-2 factor instances for planar toy problems (tests of gnppdsl.nlp only).

Each builder returns FactorInstances exactly as the factory would: bodies with Slot/Num/Call,
tags, steps and a generator of partial states (fact (var, value) pairs chosen per toy)."""
from __future__ import annotations

import math

import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.ir.expr import Call, Constraint, Index, Num, Obj, Slot, Str, Vec
from gnppdsl.nlp.geometry_protocol import Body
from gnppdsl.nlp.graph import GraphNLP


def C(fn, *args):
    return Call(fn, tuple(args))


def pose(obj: str, step: int, tags=("object",)) -> VarInstance:
    return VarInstance("pose", (obj,), step, "SE2", 3, frozenset(tags))


def factor(template, variables, body, step, tags=(), span=1, rule=None, gen=()):
    return FactorInstance(template=template, rule=rule or template.split(".")[-1],
                          bindings=tuple((f"a{i}", v.args[0] if v.args else v.kind)
                                         for i, v in enumerate(variables)),
                          tags=frozenset(tags), step=step, span=span,
                          generator=tuple(PartialState.of(g) for g in gen) or
                          tuple(PartialState() for _ in range(span)),
                          variables=tuple(variables), body=tuple(body))


def in_box(v: VarInstance, c: float, step: int, tags=("region",)) -> FactorInstance:
    """Centre of v inside [-c, c]^2: |x| <= c, |y| <= c written with abs (a real template)."""
    p = C("pos_se2", Slot(0))
    body = [Constraint(C("abs", Index(p, Num(0))), "<=", Num(c)),
            Constraint(C("abs", Index(p, Num(1))), "<=", Num(c))]
    return factor("toy.in_box", [v], body, step, tags)


def no_overlap(a: VarInstance, b: VarInstance, ra: float, rb: float, step: int,
               tags=("collision",)) -> FactorInstance:
    d = C("norm", C("sub", C("pos_se2", Slot(0)), C("pos_se2", Slot(1))))
    return factor("toy.no_overlap", [a, b], [Constraint(d, ">=", C("add", Num(ra), Num(rb)))],
                  step, tags)


def discs(n: int, c: float = 0.8, r: float = 1.0):
    """n discs of radius r with centres in [-c, c]^2 that must not overlap (one step)."""
    vs = [pose(f"b{i}", 0) for i in range(n)]
    fs = [in_box(v, c, 0) for v in vs]
    fs += [no_overlap(vs[i], vs[j], r, r, 0) for i in range(n) for j in range(i + 1, n)]
    return vs, fs


def chain(n_steps: int, conflict_at: int | None = 3):
    """One block moving along x over steps 0..n; transitions limit |dx| <= 0.5 at the conflict
    step and <= 10 elsewhere; the block must be at x <= 0 at `conflict_at` and x >= 1 at the
    next step (|dx| written as two rows: `abs` is nonsmooth and slows ipopt down a lot on
    chains, measured 10x more iterations). Only steps conflict_at..conflict_at+1 are jointly infeasible. Extra factors keep
    the graph connected (angle pinned, y pinned) so time slicing has work to do."""
    vs = [pose("b", i) for i in range(n_steps + 1)]
    fs = [factor("toy.start", [vs[0]], [Constraint(Slot(0), "==", Vec((Num(-3.0), Num(0.0), Num(0.0))))],
                 0, ("init",), gen=[[(0, 0)]])]
    for i in range(n_steps):
        lim = 0.5 if i == conflict_at else 10.0
        dx = C("sub", Index(Slot(1), Num(0)), Index(Slot(0), Num(0)))
        body = [Constraint(dx, "<=", Num(lim)), Constraint(C("neg", dx), "<=", Num(lim)),
                Constraint(Index(Slot(1), Num(1)), "==", Index(Slot(0), Num(1))),
                Constraint(C("angle_diff", Index(Slot(1), Num(2)), Index(Slot(0), Num(2))), "==", Num(0.0))]
        fs.append(factor("toy.move", [vs[i], vs[i + 1]], body, i, ("time",), span=2,
                         gen=[[(1, i)], [(1, i + 1)]]))
    if conflict_at is not None:
        fs.append(factor("toy.left", [vs[conflict_at]],
                         [Constraint(Index(Slot(0), Num(0)), "<=", Num(0.0))], conflict_at,
                         gen=[[(2, 0)]]))
        fs.append(factor("toy.right", [vs[conflict_at + 1]],
                         [Constraint(Index(Slot(0), Num(0)), ">=", Num(1.0))], conflict_at + 1,
                         gen=[[(2, 1)]]))
    return vs, fs


class DiscGeometry:
    """Analytic test stand-in for gnppdsl.geometry: every body is a disc (2D) or a sphere (3D)
    whose radius is given per name; fk is a planar 2-link arm for robot "arm2"."""

    def __init__(self, radii: dict[str, float], link_lengths=(1.0, 1.0)):
        self.radii, self.l = radii, link_lengths

    def needs_mx(self, primitive: str) -> bool:
        return False

    def _r(self, b: Body) -> float:
        return self.radii[b.name if b.link is None else f"{b.name}/{b.link}"]

    def fk(self, robot, q, frame, base):
        import casadi as ca
        from gnppdsl.nlp.lowering import compose_se3
        l1, l2 = self.l
        x = l1 * ca.cos(q[0]) + l2 * ca.cos(q[0] + q[1])
        y = l1 * ca.sin(q[0]) + l2 * ca.sin(q[0] + q[1])
        t = q[0] + q[1]
        local = ca.vertcat(x, y, 0, 0, 0, ca.sin(t / 2), ca.cos(t / 2))
        return compose_se3(base, local)

    def fk_numeric(self, robot, q, frame, base):
        l1, l2 = self.l
        t = q[0] + q[1]
        p = np.array([l1 * math.cos(q[0]) + l2 * math.cos(t), l1 * math.sin(q[0]) + l2 * math.sin(t), 0.0])
        R = _rot_numpy(base[3:7])
        yaw = np.array([[math.cos(t), -math.sin(t), 0], [math.sin(t), math.cos(t), 0], [0, 0, 1]])
        Rw = R @ yaw
        from gnppdsl.nlp.evaluate import _quat  # matrix -> quaternion helper of the checker
        # q and -q are the same rotation: pick the sign of base_q * yaw_q like the casadi path
        bq, yq = np.asarray(base[3:7], float), np.array([0, 0, math.sin(t / 2), math.cos(t / 2)])
        like = np.concatenate([bq[3] * yq[:3] + yq[3] * bq[:3] + np.cross(bq[:3], yq[:3]),
                               [bq[3] * yq[3] - bq[:3] @ yq[:3]]])
        return np.concatenate([base[:3] + R @ p, _quat(Rw, like=like)])

    def sdist(self, a, pa, b, pb):
        import casadi as ca
        return ca.sqrt(ca.sumsqr(pa[0:3] - pb[0:3])) - self._r(a) - self._r(b)

    def sdist2(self, a, pa, b, pb):
        import casadi as ca
        return ca.sqrt(ca.sumsqr(pa[0:2] - pb[0:2])) - self._r(a) - self._r(b)

    def sdist_numeric(self, a, pa, b, pb):
        return float(np.linalg.norm(np.asarray(pa[:3]) - pb[:3])) - self._r(a) - self._r(b)

    def sdist2_numeric(self, a, pa, b, pb):
        return float(np.linalg.norm(np.asarray(pa[:2]) - pb[:2])) - self._r(a) - self._r(b)


def _rot_numpy(q):
    x, y, z, w = np.asarray(q, float) / np.linalg.norm(q)
    return np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
                     [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
                     [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)]])


def coal_boxes(n: int, c: float):
    """n planar 0.4 x 0.3 boxes (coal shapes, `sdist2` >= 0.05 pairwise) inside the square
    [-c, c]^2: (GeometryContext, factors). Needs coal."""
    from gnppdsl.geometry.context import GeometryContext
    from gnppdsl.ir.scene_model import Scene, SceneObject, SceneShape
    i7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
    objs = [SceneObject(f"b{i}", SceneShape("box", (0.4, 0.3)), i7, pose2=(0, 0, 0)) for i in range(n)]
    geo = GeometryContext(Scene("boxes", 2, {}, {o.name: o for o in objs}))
    vs = [pose(f"b{i}", 0) for i in range(n)]
    fs = [in_box(v, c, 0) for v in vs]
    fs += [factor("toy.sd", [vs[i], vs[j]],
                  [Constraint(C("sdist2", Obj(f"b{i}"), Slot(0), Obj(f"b{j}"), Slot(1)), ">=", Num(0.05))],
                  0, ("collision",))
           for i in range(n) for j in range(i + 1, n)]
    return geo, fs


# ---- a 2-link arm reaching past a disc (one FK factor, one distance factor) ----------------
ARM_GEOM = DiscGeometry({"ob": 0.3, "arm2/l1": 0.1})
ARM_Q = VarInstance("q", (), 0, "joints", 2, lower=(-3.0, -3.0), upper=(3.0, 3.0))
ARM_O = VarInstance("o", (), 0, "R3", 3)


def _pose7(x, y):
    return Vec((x, y, Num(0.0), Num(0.0), Num(0.0), Num(0.0), Num(1.0)))


_IDENTITY7 = _pose7(Num(0.0), Num(0.0))
_Q_SLOT, _O_SLOT = Slot(0), Slot(1)


def _arm_tip():
    return C("fk", Obj("arm2"), _Q_SLOT, Str("tip"), _IDENTITY7)


def arm_reach_graph() -> GraphNLP:
    """Reach a target with the arm's tip (FK equality rows, no distance) while its link keeps
    0.2 off a disc whose centre is a free variable held near a nominal place (distance row)."""
    tip = _arm_tip()
    reach = factor("toy.reach", [ARM_Q, ARM_O], [
        Constraint(Index(tip, Num(0)), "==", Num(1.2)),
        Constraint(Index(tip, Num(1)), "==", Num(0.9)),
        Constraint(C("sqnorm", C("sub", _O_SLOT, Vec((Num(1.0), Num(-0.2), Num(0.0))))), "<=", Num(0.01)),
    ], 0)
    clear = factor("toy.clear", [ARM_Q, ARM_O], [
        Constraint(C("sdist", C("link", Obj("arm2"), Str("l1")), tip, Obj("ob"),
                     _pose7(Index(_O_SLOT, Num(0)), Index(_O_SLOT, Num(1)))), ">=", Num(0.2)),
    ], 0)
    return GraphNLP([reach, clear])


# ---- the curvature options (`SolverOptions.distance_curvature` / `.kinematic_curvature`) on the arm
def arm_hessian(graph: GraphNLP, z, p, lam, **options) -> np.ndarray:
    """ipopt's Hessian of the Lagrangian of graph on ARM_GEOM (MX assembly, objective factor 1)
    at (z, p, lam), with the SolverOptions `options` (a curvature switch)."""
    from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

    s = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=0, assembly="MX", **options))
    return s.assemble(graph).solver.get_function("nlp_hess_l")(z, p, 1.0, lam).full()


def hessian_points(a, n: int = 5, seed: int = 0):
    """n random (z, p, lam) of an assembled NLP `a`: z and lam normal, p the pull's reference
    near z, a's parameters and the pull's weight."""
    rng = np.random.default_rng(seed)
    for _ in range(n):
        z = rng.normal(0.0, 0.7, a.lbx.size)
        yield z, np.concatenate([z[:a.n_x] + 0.1, a.params, [0.01]]), rng.normal(0.0, 1.0, a.lbg.size)


def arm_solved_worst(graph: GraphNLP, **options) -> float:
    """Solve graph on ARM_GEOM (one restart, seed 1) with the SolverOptions `options`; it must be
    feasible; the worst violation of its factors re-evaluated by gnppdsl.nlp.evaluate (numpy)."""
    from gnppdsl.nlp.evaluate import max_violation
    from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions

    r = FeasibilitySolver(ARM_GEOM, SolverOptions(restarts=1, assembly="MX", **options)).solve(graph, seed=1)
    assert r.feasible
    return max_violation(graph.factor_instances, r.values, ARM_GEOM)[0]
