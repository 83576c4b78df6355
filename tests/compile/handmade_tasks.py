"""Hand-built SAS+ tasks exercising every feature the writers must handle.

Built directly from the `gnppdsl.compile.sas` dataclasses (no IR, no grounding) so the writers
are tested on their own.
"""
from __future__ import annotations

from gnppdsl.compile.sas import Axiom, Effect, Operator, PartialState, SASTask, SASVariable

BOOL = ("false", "true")


def blocks_task(n_blocks: int = 3, n_spots: int = 3) -> SASTask:
    """Blocks on spots with a gripper; `clear` derived through a positive auxiliary
    `occupied` (layer 0) and its negation (layer 1), like the compiler's `not exists`."""
    blocks = [f"b{i}" for i in range(1, n_blocks + 1)]
    spots = [f"s{i}" for i in range(1, n_spots + 1)]
    variables: list[SASVariable] = []
    idx: dict[str, int] = {}

    def add(name, values, layer=-1):
        idx[name] = len(variables)
        variables.append(SASVariable(name, tuple(values), layer))

    for b in blocks:
        add(f"parent({b})", spots + [x for x in blocks if x != b] + ["g"])
    add("holding(g)", ["none"] + blocks)
    for x in spots + blocks:
        add(f"_occupied({x})", BOOL, 0)
        add(f"clear({x})", BOOL, 1)

    def fact(var, value):
        return (idx[var], variables[idx[var]].values.index(value))

    axioms = []
    for x in spots + blocks:
        for b in blocks:
            if b != x:
                axioms.append(Axiom((fact(f"parent({b})", x),), idx[f"_occupied({x})"], 1))
        axioms.append(Axiom(((idx[f"_occupied({x})"], 0),), idx[f"clear({x})"], 1))

    ops = []
    for b in blocks:
        for place in spots + blocks:
            if place == b:
                continue
            ops.append(Operator(
                f"pick({b}, g, {place})",
                (fact(f"parent({b})", place), fact("holding(g)", "none"), fact(f"clear({b})", "true")),
                (Effect(*fact(f"parent({b})", "g")), Effect(*fact("holding(g)", b))),
                cost=1))
            ops.append(Operator(
                f"place({b}, g, {place})",
                (fact(f"parent({b})", "g"), fact(f"clear({place})", "true")),
                (Effect(*fact(f"parent({b})", place)), Effect(*fact("holding(g)", "none"))),
                cost=2 if place in spots else 1))
    init = [0] * len(variables)
    # b1 on s1, b2 on b1, b3 on s2 (when present)
    placement = {"b1": "s1", "b2": "b1", "b3": "s2"}
    for b in blocks:
        v, val = fact(f"parent({b})", placement.get(b, spots[-1]))
        init[v] = val
    goal = PartialState.of([fact("parent(b1)", "b2"), fact("parent(b2)", "b3")]
                           if n_blocks >= 3 else [fact("parent(b1)", "s2")])
    return SASTask(variables, tuple(init), goal, ops, axioms, name="blocks")


def counter_task() -> SASTask:
    """Conditional effects (as produced by the Appendix-B reformulation): `tick` advances a
    3-valued counter with conditional effects; `mark` needs counter = 2 and sets a flag;
    an effect with a precondition on the same variable (`reset` requires flag)."""
    variables = [SASVariable("counter", ("c0", "c1", "c2")),
                 SASVariable("flag", BOOL),
                 SASVariable("done", BOOL)]
    ops = [
        Operator("tick", (), (Effect(0, 1, ((0, 0),)), Effect(0, 2, ((0, 1),)), Effect(0, 0, ((0, 2),)))),
        Operator("mark", ((0, 2),), (Effect(1, 1),)),
        Operator("finish", ((1, 1), (0, 0)), (Effect(2, 1), Effect(1, 0)), cost=3),
        Operator("noop_flag", ((1, 1),), (Effect(1, 1),)),     # no-op effect, must be legal
    ]
    return SASTask(variables, (0, 0, 0), PartialState.of([(2, 1)]), ops, [], name="counter")


def marker_task() -> SASTask:
    """The `initial` marker variable: every operator sets it false; a derived variable that
    reads it (layer 0) allows `start` only at step 0."""
    variables = [SASVariable("initial", BOOL), SASVariable("pos", ("a", "b", "c")),
                 SASVariable("fresh", BOOL, 0)]
    axioms = [Axiom(((0, 1),), 2, 1)]
    ops = [Operator("start", ((2, 1), (1, 0)), (Effect(1, 1), Effect(0, 0))),
           Operator("step(a, c)", ((1, 0),), (Effect(1, 2), Effect(0, 0)), cost=5),
           Operator("step(b, c)", ((1, 1),), (Effect(1, 2), Effect(0, 0)))]
    return SASTask(variables, (1, 0, 0), PartialState.of([(1, 2)]), ops, axioms, name="marker")


def unsolvable_task() -> SASTask:
    variables = [SASVariable("x", ("a", "b", "c"))]
    ops = [Operator("go", ((0, 0),), (Effect(0, 1),))]
    return SASTask(variables, (0,), PartialState.of([(0, 2)]), ops, name="unsolvable")


ALL = {"blocks": blocks_task, "counter": counter_task, "marker": marker_task}
