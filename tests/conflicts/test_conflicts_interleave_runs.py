"""Runs of equal partial states in a conflict (`gnppdsl.conflicts.interleave`, "Merging" and
"Preorder chains"): which adjacent steps merge, and the sequences the conflict then forbids.

Oracle: the conflict the same situation maps to when it is held for fewer or more steps
(`to_partial_states` of hand-made factors), independent of the merging code; a stretched
instance must forbid it (each of its partial states a subset of the situation's)."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).parent))

from conflicts_fixture_factors import HOLDING, PARENT_B1, at_spot, grasp, q, same  # noqa: E402

from gnppdsl.compile.factors import FactorInstance, VarInstance  # noqa: E402
from gnppdsl.compile.sas import PartialState  # noqa: E402
from gnppdsl.conflicts.interleave import LIMIT, merged, stretched  # noqa: E402
from gnppdsl.conflicts.mapping import to_partial_states  # noqa: E402
from gnppdsl.ir.expr import Call, Constraint, Num, Slot  # noqa: E402

B = PartialState.of({PARENT_B1: 2, HOLDING: 1})


def _held_for(n: int) -> list[FactorInstance]:
    """b1 on spot 0 at step 0, held by g for n steps (its pose the same along them: `same`),
    on spot 1 at step n + 1: the shape of 'arm_s holds the stick with b1 on its tip while
    another arm acts'."""
    fs = [at_spot("b1", 0, (0.0, 0.0), PARENT_B1, 0)]
    fs += [grasp("b1", s, PARENT_B1, 1) for s in range(1, n + 1)]
    fs += [same("b1", s, 2) for s in range(1, n)]
    fs += [at_spot("b1", n + 1, (1.0, 0.0), PARENT_B1, 1)]
    return fs


def _step_limit(step: int) -> FactorInstance:
    """|q@step - q@step+1| <= 0.1 between two held steps: not an equality."""
    return FactorInstance(
        template="planar.step", rule="motion", bindings=(), tags=frozenset({"time"}), step=step, span=2,
        generator=(B, B), variables=(q(step), q(step + 1)),
        body=(Constraint(Call("norm", (Call("sub", (Slot(0), Slot(1))),)), "<=", Num(0.1)),))


def _forbids(instance, situation) -> bool:
    """Would the conflict `instance` forbid a plan whose states are `situation`'s (same length,
    each partial state of the instance within the situation's)?"""
    return len(instance) == len(situation) and all(set(a.facts) <= set(b.facts) for a, b in zip(instance, situation))


def test_a_run_tied_by_equalities_merges_to_one_step_and_is_learned_for_every_length_that_fits():
    fs = _held_for(3)
    seq = to_partial_states(fs)
    assert seq[1] == seq[2] == seq[3] == B and len(seq) == 5
    shapes = [to_partial_states(m) for m in merged(fs)]
    assert shapes == [seq, to_partial_states(_held_for(2)), to_partial_states(_held_for(1))]
    out = stretched(fs, max_length=8)
    assert out[0] == seq
    for n in range(1, 7):            # 7 would be 9 states long
        situation = to_partial_states(_held_for(n))
        assert any(_forbids(s, situation) for s in out), n
    assert all(len(s) <= 8 for s in out)


def test_a_run_with_another_factor_between_its_steps_is_not_merged():
    # a bounded move per step: three steps reach 0.2 where one reaches nothing (not sound)
    fs = _held_for(3) + [_step_limit(1), _step_limit(2)]
    assert merged(fs) == [tuple(fs)]
    shorter = to_partial_states(_held_for(1))
    assert not any(_forbids(s, shorter) for s in stretched(fs, max_length=8))


def test_steps_with_a_trajectory_between_them_are_not_merged():
    fs = _held_for(3)
    path = VarInstance("path", ("g",), 1, "SE2", 30, frozenset({"traj"}), waypoints=10)
    traj = FactorInstance(template="planar.path", rule="motion", bindings=(), tags=frozenset({"traj"}), step=1,
                          span=1, generator=(B,), variables=(path,),
                          body=(Constraint(Call("norm", (Slot(0),)), "<=", Num(1.0)),))
    # steps 1 and 2 stay apart (the motion from step 1 is part of M); 2 and 3 merge
    shapes = merged(fs + [traj])
    assert [len(to_partial_states(m)) for m in shapes] == [5, 4]
    assert any(v.waypoints and v.step == 1 for f in shapes[-1] for v in f.variables)


def test_unequal_adjacent_states_are_not_merged_and_the_count_is_capped():
    one = _held_for(1)
    assert merged(one) == [tuple(one)]
    assert len(stretched(_held_for(3), 1000)) == LIMIT


# ---- the standard library's preorder: tools.push_motion ---------------------------------------------
def _se3_mul(a, b):
    import pinocchio as pin
    import numpy as np

    def m(x):
        return pin.XYZQUATToSE3(np.asarray(x, float))
    return list(pin.SE3ToXYZQUAT(m(a) * m(b)))


def test_push_motion_is_reflexive_and_transitive_and_a_preorder_link():
    """The claim behind its `preorder` tag, at random poses: b1 riding on the stick arm_s holds
    (arm and stick fixed, b1's pose on the stick moved): no move holds, two forward pushes at the
    table's height hold and so does their sum, a push backwards does not. Its Work_2 factor is
    a chain link only when preorders are asked for (`stretch_conflicts`)."""
    import numpy as np

    import gnppdsl.ir as ir
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.conflicts.interleave import chain_link, preorder_link
    from gnppdsl.nlp.evaluate import max_violation
    from gnppdsl.solve.compiled import compile_problem

    root = Path(__file__).resolve().parents[2] / "examples" / "workshop"
    c = compile_problem(ir.load_problem(root / "work2.pntc"))
    plan = ("pick(stick, arm_s, table); push(b1, stick, arm_s); pick(b2, arm_w, table); "
            "take(b1, arm_n, stick); put(b1, arm_n, pad_n); put(b2, arm_w, pad_w)")
    factors = c.factory.factors(plan_states(c.task, parse_plan(c.task, plan)))
    (f,) = [f for f in factors if f.template == "tools.push_motion" and f.step == 2]
    assert preorder_link(f) and {v.key for v in f.variables} == {"q(arm_s)", "pose(stick)", "pose(b1)"}
    assert chain_link(f, preorder=True) and not chain_link(f, preorder=False)
    rng = np.random.default_rng(0)
    q = rng.uniform(-1, 1, 7)
    for _ in range(5):
        stick = [*rng.uniform(-0.1, 0.1, 3), *(lambda v: v / np.linalg.norm(v))(rng.normal(size=4))]
        b1 = [*rng.uniform(-0.1, 0.1, 3), *(lambda v: v / np.linalg.norm(v))(rng.normal(size=4))]

        def holds(p0, p1):
            point = {}
            for v in f.variables:
                point[v] = np.asarray(q if v.kind == "q" else stick if v.args == ("stick",) else
                                      (p0 if v.step == 2 else p1), float)
            return max_violation([f], point, c.geometry)[0] <= 1e-9

        def forward(p, t):
            # a translation along b1's own +y whose world displacement has no z (the table's height)
            import pinocchio as pin
            hand = c.geometry.fk_matrix("arm_s", q, c.geometry.scene.robots["arm_s"].ee)[:3, :3]
            R = hand @ pin.XYZQUATToSE3(np.asarray(stick, float)).rotation \
                @ pin.XYZQUATToSE3(np.asarray(p, float)).rotation
            return _se3_mul(p, [0, t, -R[2, 1] * t / R[2, 2], 0, 0, 0, 1])
        one = forward(b1, rng.uniform(0.01, 0.2))
        two = forward(one, rng.uniform(0.01, 0.2))
        assert holds(b1, b1) and holds(b1, one) and holds(one, two) and holds(b1, two)
        assert not holds(one, b1)
