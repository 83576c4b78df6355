"""Batch-learned conflicts (issue 19, `gnppdsl.conflicts.batch`): a conflict's renamings onto
objects that lifting cannot accept (other sizes, other places) are decided by their own NLPs and
learned with it when infeasible -- and never when a plan containing them is feasible.

Oracles independent of the batch code:
- brute force: every logical plan up to a length, its whole graph-NLP solved from several
  starts; no batch-learned instance may match a plan found feasible (Prop. 7.1);
- the NLP solver on hand-built plans: the regions the batch learned are too small for the
  block, the large one it left out is not;
- every returned solution passes the independent verification.
"""
from __future__ import annotations

import re
import shutil
import sys
from dataclasses import replace
from pathlib import Path

import pytest

import gnppdsl
from gnppdsl.logic.conflict_io import parse_conflicts
from gnppdsl.logic.validate import find_sequence, initial_state, successor
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
from gnppdsl.solve.active_set import verify
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.plan_graph import plan_graph

sys.path.insert(0, str(Path(__file__).parent))
from plan_brute import feasible_plans  # noqa: E402

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"
SMALL = {"r1": 0.04, "r2": 0.035, "r3": 0.03}     # half extents: all too small for a disc of radius 0.05


def uneven_family(tmp: Path, goal: str = "parent(b1) = t1  parent(b3) = t2") -> Path:
    """Two targets, each occupied by a blocker (c1, c2) that must be moved first; three small
    regions of *different* sizes at different places (so no two are the same NLP and lifting
    cannot rename one onto another), one large region `big` that holds a block, and a side
    region for both blockers. Goal: b1 in t1, b3 in t2 (N = 8), unless `goal` says otherwise."""
    shutil.copy(PLANAR / "domain.pntc", tmp / "domain.pntc")
    scene = [
        "name: uneven", "dimension: 2", "workspace: [[-1, -1], [1, 1]]", "robots:",
        "  g: {kind: planar, home: [0, 0, 0], shape: {circle: 0.03}, reach_min: [-1, -1], reach_max: [1, 1]}",
        "objects:",
        "  s1: {pose: [-0.5, 0.0, 0.0]}", "  s2: {pose: [-0.5, -0.5, 0.0]}",
        "  sc1: {pose: [0.5, 0.0, 0.0]}", "  sc2: {pose: [0.5, -0.5, 0.0]}",
        "  t1: {shape: box, size: [0.14, 0.14, 0.01], pose: [0.5, 0.0, 0.0], half_extent: [0.07, 0.07], static: true}",
        "  t2: {shape: box, size: [0.14, 0.14, 0.01], pose: [0.5, -0.5, 0.0], half_extent: [0.07, 0.07], static: true}",
        "  side: {shape: box, size: [0.5, 0.3, 0.01], pose: [0.0, 0.5, 0.0], half_extent: [0.25, 0.15], static: true}",
        "  big: {shape: box, size: [0.16, 0.16, 0.01], pose: [0.6, 0.6, 0.0], half_extent: [0.08, 0.08], static: true}",
    ]
    for i, (r, h) in enumerate(SMALL.items()):
        scene.append(f"  {r}: {{shape: box, size: [{2 * h}, {2 * h}, 0.01], pose: [{-0.6 + 0.3 * i}, -0.85, 0.0], "
                     f"half_extent: [{h}, {h}], static: true}}")
    scene += ["  b1: {shape: {circle: 0.05}, pose: [-0.5, 0.0, 0.0], radius: 0.05}",
              "  b3: {shape: {circle: 0.05}, pose: [-0.5, -0.5, 0.0], radius: 0.05}",
              "  c1: {shape: {circle: 0.05}, pose: [0.5, 0.0, 0.0], radius: 0.05}",
              "  c2: {shape: {circle: 0.05}, pose: [0.5, -0.5, 0.0], radius: 0.05}"]
    (tmp / "uneven.yaml").write_text("\n".join(scene) + "\n")
    (tmp / "uneven.pntc").write_text(
        "problem uneven for planar_blocks\nscene \"uneven.yaml\"\n"
        f"objects {{ b1, b3, c1, c2 : block  s1, s2, sc1, sc2 : spot  t1, t2, side, big, {', '.join(SMALL)} : region"
        "  g : gripper }\n"
        "init { parent(b1) = s1  parent(b3) = s2  parent(c1) = sc1  parent(c2) = sc2  holding(g) = none }\n"
        f"goal {{ {goal} }}\nsolver {{ max_horizon = 10 }}\n")
    return tmp / "uneven.pntc"


def solve(compiled, **kw):
    # batch_min_factors=0: the batch also for these small planar graphs (by default it serves
    # graphs of 200+ factors, where a loop iteration costs far more than its candidates)
    opts = replace(SolveOptions.from_settings(compiled.problem.settings, jit=False, time_limit=120,
                                              planner="sequential", batch_min_factors=0), **kw)
    return solve_compiled(compiled, opts)


def place_feasible(compiled, block: str, spot: str, region: str) -> bool:
    """The NLP solver on the hand-built plan pick(block, g, spot), place(block, g, region)."""
    task = compiled.task
    states = [initial_state(task)]
    for name in (f"pick({block}, g, {spot})", f"place({block}, g, {region})"):
        states.append(successor(task, states[-1], next(o for o in task.operators if o.name == name)))
    solver = FeasibilitySolver(compiled.geometry, SolverOptions(tolerance=1e-6, restarts=3))
    return solver.solve(plan_graph(compiled.factory, states), seed=0).feasible


def small_regions_named(texts) -> set[str]:
    return {r for t in texts for r in SMALL if f"= {r}}}" in t or f"= {r}," in t}


def test_small_regions_of_other_sizes_are_learned_in_one_batch(tmp_path):
    """The first conflict about a small region brings the other small regions with it (their
    renamed subgraphs are infeasible NLPs), never the large region; without the batch lifting
    cannot rename the regions (other sizes), so the first such conflict names one region only.
    (The eager batch, batch_lazy=False: `test_lazy_batch_...` has the default.)"""
    compiled = gnppdsl.load_and_compile(str(uneven_family(tmp_path)))
    first = {}
    for budget in (0, 32):
        r = solve(compiled, batch_conflicts=budget, batch_lazy=False)
        assert r.status == "solved" and r.stats.N == 8 and verify(compiled, r).ok
        hit = next(c for c in r.conflicts if small_regions_named([c.text]))
        first[budget] = small_regions_named([hit.text, *hit.instances, *hit.batched])
        if budget:
            assert r.stats.batch_candidates > 0 and r.stats.batch_learned == sum(len(c.batched) for c in r.conflicts)
            # one block alone fits the large regions (two blocks in `big` do not: a sound instance)
            assert not [t for c in r.conflicts for t in c.batched if re.search(r"\{parent\(\w+\) = (big|side)\}", t)]
        else:
            assert r.stats.batch_candidates == 0 and not any(c.batched for c in r.conflicts)
    assert len(first[0]) == 1, first            # lifting alone: one region per conflict
    assert first[32] == set(SMALL), first       # the batch: all three at once
    # the oracle: the regions are too small for the blocker, the large one is not
    for region in SMALL:
        assert not place_feasible(compiled, "c1", "sc1", region)
    assert place_feasible(compiled, "c1", "sc1", "big")


def test_lazy_batch_decides_a_renaming_when_a_plan_holds_it(tmp_path, monkeypatch):
    """Lazy batch (the default), with no candidate decided at once (EAGER_SHARE 0; by default
    the first ones are, for half the CPU of the conflict's plan, which on this small family
    is all of them): the first conflict about a small region learns no renaming;
    the next plan that puts the blocker into another small region is refused by that queued
    renaming (source "batch", no graph-NLP of the plan), which brings the third small region
    with it -- the same regions as the eager batch, one plan later, and fewer candidate NLPs
    (those no plan holds are never solved). Every conflict holds in the plan it came from
    (`add_conflict` asserts it), and the solution is verified."""
    from gnppdsl.solve import batch_run

    compiled = gnppdsl.load_and_compile(str(uneven_family(tmp_path)))
    eager = solve(compiled, batch_conflicts=32, batch_lazy=False)
    monkeypatch.setattr(batch_run, "EAGER_SHARE", 0.0)
    lazy = solve(compiled, batch_conflicts=32)
    for r in (lazy, eager):
        assert r.status == "solved" and r.stats.N == 8 and verify(compiled, r).ok
    regions = [c for c in lazy.conflicts if small_regions_named([c.text])]
    assert len(small_regions_named([regions[0].text, *regions[0].instances, *regions[0].batched])) == 1
    assert regions[1].source == "batch", [(c.source, c.text) for c in lazy.conflicts]
    assert small_regions_named([t for c in regions[:2] for t in (c.text, *c.instances, *c.batched)]) == set(SMALL)
    assert not [t for c in lazy.conflicts for t in c.batched if re.search(r"\{parent\(\w+\) = (big|side)\}", t)]
    assert 0 < lazy.stats.batch_candidates < eager.stats.batch_candidates
    assert lazy.stats.nlp_solves < eager.stats.nlp_solves


def test_batch_learned_conflicts_never_forbid_a_feasible_plan(tmp_path):
    """Brute force: the conflicts learned on the family (goal N = 8) against every plan up to
    length 4 of the family with the goal b1 in t1 alone (the blocker c1 moved to any region
    first: small, large, side), and those learned on planar p6 against every p6 plan up to
    length 4. No instance, lifted or batch-learned, may match a plan found feasible."""
    full = gnppdsl.load_and_compile(str(uneven_family(tmp_path)))
    short = tmp_path / "short"
    short.mkdir()
    short = gnppdsl.load_and_compile(str(uneven_family(short, "parent(b1) = t1")))
    p6 = gnppdsl.load_and_compile(str(PLANAR / "p6_clutter.pntc"))
    for learned_on, checked_on, least in ((full, short, 5), (p6, p6, 30)):
        result = solve(learned_on, interleave_conflicts=True)
        assert result.status == "solved" and verify(learned_on, result).ok
        texts = [t for c in result.conflicts if c.source != "plan" for t in (c.text, *c.instances, *c.batched, *c.interleaved)]
        if learned_on is full:
            assert any(c.batched for c in result.conflicts)      # something to check
        seqs = parse_conflicts("\n".join(texts), checked_on.task)
        feasible, checked = feasible_plans(checked_on, 4)
        assert checked >= least and feasible, checked
        for plan in feasible:
            for seq in seqs:
                assert find_sequence(plan.states, seq) is None, \
                    f"conflict {checked_on.task.partial_state_str(seq[0])} forbids the feasible plan {plan.names}"


@pytest.mark.parametrize("bad", [-1])
def test_batch_budget_is_range_checked(bad):
    from gnppdsl.errors import UserError

    with pytest.raises(UserError):
        SolveOptions(batch_conflicts=bad).validated()


def hand_plan(compiled, names):
    """The logic plan of these action names from the initial state (derived values included)."""
    from gnppdsl.compile.semantics import derive
    from gnppdsl.logic.planner import Plan

    task = compiled.task
    ops = [next(i for i, o in enumerate(task.operators) if o.name == n) for n in names]
    states = [initial_state(task)]
    for i in ops:
        states.append(successor(task, states[-1], task.operators[i]))
    return Plan(tuple(ops), tuple(names), tuple(tuple(derive(task, s)) for s in states), float(len(ops)))


def test_lazy_batch_hit_on_a_symmetric_instance_of_a_queued_candidate(tmp_path, monkeypatch):
    """A plan that holds not a queued candidate but a symmetric instance of one (the lifter's:
    the same NLP up to renaming) is decided by that candidate's NLP alone: the conflict about c1
    in the small region r2 queues its renamings onto the other regions (c1 itself is not
    renamed: lifting already takes it onto every other disc), so `{parent(c1) = r3}` is queued
    and `{parent(c2) = r3}` is not; the plan putting c2 into r3 is refused by the queued
    candidate's verdict (source "batch", no graph-NLP of the plan). The conflict holds in that
    plan (`add_conflict` asserts it) and the oracle agrees: c2 does not fit into r3. A plan with
    c2 in the large region is not refused. (Without the lifted hit, `batch_hit` answered False.)"""
    from gnppdsl.solve import batch_run
    from gnppdsl.solve.loop import Loop

    monkeypatch.setattr(batch_run, "EAGER_SHARE", 0.0)
    compiled = gnppdsl.load_and_compile(str(uneven_family(tmp_path)))
    opts = replace(SolveOptions.from_settings(compiled.problem.settings, jit=False, time_limit=120,
                                              planner="sequential", batch_min_factors=0), batch_conflicts=32)
    loop = Loop(compiled, opts.validated(), None)
    assert loop.attempt(hand_plan(compiled, ["pick(c1, g, sc1)", "place(c1, g, r2)"])) is None
    assert loop.conflicts[-1].source == "nlp" and "parent(c1) = r2" in loop.conflicts[-1].text
    queued = [c.conflict for _, c in loop.batcher.pending]
    c2_r3 = hand_plan(compiled, ["pick(c2, g, sc2)", "place(c2, g, r3)"])
    assert any(find_sequence(hand_plan(compiled, ["pick(c1, g, sc1)", "place(c1, g, r3)"]).states, q) is not None
               for q in queued)
    assert not any(find_sequence(c2_r3.states, q) is not None for q in queued)
    assert loop.batch_hit(hand_plan(compiled, ["pick(c2, g, sc2)", "place(c2, g, big)"])) is False
    assert loop.batch_hit(c2_r3) is True
    c = loop.conflicts[-1]
    assert c.source == "batch" and c.text == "{parent(c2) = r3}", (c.source, c.text)
    assert find_sequence(c2_r3.states, c.partial_states) is not None
    assert not place_feasible(compiled, "c2", "sc2", "r3")
    assert place_feasible(compiled, "c2", "sc2", "big")


def test_batch_renames_onto_objects_of_a_subtype(tmp_path, monkeypatch):
    """The blockers are declared `blocker < block`: lifting never renames b1 onto them (another
    type), and before this the batch did not either. A conflict about b1 in the small region r2
    now queues the renaming onto the blocker c1 (after every same-type renaming, and never
    decided at once: `Candidate.subtype`); the plan that puts c1 into r2 holds it and is refused
    by its NLP alone (source "batch"); the oracle agrees that c1 does not fit into r2, and
    a plan with c1 in the large region is not refused."""
    from gnppdsl.solve import batch_run
    from gnppdsl.solve.loop import Loop

    monkeypatch.setattr(batch_run, "EAGER_SHARE", 1e9)       # the same-type ones at once: no matter
    problem = uneven_family(tmp_path)
    domain = tmp_path / "domain.pntc"
    domain.write_text(domain.read_text().replace("type block ", "type blocker < block\ntype block ", 1)
                      if "type blocker" not in domain.read_text() else domain.read_text())
    text = problem.read_text()
    assert "b1, b3, c1, c2 : block" in text
    problem.write_text(text.replace("b1, b3, c1, c2 : block", "b1, b3 : block  c1, c2 : blocker"))
    compiled = gnppdsl.load_and_compile(str(problem))
    assert compiled.problem.objects["c1"] == "blocker"
    opts = replace(SolveOptions.from_settings(compiled.problem.settings, jit=False, time_limit=120,
                                              planner="sequential", batch_min_factors=0), batch_conflicts=32)
    loop = Loop(compiled, opts.validated(), None)
    assert loop.attempt(hand_plan(compiled, ["pick(b1, g, s1)", "place(b1, g, r2)"])) is None
    first = loop.conflicts[-1]
    assert first.source == "nlp" and "parent(b1) = r2" in first.text
    assert not any("c1" in t or "c2" in t for t in (first.text, *first.instances, *first.batched))
    c1_r2 = hand_plan(compiled, ["pick(c1, g, sc1)", "place(c1, g, r2)"])
    assert any(find_sequence(c1_r2.states, c.conflict) is not None and c.subtype for _, c in loop.batcher.pending)
    assert loop.batch_hit(hand_plan(compiled, ["pick(c1, g, sc1)", "place(c1, g, big)"])) is False
    assert loop.batch_hit(c1_r2) is True
    c = loop.conflicts[-1]
    assert c.source == "batch" and find_sequence(c1_r2.states, c.partial_states) is not None, (c.source, c.text)
    assert not place_feasible(compiled, "c1", "sc1", "r2")
    assert place_feasible(compiled, "c1", "sc1", "big")
