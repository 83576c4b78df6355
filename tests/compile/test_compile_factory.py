"""The graph-NLP factory: factors, generators, variables and resolved bodies."""
from __future__ import annotations

import numpy as np
import pytest

import planar_ir
from body_eval import violation

from gnppdsl.compile.factory import GraphNLPFactory
from gnppdsl.compile.sas import PartialState
from gnppdsl.compile.semantics import parse_plan, plan_states
from gnppdsl.compile.task import build_task
from gnppdsl.errors import UserError
from gnppdsl.ir.expr import Call, Obj, Slot, Vec


def _setup(name="p1", plan="pick(b1, g, s1); place(b1, g, r1)", **kw):
    problem = planar_ir.problem(name, **kw)
    task = build_task(problem)
    states = plan_states(task, parse_plan(task, plan))
    return problem, task, GraphNLPFactory(problem, task), states


def _by_rule(factors):
    return sorted((f.rule, f.step) for f in factors)


def test_p1_factor_list():
    _, task, fac, states = _setup()
    factors = fac.factors(states)
    assert _by_rule(factors) == sorted([
        ("home", 0), ("reach", 0), ("reach", 1), ("reach", 2), ("on_spot", 0),
        ("switch", 0), ("held", 1), ("switch", 1), ("placed", 2)])
    # deterministic: same list twice, and a fresh factory gives the same
    assert factors == fac.factors(states)
    assert factors == GraphNLPFactory(fac.problem, task).factors(states)


def test_generators_include_consulted_chain_facts():
    _, task, fac, states = _setup()
    factors = {(f.rule, f.step): f for f in fac.factors(states)}
    ps = task.partial_state_str
    held = factors[("held", 1)]
    assert held.span == 1 and [ps(p) for p in held.generator] == ["{parent(b1) = g}"]
    sw = factors[("switch", 0)]
    assert sw.span == 2 and [ps(p) for p in sw.generator] == ["{parent(b1) = s1}", "{parent(b1) = g}"]
    # an `always` rule that expands no chain has an empty pattern ...
    assert factors[("reach", 2)].generator == (PartialState(),)
    # ... and `initial` is the marker fact
    assert [ps(p) for p in factors[("home", 0)].generator] == ["{initial}"]
    # every generator holds in the states it was generated from (p ⊆ s_i, p' ⊆ s_{i+1})
    for f in fac.factors(states):
        for k, p in enumerate(f.generator):
            assert p.holds_in(states[f.step + k])


def test_always_rule_over_chain_gets_chain_facts():
    # apart(b1, b2) reads world(b1), world(b2): its generator is their parents at that step
    _, task, fac, states = _setup("p2", "pick(b1, g, s1)")
    apart = [f for f in fac.factors(states) if f.rule == "apart"]
    assert [task.partial_state_str(f.generator[0]) for f in apart] == [
        "{parent(b1) = s1, parent(b2) = s2}", "{parent(b1) = g, parent(b2) = s2}"]
    # the scene radii fold into a constant: (0.05 + 0.05) ^ 2
    (c,) = apart[0].body
    assert c.op == ">=" and c.rhs.value == pytest.approx(0.01)


def test_variables_and_slots():
    _, task, fac, states = _setup()
    factors = fac.factors(states)
    variables = fac.variables(states)
    assert [v.name for v in variables] == [
        "pose(b1)@0", "q(g)@0", "pose(b1)@1", "q(g)@1", "pose(b1)@2", "q(g)@2"]
    assert all(v.dim == 3 and v.space == "SE2" for v in variables)
    sw = next(f for f in factors if f.rule == "switch" and f.step == 1)
    # kin_switch(b1, g) from 1 to 2: world(r1) * pose(b1)@2 == q(g)@2 * (inv(q(g)@1) * (q(g)@1 *
    # pose(b1)@1)); the pose of g at 1 cancels exactly, so q(g)@1 is not a variable of it
    assert sorted(v.name for v in sw.variables) == ["pose(b1)@1", "pose(b1)@2", "q(g)@2"]
    for f in factors:
        slots = _slots(f.body)
        assert slots == set(range(len(f.variables)))     # every variable used, no dangling slot
        assert not _has(f.body, ("world", "next", "radius", "home", "half_extent", "reach_min"))


def _walk(node):
    yield node
    if isinstance(node, tuple):
        for x in node:
            yield from _walk(x)
    elif hasattr(node, "__dataclass_fields__"):
        for name in node.__dataclass_fields__:
            if name != "span":
                yield from _walk(getattr(node, name))


def _slots(body):
    return {n.index for n in _walk(body) if isinstance(n, Slot)}


def _has(body, fns):
    return any(isinstance(n, Call) and n.fn in fns for n in _walk(body))


def _solution_p1():
    """A hand-made geometric solution of p1 (block moved from s1 at (-0.5, 0) to r1 at (0.5, 0))."""
    return {
        "q(g)@0": [0.0, 0.0, 0.0], "pose(b1)@0": [0.0, 0.0, 0.0],
        "q(g)@1": [-0.5, 0.0, 0.3], "pose(b1)@1": [0.0, 0.0, -0.3],   # grasped, rotated gripper
        "q(g)@2": [0.5, 0.1, 0.3], "pose(b1)@2": [0.0, 0.1, 0.0],    # released in r1
    }


def test_bodies_evaluate_to_the_template_semantics():
    _, _, fac, states = _setup()
    sol = _solution_p1()
    for f in fac.factors(states):
        values = [sol[v.name] for v in f.variables]
        for c in f.body:
            assert violation(c, values) < 1e-9, (f.label, c)
    # moving the released block out of the region violates `inside` and the kin switch
    bad = dict(sol, **{"pose(b1)@2": [0.2, 0.0, 0.0]})
    violated = {f.rule for f in fac.factors(states)
                if any(violation(c, [bad[v.name] for v in f.variables]) > 1e-6 for c in f.body)}
    assert violated == {"placed", "switch"}


def test_factor_time_invariance():
    """Property 4.2: the same generator at another time yields the same factor up to the shift."""
    problem, task, fac, _ = _setup("p2", "")
    plan = parse_plan(task, "pick(b2, g, s2); place(b2, g, ra); pick(b1, g, s1); place(b1, g, rb)")
    states = plan_states(task, plan)
    factors = fac.factors(states)
    # take the switch factor of b1 (s1 -> g) at step 2 and recompute it on a sequence that only
    # satisfies its generator at step 0
    f = next(f for f in factors if f.rule == "switch" and f.step == 2)
    short = [tuple(states[2]), tuple(states[3])]
    fresh = GraphNLPFactory(problem, task)           # no cache shared with `fac`
    g = next(x for x in fresh.factors(short) if x.rule == "switch" and x.bindings == f.bindings)
    assert g.body == f.body and g.generator == f.generator
    assert [(v.kind, v.args, v.step + 2) for v in g.variables] == [(v.kind, v.args, v.step) for v in f.variables]


def test_handover_chain_and_kin_switch_between_grippers():
    _, task, fac, states = _setup("p5", "pick(b1, g1, s1); handover(b1, g1, g2); place(b1, g2, target)")
    factors = fac.factors(states)
    sw = next(f for f in factors if f.rule == "switch" and f.step == 1)
    assert [task.partial_state_str(p) for p in sw.generator] == ["{parent(b1) = g1}", "{parent(b1) = g2}"]
    # q(g2)@2 * pose(b1)@2 == q(g1)@2 * pose(b1)@1 (the pose of g1 at 1 cancels)
    assert sorted(v.name for v in sw.variables) == ["pose(b1)@1", "pose(b1)@2", "q(g1)@2", "q(g2)@2"]
    held = [(f.bindings, f.step) for f in factors if f.rule == "held"]
    assert held == [((("o", "b1"), ("g", "g1")), 1), ((("o", "b1"), ("g", "g2")), 2)]


def test_trajectories_forall_unrolled_and_only_before_last_step():
    _, _, fac, states = _setup(with_traj=True)
    smooth = [f for f in fac.factors(states) if f.rule == "smooth"]
    assert [f.step for f in smooth] == [0, 1]            # no trajectory after the last state
    f = smooth[0]
    assert len(f.body) == 4                              # k = 0 .. waypoints(5) - 2
    (v,) = f.variables
    assert (v.name, v.dim, v.waypoints, "traj" in v.tags) == ("path(g)@0", 15, 5, True)
    # waypoint k+1 - waypoint k: a straight line with small steps satisfies it, a jump does not
    line = np.linspace([0, 0, 0], [0.2, 0.2, 0], 5).ravel()
    assert max(violation(c, [line]) for c in f.body) == 0.0
    jump = line.copy()
    jump[6:9] = [1.0, 1.0, 0.0]
    assert max(violation(c, [jump]) for c in f.body) > 0


def test_initial_guess_from_scene():
    problem, task, fac, states = _setup("p2", "pick(b2, g, s2)")
    variables = {v.name: v for v in fac.variables(states)}
    assert fac.initial_guess(variables["q(g)@0"]) == [0.1, 0.2, 0.3]
    # b2's scene pose is (-0.4, -0.2, 0.5) in the world; its parent s2 is at (-0.5, -0.2, 0.5)
    guess = fac.initial_guess(variables["pose(b2)@0"])
    # (rotated by 0.5): relative pose = R(-0.5) (0.1, 0), same angle
    assert np.allclose(guess, [0.1 * np.cos(0.5), -0.1 * np.sin(0.5), 0.0])


def test_inapplicable_plan_is_a_user_error():
    problem = planar_ir.problem("p1")
    task = build_task(problem)
    with pytest.raises(UserError, match="place\\(b1, g, r1\\), is not applicable"):
        plan_states(task, parse_plan(task, "place(b1, g, r1)"))
    with pytest.raises(UserError, match="unknown or statically inapplicable action 'fly\\(b1\\)'"):
        parse_plan(task, "fly(b1)")


def test_cache_across_plans_gives_the_same_factors_as_fresh_factories():
    """The factory reuses resolutions whose consulted facts hold again (any step, any plan);
    random walks through p5 (handover) must give exactly what a fresh factory computes."""
    import random

    from gnppdsl.compile.semantics import applicable, initial_state, successor

    problem = planar_ir.problem("p5", with_traj=True)
    task = build_task(problem)
    shared = GraphNLPFactory(problem, task)
    rng = random.Random(0)
    for _ in range(12):
        states = [initial_state(task)]
        for _ in range(rng.randint(0, 6)):
            ops = [op for op in task.operators if applicable(op, states[-1])]
            states.append(successor(task, states[-1], rng.choice(ops)))
        assert shared.factors(states) == GraphNLPFactory(problem, task).factors(states)


def test_pose_simplification_cancels_only_identical_frames():
    from gnppdsl.compile.factory import _simplify_pose
    from gnppdsl.ir.expr import Num

    a, b, c = Slot(0), Slot(1), Slot(2)
    inv = lambda x: Call("inv_se2", (x,))
    comp = lambda x, y: Call("compose_se2", (x, y))
    assert _simplify_pose(comp(inv(a), comp(a, b))) == b
    assert _simplify_pose(comp(a, comp(inv(a), b))) == b
    assert _simplify_pose(inv(inv(a))) == a
    assert _simplify_pose(comp(inv(a), comp(c, b))) == comp(inv(a), comp(c, b))
    assert _simplify_pose(comp(inv(a), Call("compose_se3", (a, b)))) == comp(inv(a), Call("compose_se3", (a, b)))
    const = Vec((Num(1.0), Num(2.0), Num(0.5)))
    assert _simplify_pose(comp(inv(const), comp(const, b))) == b
