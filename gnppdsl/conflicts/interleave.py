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

Merging (runs of equal states, the Workshop's case): "arm_s pushes b1 and arm_e takes it off the
stick" was learned with one, then two, then three unrelated actions between push and take,
the block riding on the stick all along: a run of equal partial states p_{k-1} = p_k tied by
chain links. Two adjacent steps k-1, k are merged (`merged`) when their partial states in
M are equal, every factor of M crossing k-1 -> k is a chain link at k-1, no trajectory runs
between them, and the variables of a key present at both steps have the same dimension and
bounds: the crossing factors are dropped and the later steps move one earlier. The merged M' is
infeasible: from a solution of M' give both steps the merged step's values; the factors at k-1
and at k read exactly what they read in M', each dropped chain link holds by reflexivity, so M
would be feasible. Its partial states are M's, one of the equal pair left out, so every plan
containing them contains M' (Property 4.2). M' is not stretched where the pair was: a copy of
the run's state between them would need the dropped links (a step of M inside the run maps to
a step whose state holds only the bridge); the unmerged M covers the longer runs.

Preorder chains (option `preorder`, the solver's `stretch_conflicts`): a transition template
tagged PREORDER is, as a relation between the values of one step and of the next, reflexive
and transitive (`tools.push_motion`: a push forward along the block's own +y axis at its
height; its author asserts it, tests/conflicts/test_conflicts_interleave.py checks the standard
library's at random poses). Such a factor over the same variable keys at both steps is a chain
link too: the three arguments above use of `x[s] == x'[s]` only reflexivity (contraction,
merging) and transitivity (stretching). Off by default: on Work_5 (seed 0) the preorder runs'
217 instances took clingo's calls from 2.5 to 155 s CPU (docs/design.md, "Stretched conflicts").

Stutters (a kinematic switch across the stretched transition): Field_3 learned "mm picks o1 at
site_a and places it on station_n, parked in between" as <p_0, p_1, p_2>, then again with the
arm1's pick of o2 between the pick and the place (p_1 twice), each a whole loop iteration. The
place's factor `kin_switch_rel` crosses 1 -> 2, so the transition is no chain link; but it reads
at step 1 only o1's pose relative to the hand, and a repeated state p_1 -> p_1 carries that
variable whole (`stay`: `pose(o) == pose(o)'`). So a transition j -> j+1 is stretched too when
every factor of M crossing it is a chain link at j or a transition factor at j (steps j and j+1
only) whose variables at step j are each carried whole (`x == x'`, same dimension and bounds)
by a chain equality the factory builds on the transition s_j -> s_j of the plan's full state s_j
(`Stutter`, passed by the caller; only M itself, whose steps are the plan's, is asked), except
M's first transition: there a stutter only delays M's start, which M itself matches wherever its
first state still holds (Work_2: 91 such instances of "b1 is not picked from the table", +0.5 s
of clingo per solve, no plan fewer). Its
bridge B_j holds the generators of the chain links used (both partial states) and the crossing
factors' partial states at j; a stretched instance is <.., p_j + B_j, B_j, .., B_j, p_{j+1}, ..>
(p_j takes B_j's facts: the links' generators must hold at j). Soundness: a plan holding it
holds the links' copies along j, y_1, .., y_d, M's chain links across j as copies (as above),
and each crossing factor f at y_d -> y_d + 1 = j+1 (its partial states hold there; Property 4.2).
From a solution of that subgraph take M's values at its own steps: every factor not crossing j
reads what it reads there; f read at step j only variables equal along j, y_1, .., y_d by the
links (transitivity), so f at j -> j+1 holds as it does at y_d -> j+1; the chain links of M
across j hold by transitivity. So M would be feasible: M is infeasible, so is the plan's graph.

Cost: no NLP; the instances of each length are one lifted constraint for the planner. At most
`limit` instances per conflict, no longer than `max_length` states (the planner's horizon + 1),
shortest first.
"""
from __future__ import annotations

import itertools
from typing import Callable, Sequence

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts.mapping import step_range, to_partial_states
from gnppdsl.ir.expr import Constraint, Index, Num, Slot

Conflict = tuple[PartialState, ...]

Stutter = Callable[[int], Sequence[FactorInstance]]
"""The chain links (`chain_link`) the factory builds on the transition s_j -> s_j of a conflict's
plan state at step j (module docstring, "Stutters"), at steps j, j+1."""

LIMIT = 64
"""Stretched instances per conflict (the original included)."""

PREORDER = "preorder"
"""The tag of a transition template that is reflexive and transitive as a relation between one
step's values and the next's (module docstring, "Preorder chains")."""


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


def _same_variable(a, b) -> bool:
    """Are `a` and `b` the same continuous variable (key, no trajectory, dimension, bounds) at
    two steps? Then one may take the other's value (reflexivity needs that much)."""
    return a.key == b.key and not a.waypoints and not b.waypoints and a.dim == b.dim \
        and a.lower == b.lower and a.upper == b.upper


def preorder_link(f: FactorInstance) -> bool:
    """Is `f` a transition factor of a template tagged PREORDER over the same variables (keys,
    dimensions, bounds) at step f.step and at f.step + 1, and no other?"""
    if PREORDER not in f.tags or f.span != 2 or len(f.generator) != 2:
        return False
    at: dict[int, dict] = {f.step: {}, f.step + 1: {}}
    for v in f.variables:
        if v.step not in at or v.key in at[v.step]:
            return False
        at[v.step][v.key] = v
    here, there = at[f.step], at[f.step + 1]
    return bool(here) and here.keys() == there.keys() and all(_same_variable(here[k], there[k]) for k in here)


def chain_link(f: FactorInstance, preorder: bool = False) -> bool:
    """A factor whose copies along consecutive steps compose (module docstring): a chain
    equality, or with `preorder` a PREORDER transition."""
    return chain_equality(f) or (preorder and preorder_link(f))


def bridges(factors: Sequence[FactorInstance], preorder: bool = False,
            stutter: Stutter | None = None) -> list[PartialState | None]:
    """Per transition j -> j+1 of the conflict of `factors` (relative steps), its bridge B_j
    when stretchable (module docstring; chain links as `chain_link(f, preorder)`), else None.
    `stutter`: the chain links of a repeated state at a step (module docstring, "Stutters"),
    for the transitions a kinematic switch crosses."""
    factors = list(factors)
    first, last = step_range(factors)
    out: list[PartialState | None] = []
    for j in range(first, last):
        if stutter is not None and j > first:
            b = _stutter_bridge(factors, j, stutter, preorder)
            if b is not None:
                out.append(b)
                continue
        facts: dict[int, int] = {}
        ok = True
        for f in factors:
            steps = [v.step for v in f.variables] + [f.step + k for k in range(len(f.generator))]
            if any(v.waypoints and v.step == j for v in f.variables):
                ok = False                               # a motion j -> j+1 is part of M
                break
            if not (min(steps) <= j < max(steps)):
                continue                                 # does not cross j -> j+1
            if not chain_link(f, preorder) or f.step != j:
                ok = False
                break
            for p in f.generator:
                for var, val in p.facts:
                    if facts.setdefault(var, val) != val:
                        ok = False
        out.append(PartialState.of(facts) if ok else None)
    return out


def _full_equality(g: FactorInstance) -> bool:
    """Is `g` a chain equality of its whole variable (`x == x'`, no component range)?"""
    if not chain_equality(g):
        return False
    dim = g.variables[0].dim
    return any(_slot_range(c.lhs)[1] in ((), (0, dim)) for c in g.body)


def _stutter_bridge(factors: Sequence[FactorInstance], j: int, stutter: Stutter,
                    preorder: bool) -> PartialState | None:
    """The bridge of transition j -> j+1 that factors other than chain links cross (module
    docstring, "Stutters"), or None: every crossing factor is a chain link at j or a transition
    factor at j whose variables at step j are each carried whole by a chain equality of a
    repeated state j (`stutter(j)`, the factory's); the bridge holds the generators of the
    chain links used and the crossing factors' partial states at j."""
    facts: dict[int, int] = {}
    need: dict = {}
    crossed = False

    def add(p: PartialState) -> bool:
        return all(facts.setdefault(var, val) == val for var, val in p.facts)

    for f in factors:
        if any(v.waypoints and v.step == j for v in f.variables):
            return None                                  # a motion j -> j+1 is part of M
        steps = _steps(f)
        if not (min(steps) <= j < max(steps)):
            continue
        if f.step != j or len(f.generator) != 2 or not steps <= {j, j + 1}:
            return None
        if chain_link(f, preorder):
            if not all(add(p) for p in f.generator):
                return None
            continue
        crossed = True
        if not add(f.generator[0]):
            return None
        for v in f.variables:
            if v.step == j:
                need[v.key] = v
    if not crossed:
        return None                                      # chain links only: `bridges` as before
    links = stutter(j)
    for key, v in need.items():
        link = next((g for g in links if g.step == j and _full_equality(g) and g.variables[0].key == key
                     and _same_variable(g.variables[0], v)), None)
        if link is None or not all(add(p) for p in link.generator):
            return None
    return PartialState.of(facts)


def _key(f: FactorInstance) -> tuple:
    return f.rule, f.template, f.bindings, f.generator


def contracted(factors: Sequence[FactorInstance], preorder: bool = False) -> tuple[FactorInstance, ...]:
    """M with every removable step removed (module docstring, "Contraction"), until none is
    left: an interior step k whose variables M constrains only by chain links across k-1 -> k
    and k -> k+1, the same ones on both sides (rule, template, bindings and generator), loses
    the factors across k -> k+1, and every later step moves one earlier."""
    current = tuple(factors)
    while (step := _contractible(current, preorder)) is not None:
        current = _removed(current, *step)
    return current


def merged(factors: Sequence[FactorInstance], preorder: bool = False,
           limit: int = LIMIT) -> list[tuple[FactorInstance, ...]]:
    """`factors` and the subgraphs with runs of equal partial states shortened (module
    docstring, "Merging"): every set of adjacent pairs merged, fewest merges first, at most
    `limit`. The unmerged one stays: only it may be stretched inside a run."""
    out = [tuple(factors)]
    seen = {to_partial_states(out[0])}
    frontier = out[:]
    while frontier and len(out) < limit:
        nxt = []
        for current in frontier:
            for drop, k in _mergeable(current, preorder):
                m = _removed(current, drop, k)
                key = to_partial_states(m)
                if key not in seen and len(out) < limit:
                    seen.add(key)
                    out.append(m)
                    nxt.append(m)
        frontier = nxt
    return out


def _removed(current: tuple[FactorInstance, ...], drop, k: int) -> tuple[FactorInstance, ...]:
    """`current` without the factors `drop`, the steps from k on one earlier."""
    return tuple(dict.fromkeys(f if f.step < k else f.shifted(-1) for f in current if f not in drop))


def _contractible(current: tuple[FactorInstance, ...], preorder: bool):
    """(factors to drop, first step to move) of an interior step touched only by the same chain
    links on both sides, or None."""
    first, last = step_range(current)
    for k in range(first + 1, last):
        touching = [f for f in current if k in _steps(f)]
        into = [f for f in touching if f.step == k - 1]
        out_of = [f for f in touching if f.step == k]
        if not touching or len(into) + len(out_of) != len(touching) \
                or not all(chain_link(f, preorder) for f in touching) \
                or sorted(map(_key, into), key=repr) != sorted(map(_key, out_of), key=repr):
            continue
        return set(out_of), k + 1
    return None


def _mergeable(current: tuple[FactorInstance, ...], preorder: bool):
    """(factors to drop, first step to move) of each pair of adjacent steps k-1, k with equal
    partial states whose crossing factors are all chain links at k-1 (no trajectory between
    them), the variables of a key at both steps alike."""
    first, last = step_range(current)
    seq = to_partial_states(current)
    for k in range(first + 1, last + 1):
        if seq[k - 1 - first] != seq[k - first]:
            continue
        crossing = [f for f in current if min(_steps(f)) <= k - 1 < max(_steps(f))]
        if not all(chain_link(f, preorder) and f.step == k - 1 for f in crossing):
            continue
        at = {s: {v.key: v for f in current for v in f.variables if v.step == s} for s in (k - 1, k)}
        if any(v.waypoints for v in at[k - 1].values()) \
                or any(not _same_variable(v, at[k][key]) for key, v in at[k - 1].items() if key in at[k]):
            continue
        yield set(crossing), k


def _steps(f: FactorInstance) -> set[int]:
    return {v.step for v in f.variables} | {f.step + j for j in range(len(f.generator))}



def stretched(factors: Sequence[FactorInstance], max_length: int, limit: int = LIMIT,
              preorder: bool = False, stutter: Stutter | None = None) -> list[Conflict]:
    """The conflict of `factors`, then the instances of M contracted (`contracted`), with its
    runs shortened (`merged`) and stretched (module docstring): each at most `max_length`
    partial states long, shortest first, at most `limit` in all (duplicates counted once).
    `preorder`: PREORDER transitions are chain links too. `stutter`: the chain links of a
    repeated state at a step of `factors` (module docstring, "Stutters"; only M itself, not
    its contracted or merged forms, has steps of the plan the links are built on)."""
    out = [to_partial_states(factors)]
    seen = set(out)
    shapes = []
    whole = tuple(factors)
    for m in merged(contracted(factors, preorder), preorder):
        seq = to_partial_states(m)
        bridge = bridges(m, preorder)
        grown: set[int] = set()         # stutter spots: p_j takes the bridge's facts too
        if stutter is not None and m == whole:
            plain = bridge
            bridge = bridges(m, preorder, stutter)
            grown = {j for j, b in enumerate(bridge) if b is not None and plain[j] is None}
        shapes.append((seq, bridge, [j for j, b in enumerate(bridge) if b is not None], grown))
    for length in range(min(len(seq) for seq, _, _, _ in shapes), max_length + 1):
        for seq, bridge, spots, grown in shapes:
            extra = length - len(seq)
            if extra < 0 or (extra and not spots):
                continue
            for counts in _compositions(extra, len(spots)) if spots else [()]:
                inserted = dict(zip(spots, counts))
                inst: list[PartialState] = []
                for j, p in enumerate(seq):
                    if inserted.get(j):
                        # a stutter's links hold at j -> y_1 only if their generators do
                        inst.append(p.union(bridge[j]) if j in grown else p)
                        inst.extend([bridge[j]] * inserted[j])
                    else:
                        inst.append(p)
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
