"""Generated SAS+ tasks and conflict sets for tests and benchmarks of the logic layer.

Why: the planner must work on any compiled task, so it is exercised on families that are
generated rather than hand-encoded: blocks world with towers (derived `covered(x)` used
negated in preconditions, as `clear` in the DSL), random small tasks with conditional effects
and two axiom layers, and random conflicts read off states along random walks (so that they do
forbid reachable state sequences).
"""
from __future__ import annotations

import random
from typing import Sequence

from gnppdsl.compile.sas import Axiom, Effect, Operator, PartialState, SASTask, SASVariable
from gnppdsl.logic.validate import applicable, fired_effects, initial_state, successor

BOOL = ("false", "true")


def blocks_world(init_towers: Sequence[Sequence[str]], goal_towers: Sequence[Sequence[str]],
                 name: str = "blocks") -> SASTask:
    """Blocks world with one gripper; towers are listed bottom-up, e.g. [["b1", "b2"], ["b3"]].

    Variables: on(b) in {table, <other blocks>, hand}, holding in {none, <blocks>}; derived
    covered(x) := exists o . on(o) = x. Actions pick(b, from) and place(b, to).
    """
    blocks = sorted({b for t in init_towers for b in t})
    if sorted(b for t in init_towers for b in t) != blocks:
        raise ValueError("a block appears twice in the initial towers")
    variables: list[SASVariable] = []
    on_vals: dict[str, tuple[str, ...]] = {}
    for b in blocks:
        vals = ("table", *[o for o in blocks if o != b], "hand")
        on_vals[b] = vals
        variables.append(SASVariable(f"on({b})", vals))
    variables.append(SASVariable("holding", ("none", *blocks)))
    hold = len(blocks)
    for b in blocks:
        variables.append(SASVariable(f"covered({b})", BOOL, axiom_layer=0))
    on = {b: i for i, b in enumerate(blocks)}
    cov = {b: hold + 1 + i for i, b in enumerate(blocks)}

    def on_fact(b: str, place: str) -> tuple[int, int]:
        return (on[b], on_vals[b].index(place))

    initial = [0] * len(variables)
    for tower in init_towers:
        below = "table"
        for b in tower:
            initial[on[b]] = on_vals[b].index(below)
            below = b
    goal = []
    for tower in goal_towers:
        below = "table"
        for b in tower:
            goal.append(on_fact(b, below))
            below = b
    ops: list[Operator] = []
    for b in blocks:
        for place in ("table", *[o for o in blocks if o != b]):
            pre = [on_fact(b, place), (hold, 0), (cov[b], 0)]
            ops.append(Operator(f"pick({b}, {place})", tuple(pre),
                                (Effect(on[b], on_vals[b].index("hand")), Effect(hold, 1 + blocks.index(b)))))
    for b in blocks:
        for place in ("table", *[o for o in blocks if o != b]):
            pre = [(hold, 1 + blocks.index(b))]
            if place != "table":
                pre.append((cov[place], 0))
            ops.append(Operator(f"place({b}, {place})", tuple(pre),
                                (Effect(on[b], on_vals[b].index(place)), Effect(hold, 0))))
    axioms = [Axiom((on_fact(o, x),), cov[x]) for x in blocks for o in blocks if o != x]
    return SASTask(variables, tuple(initial), PartialState.of(goal), ops, axioms, name=name)


def tower_task(n: int) -> SASTask:
    """n blocks on the table; goal: one tower b1 (bottom) .. bn."""
    blocks = [f"b{i}" for i in range(1, n + 1)]
    return blocks_world([[b] for b in blocks], [blocks], name=f"tower{n}")


def reverse_tower_task(n: int) -> SASTask:
    """A tower b1 .. bn; goal: the reversed tower."""
    blocks = [f"b{i}" for i in range(1, n + 1)]
    return blocks_world([blocks], [blocks[::-1]], name=f"reverse{n}")


def grid_task(width: int, height: int, objects: int, rng: random.Random | None = None,
              name: str = "grid") -> SASTask:
    """A robot on a width x height grid carries objects to target cells (one at a time).

    Variables: at(robot) in cells; at(o) in cells + {robot}; derived occupied(c) := exists o .
    at(o) = c (dropping needs not occupied(c)). Conflicts on it have detours, unlike towers.
    Objects start and end on random distinct cells (fixed ones without `rng`).
    """
    rng = rng or random.Random(0)
    cells = [f"c{x}{y}" for y in range(height) for x in range(width)]
    variables = [SASVariable("at(robot)", tuple(cells))]
    variables += [SASVariable(f"at(o{i})", (*cells, "robot")) for i in range(objects)]
    variables.append(SASVariable("carrying", ("none", *[f"o{i}" for i in range(objects)])))
    carry = 1 + objects
    occ = carry + 1
    variables += [SASVariable(f"occupied({c})", BOOL, axiom_layer=0) for c in cells]
    ops: list[Operator] = []
    for j, c in enumerate(cells):
        x, y = j % width, j // width
        for dx, dy in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            if 0 <= x + dx < width and 0 <= y + dy < height:
                k = (y + dy) * width + x + dx
                ops.append(Operator(f"move({c}, {cells[k]})", ((0, j),), (Effect(0, k),)))
    robot = len(cells)
    for i in range(objects):
        for j, c in enumerate(cells):
            ops.append(Operator(f"pick(o{i}, {c})", ((0, j), (1 + i, j), (carry, 0)),
                                (Effect(1 + i, robot), Effect(carry, 1 + i))))
            ops.append(Operator(f"drop(o{i}, {c})", ((0, j), (carry, 1 + i), (occ + j, 0)),
                                (Effect(1 + i, j), Effect(carry, 0))))
    axioms = [Axiom(((1 + i, j),), occ + j) for i in range(objects) for j in range(len(cells))]
    start = rng.sample(range(len(cells)), objects + 1)
    target = rng.sample(range(len(cells)), objects)
    initial = [start[0], *start[1:], 0] + [0] * len(cells)
    goal = PartialState(tuple((1 + i, target[i]) for i in range(objects)))
    return SASTask(variables, tuple(initial), goal, ops, axioms, name=name)


def random_task(rng: random.Random, n_vars: int = 4, n_ops: int = 8, max_dom: int = 3,
                conditional: float = 0.3, derived: bool = True) -> SASTask:
    """A small random task: preconditions/effects on state and derived variables, conditional
    effects with probability `conditional`, axioms on two layers (layer 1 negates layer 0).
    The goal is a partial state reached by a random walk, so the task is usually solvable.
    """
    variables = [SASVariable(f"v{i}", tuple(f"x{j}" for j in range(rng.randint(2, max_dom))))
                 for i in range(n_vars)]
    axioms: list[Axiom] = []
    if derived:
        d0, d1 = n_vars, n_vars + 1
        variables += [SASVariable("d0", BOOL, 0), SASVariable("d1", BOOL, 1)]
        for _ in range(2):
            v = rng.randrange(n_vars)
            w = rng.randrange(n_vars)
            conds = {v: rng.randrange(len(variables[v].values))}
            conds.setdefault(w, rng.randrange(len(variables[w].values)))
            axioms.append(Axiom(tuple(sorted(conds.items())), d0))
        v = rng.randrange(n_vars)
        axioms.append(Axiom(((v, rng.randrange(len(variables[v].values))), (d0, 0)), d1))
    state_vars = list(range(n_vars))
    all_vars = list(range(len(variables)))

    def rand_fact(pool):
        v = rng.choice(pool)
        return (v, rng.randrange(len(variables[v].values)))

    ops = []
    for o in range(n_ops):
        pre = dict(rand_fact(all_vars) for _ in range(rng.randint(0, 2)))
        effects = []
        for v in rng.sample(state_vars, rng.randint(1, 2)):
            val = rng.randrange(len(variables[v].values))
            conds: tuple = ()
            if rng.random() < conditional:
                conds = (rand_fact(all_vars),)
            effects.append(Effect(v, val, conds))
        ops.append(Operator(f"a{o}", tuple(sorted(pre.items())), tuple(effects), cost=rng.randint(1, 3)))
    initial = [rng.randrange(len(v.values)) if not v.is_derived else 0 for v in variables]
    task = SASTask(variables, tuple(initial), PartialState(), ops, axioms, name="random")
    walk = random_walk(task, rng, rng.randint(3, 8))
    last = walk[-1]
    changed = [v for v in state_vars if last[v] != initial[v]] or state_vars
    goal_vars = rng.sample(changed, min(len(changed), rng.randint(1, 3)))
    task.goal = PartialState(tuple((v, last[v]) for v in goal_vars))
    return task


def random_walk(task: SASTask, rng: random.Random, length: int) -> list[tuple[int, ...]]:
    """States s_0 .. s_k of a random walk of at most `length` applicable operators."""
    state = initial_state(task)
    states = [state]
    for _ in range(length):
        choices = []
        for op in task.operators:
            if applicable(op, state):
                try:
                    fired_effects(op, state)
                except ValueError:
                    continue
                choices.append(op)
        if not choices:
            break
        state = successor(task, state, rng.choice(choices))
        states.append(state)
    return states


def random_conflicts(task: SASTask, rng: random.Random, count: int, max_len: int = 3,
                     max_facts: int = 3, walk_length: int = 8) -> list[tuple[PartialState, ...]]:
    """Conflicts <p_0 .. p_L> made of facts of consecutive states s_i .. s_{i+L} on random walks.

    Like the conflicts of the Graph-NLP Planner they mostly describe a *change*: the facts are
    drawn from the variables whose value changes inside the window (from s_{i-1} for L = 0),
    and s_0 is avoided when the walk allows (a conflict holding in s_0 kills every plan).
    """
    out = []
    nvars = len(task.variables)
    for _ in range(count):
        states = random_walk(task, rng, walk_length)
        L = rng.randint(0, min(max_len, len(states)) - 1)
        first = 1 if len(states) > L + 1 else 0
        i = rng.randint(first, len(states) - 1 - L)
        lo = max(0, i - 1) if L == 0 else i
        window = states[lo:i + L + 1]
        pool = [v for v in range(nvars) if len({s[v] for s in window}) > 1] or list(range(nvars))
        seq = []
        for l in range(L + 1):
            st = states[i + l]
            vars_ = rng.sample(pool, min(rng.randint(1, max_facts), len(pool)))
            seq.append(PartialState(tuple((v, st[v]) for v in vars_)))
        out.append(tuple(seq))
    return out
