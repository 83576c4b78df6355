"""A motion whose straight-line start between fixed keyframes passes through an obstacle
(`TrajectoryPhase.detour_start`, `interpolation.via_line`): the phase is tried once more from a
path through another keyframe of the same arm, and is solved there instead of going on to the
keyframes-with-motions and joint solves.

The case is Work_5 seed 5's motion 8 (plan 4: arm_n carries b2 from the stick's tip to pad_n
while arm_s holds the stick), with the keyframes that seed's run had when the phase failed
(tests/solve/data/work5_seed5_motion8.json, recorded from e6a0292's solve): the straight line
in joint space puts arm_n's hand 10 cm into the table, and ipopt stalls at violation ~0.014
from it. The answer is re-checked with the independent numpy evaluator (every factor of the
phase) and with the summed collision penetration of the returned path."""
from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.solve import motions
from gnppdsl.solve.check_memory import StampedValues
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.interpolation import interpolate_trajectories, straight_line, via_line
from gnppdsl.solve.loop import Loop
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.timing import result_states

ROOT = Path(__file__).resolve().parents[2]
DATA = Path(__file__).resolve().parent / "data" / "work5_seed5_motion8.json"
PLAN = ["pick(stick, arm_s, table)", "push(b1, stick, arm_s)", "pick(b3, arm_e, table)",
        "put(b3, arm_e, pad_e)", "take(b1, arm_n, stick)", "push(b2, stick, arm_s)",
        "put(b1, arm_n, pad_n2)", "take(b2, arm_n, stick)", "put(b2, arm_n, pad_n)",
        "pick(b4, arm_w, table)", "put(b4, arm_w, pad_w)"]
STEP = 8


def test_via_line_runs_evenly_through_the_via_point():
    xa, xv, xb = np.zeros(2), np.array([1.0, 0.0]), np.array([1.0, 1.0])
    pts = via_line(xa, xv, xb, 5, "joints").reshape(5, 2)
    assert np.array_equal(pts[0], xa) and np.array_equal(pts[-1], xb)
    assert np.allclose(pts[2], xv)                       # halfway along 2 m of path
    assert np.allclose(np.linalg.norm(np.diff(pts, axis=0), axis=1), 0.5)
    # a via point on the line gives the straight line
    assert np.allclose(via_line(xa, xb / 2, xb, 7, "joints"), straight_line(xa, xb, 7, "joints"))


def _phase():
    compiled = load_and_compile([str(ROOT / "examples" / "workshop" / "work5.pntc")])
    run = Loop(compiled, SolveOptions(switches="trng", seed=5, time_limit=300, jit=False), None)
    graph = run.build_graph([tuple(x) for x in result_states(compiled.task, PLAN)])
    checker = FeasibilityCheck(run, run.new_solver(), graph, use_db=False)
    recorded = {(k, s): np.asarray(x, float) for k, s, x in json.loads(DATA.read_text())["keyframes"]}
    checker.values = StampedValues({v: recorded[(v.key, v.step)] for v in graph.variables
                                    if not v.waypoints})
    trajs = [v for v in graph.variables if v.waypoints and v.step == STEP]
    warm = interpolate_trajectories(
        trajs, checker.values, lambda v: [x for h in graph.graph.neighbors(v) for x in graph.graph.neighbors(h)])
    return run, checker, graph, trajs, warm


def _penetration(run, s, point) -> float:
    from gnppdsl.nlp.evaluate import factor_margins

    collision = [s.factor(r) for r in s.factor_refs if "collision" in s.factor(r).tags]
    return sum(max(0.0, m) for m in factor_margins(collision, point, run.compiled.geometry))


@pytest.mark.parametrize("detours", [True, False])
def test_a_motion_through_the_table_is_solved_between_fixed_keyframes_through_a_keyframe(monkeypatch, detours):
    """With detours the phase is solved with its keyframes fixed; without (the counterfactual,
    e6a0292's behaviour) it fails from the straight line, which is what sent seed 5 to the
    keyframes-with-motions and joint solves."""
    if not detours:
        monkeypatch.setattr(motions.TrajectoryPhase, "detour_start", lambda self, s, i, start: {})
    run, checker, graph, trajs, warm = _phase()
    s = graph.time_slice(STEP, STEP + 1)         # the phase's NLP, as `phases_between_keyframes`
    s = s.subgraph(variables=[v for v in s.variables if not (v.waypoints and v.step != STEP)])
    start = {v: (warm[v] if v.waypoints else checker.values[v]) for v in s.variables}
    if detours:
        # the recorded start: the straight line of arm_n through the table, and a keyframe
        # path that penetrates less
        assert _penetration(run, s, start) > 0.1
        detour = checker.detour_start(s, STEP, start)
        assert detour and _penetration(run, s, {**start, **detour}) < _penetration(run, s, start)
    fixed: dict = {}
    failed = checker.phases_between_keyframes(graph, trajs, warm, fixed, [])
    if not detours:
        assert failed == STEP
        return
    assert failed is None
    point = {**{v: checker.values[v] for v in s.variables if not v.waypoints}, **fixed}
    assert all(v in point for v in s.variables)
    # every factor of the phase (keyframes as recorded, the motions returned) holds: numpy
    assert max_violation(s.factor_instances, point, run.compiled.geometry)[0] <= run.options.tolerance
    # the keyframes were not moved
    for v in s.variables:
        if not v.waypoints:
            assert np.array_equal(np.asarray(checker.values[v]), np.asarray(point[v]))
