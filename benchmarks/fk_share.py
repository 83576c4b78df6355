"""How much of the keyframe NLP's constraint rows and Jacobian is forward kinematics (issue 20).

Question: every template instance that uses an arm's frames (`clear_gripper`, `self_clear`,
`grasp`, `kin_switch_rel`) computes that arm's kinematic chain itself, in its rows (g) and in
its Jacobian (forward chain and reverse sweep), although a keyframe NLP has only a few robot
configurations. What would one forward-kinematics evaluation per configuration, shared by the
templates, save?

For each such template of `bench_komo.py`'s keyframe NLP (seed 0) this lowers the body twice:
as the compiler does, and with every frame (R, p) a free input (what a template would compute
if the frames came from a shared FK Function). It prints, per template and in all (weighted by
the number of instances): SX instructions and casadi virtual-machine time of the Jacobian with
respect to the slots (the open form, plus the distance queries' inputs, `stops`) and of the
rows; the same with free frames; the chain rule such a template would need to return dh/dq
(each nonzero of dh/dF times the 7 columns of dF/dq, a multiply and an add); and the shared
FK of every link of the arm with its Jacobian, once per configuration.

    PYTHONPATH=$PWD python benchmarks/fk_share.py
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
import bench_komo as bk  # noqa: E402


class FreeFrames:
    """The geometry, with every frame the lowering asks for a fresh (R, p) symbol pair."""

    def __init__(self, geometry) -> None:
        self.geometry = geometry
        self.frames: list[tuple] = []

    def __getattr__(self, k):
        return getattr(self.geometry, k)

    def _sym(self):
        i = len(self.frames)
        R, p = ca.SX.sym(f"R{i}", 3, 3), ca.SX.sym(f"p{i}", 3)
        self.frames.append((R, p))
        return R, p

    def fk_chain(self, robot, q, base):
        me = self

        class Chain:
            def frame(self, frame):
                return me._sym()
        return Chain()

    def fk_rp(self, robot, q, frame, base):
        return self._sym()

    def fk(self, robot, q, frame, base):
        from gnppdsl.geometry.kinematics import rp_to_se3_vec
        return rp_to_se3_vec(*self._sym())


def lowered(factor, geometry):
    from gnppdsl.nlp.lowering import BodyLowering, SlotSignature, constraint_rows, lift_constants
    sigs = tuple(SlotSignature.of(v) for v in factor.variables)
    body, lifted = lift_constants(factor.body)
    slots = [ca.SX.sym(f"x{j}", s.dim) for j, s in enumerate(sigs)]
    p = ca.SX.sym("p", len(lifted))
    b = BodyLowering(slots, sigs, p, geometry, open_stops=True)
    b.plan_chains(body)
    out = ca.vertcat(*[constraint_rows(b, c) for c in body])
    O = ca.vertcat(*[o for o, _ in b.stops]) if b.stops else ca.SX(0, 1)
    stop_in = ca.vertcat(*b.stop_inputs) if b.stops else ca.SX(0, 1)
    return slots, p, out, O, stop_in


def vm_us(fn: ca.Function, M: int = 300) -> float:
    """Virtual-machine time of one call (a mapped call of M, best of 3; random inputs)."""
    rng = np.random.default_rng(0)
    m = fn.map(M, "serial")
    args = [np.tile(rng.uniform(-1, 1, (fn.size1_in(i), 1)), (1, M)) for i in range(fn.n_in())]
    m(*args)
    best = np.inf
    for _ in range(3):
        t0 = time.process_time()
        m(*args)
        best = min(best, (time.process_time() - t0) / M * 1e6)
    return best


def measure(slots, p, out, O, stop_in, frames=()) -> dict:
    from gnppdsl.nlp.body_compiler import sx_jacobian
    F = [ca.vertcat(ca.vec(R), q) for R, q in frames]
    X = ca.vertcat(*slots, *F)
    ins = [*slots, p, O, *F]
    J = sx_jacobian(out, X, [p, O])
    jac = ca.Function("rows_jac", ins, [J])
    stops = ca.Function("stops", [*slots, p, *F], [stop_in])
    rows = ca.Function("rows", ins, [out])
    chain = 0
    if F:
        rr, cc = J.sparsity().get_triplet()
        n_x = sum(s.numel() for s in slots)
        chain = 2 * 7 * sum(1 for c in cc if c >= n_x)       # each nonzero of dh/dF x 7 columns
    return {"jac": jac.n_instructions() + stops.n_instructions(), "rows": rows.n_instructions(),
            "jac_us": vm_us(jac) + vm_us(stops), "rows_us": vm_us(rows), "chain": chain,
            "frames": len(F)}


def main() -> int:
    from gnppdsl import load_and_compile
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.solve.plan_graph import plan_graph
    c = load_and_compile([str(bk.LAB / "domain.pntc"), str(bk.write_problem(Path(tempfile.mkdtemp()), 0))])
    compiler = c.body_compiler("off")
    g = plan_graph(c.factory, plan_states(c.task, parse_plan(c.task, bk.PLAN)))
    modes = g.subgraph(variables=[v for v in g.variables if not v.waypoints], suffix="{modes}")
    seen: dict[int, tuple] = {}
    count: dict[int, int] = {}
    for _, f in modes.iter_factors():
        cb, _ = compiler.compile(f)
        if "fk" not in cb.primitives:
            continue
        count[id(cb)] = count.get(id(cb), 0) + 1
        if id(cb) not in seen:
            ff = FreeFrames(c.geometry)
            free = lowered(f, ff)
            seen[id(cb)] = (cb.name, measure(*lowered(f, c.geometry)), measure(*free, ff.frames))
    tot = {k: 0.0 for k in ("jac", "rows", "jac_us", "rows_us", "jac_free", "rows_free",
                            "jac_free_us", "rows_free_us", "chain")}
    print(f"{'template':32s} {'k':>2s} {'jac instr':>10s} {'free':>6s} {'chain':>6s} "
          f"{'jac us':>7s} {'free':>6s} {'rows instr':>10s} {'free':>6s}")
    for key, (name, a, b) in seen.items():
        k = count[key]
        print(f"{name:32s} {k:2d} {a['jac']:10d} {b['jac']:6d} {b['chain']:6d} {a['jac_us']:7.1f} "
              f"{b['jac_us']:6.1f} {a['rows']:10d} {b['rows']:6d}")
        for n, v in (("jac", a["jac"]), ("rows", a["rows"]), ("jac_us", a["jac_us"]),
                     ("rows_us", a["rows_us"]), ("jac_free", b["jac"]), ("rows_free", b["rows"]),
                     ("jac_free_us", b["jac_us"]), ("rows_free_us", b["rows_us"]),
                     ("chain", b["chain"])):
            tot[n] += k * v
    # the shared part: every link of the arm and its Jacobian, once per configuration
    q, base = ca.SX.sym("q", 7), ca.SX.sym("base", 7)
    chain = c.geometry.fk_chain("arm", q, base)
    fk = ca.vertcat(*[ca.vertcat(ca.vec(R), p) for R, p in map(chain.frame, c.geometry.links("arm"))])
    shared_fk = ca.Function("fk", [q, base], [fk])
    shared_jac = ca.Function("fk_jac", [q, base], [ca.jacobian(fk, q)])
    n_conf = sum(1 for v in modes.variables if v.kind == "q")
    print(f"shared FK per configuration ({n_conf}): rows {shared_fk.n_instructions()} instr "
          f"{vm_us(shared_fk):.1f} us, Jacobian {shared_jac.n_instructions()} instr {vm_us(shared_jac):.1f} us")
    print(f"in all (instances weighted): Jacobian {tot['jac']:.0f} instr {tot['jac_us']:.0f} us -> "
          f"free frames {tot['jac_free']:.0f} instr {tot['jac_free_us']:.0f} us + chain rule "
          f"{tot['chain']:.0f} + shared {n_conf * (shared_fk.n_instructions() + shared_jac.n_instructions())} instr; "
          f"rows {tot['rows']:.0f} instr {tot['rows_us']:.0f} us -> free frames {tot['rows_free']:.0f} "
          f"instr {tot['rows_free_us']:.0f} us + shared {n_conf * shared_fk.n_instructions()} instr")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
