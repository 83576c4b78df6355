"""Random SAS+ tasks for property tests (hypothesis): two to four state variables, a derived
variable over state facts and one over its negation (stratified axioms), operators with
conditional effects and costs, and a goal taken from a random walk (mostly solvable, never
trivial). Shared by the compiler's tests that compare against naive search and Fast Downward."""
from __future__ import annotations

from hypothesis import assume
from hypothesis import strategies as st

from sas_semantics import initial, successor

from gnppdsl.compile.sas import Axiom, Effect, Operator, PartialState, SASTask, SASVariable

BOOL = ("false", "true")


@st.composite
def tasks(draw):
    n_state = draw(st.integers(2, 4))
    variables = []
    for i in range(n_state):
        k = draw(st.integers(2, 3))
        variables.append(SASVariable(f"v{i}", BOOL if k == 2 else tuple(f"x{j}" for j in range(k))))
    # layer 0: d0 from state facts; layer 1: d1 = not d0 (plus maybe a state fact)
    d0, d1 = n_state, n_state + 1
    variables += [SASVariable("d0", BOOL, 0), SASVariable("d1", BOOL, 1)]
    fact = lambda: draw(st.sampled_from([(v, x) for v in range(n_state) for x in range(len(variables[v].values))]))
    axioms = [Axiom((fact(),), d0, 1) for _ in range(draw(st.integers(1, 2)))]
    extra = () if draw(st.booleans()) else (fact(),)
    axioms.append(Axiom(tuple(sorted(dict([(d0, 0), *extra]).items())), d1, 1))
    ops = []
    for k in range(draw(st.integers(2, 6))):
        pre = dict(draw(st.lists(st.one_of(st.builds(lambda: fact()),
                                           st.sampled_from([(d0, 0), (d0, 1), (d1, 1)])), max_size=1)))
        effects = []
        for v in draw(st.lists(st.integers(0, n_state - 1), min_size=1, max_size=2, unique=True)):
            value = draw(st.integers(0, len(variables[v].values) - 1))
            conds = ()
            if draw(st.booleans()):
                c = draw(st.one_of(st.builds(lambda: fact()), st.sampled_from([(d0, 1), (d1, 1), (d1, 0)])))
                conds = (c,)
            effects.append(Effect(v, value, conds))
        ops.append(Operator(f"op{k}", tuple(sorted(pre.items())), tuple(effects), draw(st.integers(1, 3))))
    init = tuple(draw(st.integers(0, len(v.values) - 1)) if not v.is_derived else 0 for v in variables)
    # goal: facts of a state reached by a random walk (mostly solvable, never trivial)
    task = SASTask(variables, init, PartialState(), ops, axioms, name="random")
    state = initial(task)
    for _ in range(draw(st.integers(1, 4))):
        succ = [t for t in (successor(task, state, i) for i in range(len(ops))) if t is not None]
        if not succ:
            break
        state = draw(st.sampled_from(succ))
    start = initial(task)
    changed = [(v, state[v]) for v in range(len(variables)) if state[v] != start[v]]
    assume(changed)
    goal = dict(draw(st.lists(st.sampled_from(changed), min_size=1, max_size=2, unique=True)))
    task.goal = PartialState.of(goal)
    return task
