"""The deletion filter of `conflicts.minimise` on hand-built factors, with the infeasibility
verdict given by a table written here (which factor sets are infeasible), so what is dropped is
known in advance: facts whose factors the verdict does not need go, the others stay, the
result is always an infeasible subset, and `max_checks` bounds the NLPs."""
from __future__ import annotations

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts.minimise import minimise_facts
from gnppdsl.conflicts.mapping import to_partial_states


def factor(name: str, step: int, facts: dict[int, int]) -> FactorInstance:
    return FactorInstance(template=f"t.{name}", rule=name, bindings=(), tags=frozenset(), step=step, span=1,
                          generator=(PartialState.of(facts),), variables=(), body=())


# a reach failure needs `grasp` and `place` (facts 0=1 at step 0, 1=2 at step 1); `off_pads`
# (fact 2=0 at step 1: `moved(o4)` of issue 19) is violated at the convergence point only
GRASP, PLACE, OFF = factor("grasp", 0, {0: 1}), factor("place", 1, {1: 2}), factor("off_pads", 1, {2: 0})


def infeasible_when_both(fs) -> bool:
    return GRASP in fs and PLACE in fs


def test_a_fact_no_infeasible_core_needs_is_dropped():
    out, checks = minimise_facts((GRASP, PLACE, OFF), infeasible_when_both)
    assert set(out) == {GRASP, PLACE} and infeasible_when_both(out)
    assert to_partial_states(out) == (PartialState.of({0: 1}), PartialState.of({1: 2}))
    assert checks == 3                       # one check per fact, each a proper subset


def test_facts_the_verdict_needs_stay():
    out, _ = minimise_facts((GRASP, PLACE), infeasible_when_both)
    assert set(out) == {GRASP, PLACE}
    every = lambda fs: True                  # noqa: E731 - infeasible whatever is left
    out, _ = minimise_facts((GRASP, PLACE, OFF), every)
    assert len(out) == 1                     # only the last fact's factor remains


def test_max_checks_bounds_the_nlps():
    calls = []

    def counted(fs):
        calls.append(fs)
        return infeasible_when_both(fs)

    out, checks = minimise_facts((GRASP, PLACE, OFF), counted, max_checks=1)
    # facts in step order: grasp's (step 0) is checked and needed; the budget ends before off_pads'
    assert checks == len(calls) == 1 and set(out) == {GRASP, PLACE, OFF}
