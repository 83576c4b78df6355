"""The lazy batch's structural gate (`conflicts.batch.EAGER_SHARE`, `Candidate.outside`): of a
conflict's renamed candidates, only renamings onto objects the conflict's plan already uses are
decided at once; a renaming onto an object no action of the plan names is queued, and decided
only when a plan holds it (`batch_hit`). The gate reads the plan, not the clock, so the same
candidates are decided at once on a loaded machine as on an idle one.

Oracle independent of the batch code: the NLP solver on hand-built plans (the small regions are
too small for a blocker, `test_conflicts_batch.place_feasible`)."""
from __future__ import annotations

import sys
from dataclasses import replace
from pathlib import Path

import gnppdsl
from gnppdsl.logic.validate import find_sequence
from gnppdsl.solve.options import SolveOptions

sys.path.insert(0, str(Path(__file__).parent))
from test_conflicts_batch import hand_plan, place_feasible, uneven_family  # noqa: E402


def test_renamings_onto_objects_outside_the_plan_are_queued(tmp_path, monkeypatch):
    """The plan puts c1 into r2 and c2 into r3 (both too small). With an unbounded eager share
    every candidate used to be decided at once, the renaming onto r1 (no action of the plan
    names r1) among them; now the renamings within the plan (r2 <-> r3, c1 <-> c2) are decided
    and every renaming onto another object (r1, b1, b3, big, ...) is queued. The plan that puts
    c1 into r1 holds a queued one and is refused by its NLP alone (source "batch")."""
    from gnppdsl.solve import batch_run
    from gnppdsl.solve.loop import Loop

    monkeypatch.setattr(batch_run, "EAGER_SHARE", 1e9)     # no CPU bound: only the gate decides
    compiled = gnppdsl.load_and_compile(str(uneven_family(tmp_path)))
    opts = replace(SolveOptions.from_settings(compiled.problem.settings, jit=False, time_limit=120,
                                              planner="sequential", batch_min_factors=0), batch_conflicts=32)
    loop = Loop(compiled, opts.validated(), None)
    decided = []
    real = loop.decide
    monkeypatch.setattr(loop, "decide", lambda cand: decided.append(cand) or real(cand))
    plan = hand_plan(compiled, ["pick(c1, g, sc1)", "place(c1, g, r2)", "pick(c2, g, sc2)", "place(c2, g, r3)"])
    used = {"c1", "c2", "g", "sc1", "sc2", "r2", "r3"}
    assert loop.attempt(plan) is None
    first = loop.conflicts[-1]
    assert first.source == "nlp", (first.source, first.text)
    assert decided, "the renamings within the plan are decided at once"
    assert all({t for _, t in c.mapping} <= used for c in decided), [c.mapping for c in decided]
    pending = [c for _, c in loop.batcher.pending]
    assert pending and all(not {t for _, t in c.mapping} <= used for c in pending), [c.mapping for c in pending]
    assert all(c.outside for c in pending) and not any(c.outside for c in decided)
    # the queued renaming onto r1 is decided when a plan holds it, and refuses that plan
    c1_r1 = hand_plan(compiled, ["pick(c1, g, sc1)", "place(c1, g, r1)"])
    assert any(find_sequence(c1_r1.states, c.conflict) is not None for c in pending)
    assert loop.batch_hit(c1_r1) is True
    c = loop.conflicts[-1]
    assert c.source == "batch" and find_sequence(c1_r1.states, c.partial_states) is not None, (c.source, c.text)
    assert not place_feasible(compiled, "c1", "sc1", "r1")
