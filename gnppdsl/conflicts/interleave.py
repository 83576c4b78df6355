"""Interleaved conflicts: one infeasible subgraph, every interleaving of steps that leave it alone.

Why: a conflict <p_0 .. p_L> fixes the distance between its steps. On the Field problems the
mobile base is tied across steps by the `parked` rule (`q(mm)[0:3] == q(mm)'[0:3]` while
`not driving(mm)`), so "mm cannot pick o1 at site_a from its initial base pose" was learned
once per number of steps between the initial state and the pick: `{initial, not driving(mm)}
-> {parent(o1) = site_a, ...}`, then with one `{not driving(mm)}` step in between, then two, ...
-- one conflict for every interleaving of the other robot's actions, each a whole loop
iteration. The geometric failure is the same: the base pose at both ends is the same variable
value whatever happens in between, as long as the base stays parked.

What: a transition j -> j+1 of the conflict is *stretchable* when every factor of the infeasible
subgraph M that relates the two steps is a chain equality (`chain_equality`: a transition
factor whose body is only constraints `x[s] == x'[s]` between the same continuous variable at
step j and at step j+1, the same constant component range on both sides; `parked`,
`manipulation.same`) and M has no trajectory variable at step j. Its *bridge* B_j is the union
of those factors' generators. A stretched instance inserts d_j >= 0 partial states B_j after
p_j: <p_0 .. p_j, B_j, .., B_j, p_{j+1} .. p_L>.

Soundness (Prop. 7.1: a conflict may forbid only plans whose graph-NLP contains an infeasible
subgraph). Let a plan's states contain a stretched instance at some offset. By factor
time-invariance (Property 4.2) the plan's graph-NLP contains every factor of M that does not
cross a stretched transition, at the corresponding steps (its generator is in p_j or in
(p_j, p_{j+1}) of a transition left alone), and, for each chain equality f across a stretched
transition j, a copy of f on every consecutive pair of the steps j, y_1, .., y_d, j+1 (each pair's
states contain f's generator, since B_j includes both of its partial states). Call this subgraph
M*. If M* had a solution, its values at the steps of M would solve M: every factor of M that
does not cross a stretched transition is in M* on the same variables, and each chain equality
x_j[s] == x_{j+1}[s] follows from x_j[s] == y_1[s] == .. == y_d[s] == x_{j+1}[s] (equality is
transitive; with the solver's tolerance e per link the chain holds to (d + 1) e). M is
infeasible, so M* is, and the plan is rightly forbidden. Nothing else is assumed: a transition
with a kinematic switch, a velocity bound or a trajectory is never stretched (such factors do
not compose), and the instances are ground conflicts handed to the planner as any other.

Contraction (the other direction): the planner may first propose the pick three steps after
the initial state, so M holds two interior steps k at which the base is only passed on. Such a
step is removed first (`contracted`) when M constrains its variables only by chain equalities
across k-1 -> k and k -> k+1, the same ones on both sides (rule, template, bindings and
generator): the factors across k -> k+1 are dropped and the later steps move one earlier. The
contracted M' is infeasible: from a solution of M' set the variables of step k to the values
of step k-1 (the same variable, dimension and bounds); every chain equality across k-1 -> k
then holds trivially and the one across k -> k+1 is M''s own across k-1 -> k+1, so M would be
feasible. Every plan containing M''s partial states contains M' (Property 4.2: each generator
of M' is one of M's, at the steps it was found at or one earlier), so it is a sound conflict;
stretching M' then covers the original distance and every other one.

Cost: no NLP; the instances of each length are one lifted constraint for the planner. At most
`limit` instances per conflict, no longer than `max_length` states (the planner's horizon + 1),
fewest inserted steps first.
"""
from __future__ import annotations

import itertools
from dataclasses import replace
from typing import Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts.mapping import step_range, to_partial_states
from gnppdsl.ir.expr import Constraint, Index, Num, Slot

Conflict = tuple[PartialState, ...]

LIMIT = 64
"""Stretched instances per conflict (the original included)."""


def _slot_range(e) -> tuple[int, tuple] | None:
    """`Slot(i)` -> (i, ()); `Slot(i)[a:b]` / `Slot(i)[a]` with constant bounds -> (i, (a, b));
    anything else -> None."""
    if isinstance(e, Slot):
        return e.index, ()
    if isinstance(e, Index) and isinstance(e.base, Slot) and isinstance(e.index, Num) \
            and (e.stop is None or isinstance(e.stop, Num)):
        return e.base.index, (e.index.value, None if e.stop is None else e.stop.value)
    return None


def chain_equality(f: FactorInstance) -> bool:
    """Is `f` a transition factor made only of `x[s] == x'[s]` constraints between one continuous
    variable (no trajectory) at step f.step and the same variable at f.step + 1?"""
    if len(f.generator) != 2 or len(f.variables) != 2 or not f.body:
        return False
    a, b = f.variables
    if a.key != b.key or a.waypoints or b.waypoints or {a.step, b.step} != {f.step, f.step + 1} \
            or a.dim != b.dim or a.lower != b.lower or a.upper != b.upper:
        return False
    for c in f.body:
        if not isinstance(c, Constraint) or c.op != "==":
            return False
        lhs, rhs = _slot_range(c.lhs), _slot_range(c.rhs)
        if lhs is None or rhs is None or lhs[1] != rhs[1] or {lhs[0], rhs[0]} != {0, 1}:
            return False
    return True


def bridges(factors: Sequence[FactorInstance]) -> list[PartialState | None]:
    """Per transition j -> j+1 of the conflict of `factors` (relative steps), its bridge B_j
    when stretchable (module docstring), else None."""
    factors = list(factors)
    first, last = step_range(factors)
    out: list[PartialState | None] = []
    for j in range(first, last):
        facts: dict[int, int] = {}
        ok = True
        for f in factors:
            steps = [v.step for v in f.variables] + [f.step + k for k in range(len(f.generator))]
            if any(v.waypoints and v.step == j for v in f.variables):
                ok = False                               # a motion j -> j+1 is part of M
                break
            if not (min(steps) <= j < max(steps)):
                continue                                 # does not cross j -> j+1
            if not chain_equality(f) or f.step != j:
                ok = False
                break
            for p in f.generator:
                for var, val in p.facts:
                    if facts.setdefault(var, val) != val:
                        ok = False
        out.append(PartialState.of(facts) if ok else None)
    return out


def _key(f: FactorInstance) -> tuple:
    return f.rule, f.template, f.bindings, f.generator


def contracted(factors: Sequence[FactorInstance]) -> tuple[FactorInstance, ...]:
    """M with every removable step removed (module docstring, "Contraction"): an interior step
    k whose variables M constrains only by chain equalities across k-1 -> k and k -> k+1, the
    same ones on both sides (rule, template, bindings and generator). The factors across
    k -> k+1 are dropped and every later step moves one earlier, so each chain equality
    across k-1 -> k now relates k-1 to what was k+1."""
    current = tuple(factors)
    while True:
        first, last = step_range(current)
        for k in range(first + 1, last):
            touching = [f for f in current if k in _steps(f)]
            into = [f for f in touching if f.step == k - 1]
            out_of = [f for f in touching if f.step == k]
            if not touching or len(into) + len(out_of) != len(touching) \
                    or not all(chain_equality(f) for f in touching) \
                    or sorted(map(_key, into), key=repr) != sorted(map(_key, out_of), key=repr):
                continue
            current = tuple(f if f.step < k else _shift(f, -1) for f in current if f.step != k)
            break
        else:
            return current


def _steps(f: FactorInstance) -> set[int]:
    return {v.step for v in f.variables} | {f.step + j for j in range(len(f.generator))}


def _shift(f: FactorInstance, by: int) -> FactorInstance:
    return replace(f, step=f.step + by, variables=tuple(replace(v, step=v.step + by) for v in f.variables))


def stretched(factors: Sequence[FactorInstance], max_length: int, limit: int = LIMIT) -> list[Conflict]:
    """The conflict of `factors`, then that of M contracted (`contracted`) and its stretched
    instances (module docstring), each at most `max_length` partial states long, fewest
    inserted steps first, at most `limit` in all (duplicates counted once)."""
    out = [to_partial_states(factors)]
    factors = contracted(factors)
    seq = to_partial_states(factors)
    if seq not in out:
        out.append(seq)
    bridge = bridges(factors)
    spots = [j for j, b in enumerate(bridge) if b is not None]
    if not spots:
        return out
    seen = set(out)
    for extra in range(1, max_length - len(seq) + 1):
        for counts in _compositions(extra, len(spots)):
            inserted = dict(zip(spots, counts))
            inst: list[PartialState] = []
            for j, p in enumerate(seq):
                inst.append(p)
                if j in inserted:
                    inst.extend([bridge[j]] * inserted[j])
            inst_t = tuple(inst)
            if inst_t in seen:
                continue
            seen.add(inst_t)
            out.append(inst_t)
            if len(out) >= limit:
                return out
    return out


def _compositions(total: int, parts: int):
    """Tuples of `parts` non-negative integers summing to `total`."""
    for cut in itertools.combinations(range(total + parts - 1), parts - 1):
        prev, out = -1, []
        for c in cut + (total + parts - 1,):
            out.append(c - prev - 1)
            prev = c
        yield tuple(out)
