"""Relaxed reachability: drop the operators that can never apply and the values a variable can
never take, before the logic planner, the mutex analysis and the factory see the task.

Why: grounding binds every parameter to every object of its type, so `pick(o, g, from: place)`
over 80 blocks and 82 places gives 6560 operators, and `parent(o)` 83 values per block, although
a block only ever rests on its own spot, a region or the gripper. The h^2 mutex matrix is
quadratic in the facts (6.7k facts: a 45 MB matrix and 22 M candidate pairs in Python), and the
ASP encoding linear in the operators; both grew with the square of the objects. Fast Downward's
translator prunes the same way (relaxed reachability of its Datalog grounding).

Soundness: the analysis is the delete relaxation (facts once reachable stay reachable), an
over-approximation of the reachable states. An operator whose precondition contains a fact
never reachable is never applicable in any state reachable from s_0; a value never reachable
is never held. So every plan of the task is a plan of the pruned task with the same states
(read by name), and conversely: plans, plan lengths and shortest plans are unchanged (tested
against brute force and Fast Downward on random tasks and on every bundled example).

Why not also the goal-relevance (backward) pruning of FD's translator: the logic of a PNTC task
is only half of it. A block the goal never mentions may have to be moved because it is in the
way geometrically, which the logic learns later, as a conflict (paper 000, Sec. VII); dropping
its operators would remove the plans Theorem 7.1's completeness relies on. What the goal does
not need is instead never grounded on the geometric side: factors are grounded lazily, only
for the states of the plans tried (`gnppdsl.compile.ground.RuleMatcher`).

Kept whatever the analysis says: both values of booleans (code relies on ("false", "true")),
the initial value and the goal values of every variable (an unreachable goal stays written, so
the task is visibly unsolvable), every derived variable.
"""
from __future__ import annotations

from gnppdsl.compile.sas import Axiom, Effect, Fact, Operator, PartialState, SASTask, SASVariable

__all__ = ["reachable_facts", "prune_unreachable"]


def reachable_facts(task: SASTask) -> tuple[set[Fact], list[bool]]:
    """(facts reachable under the delete relaxation, per operator: reachably applicable).

    A derived variable's default value 0 counts as reachable (negation by failure can always
    hold in the relaxation: an over-approximation); its value 1 once an axiom's conditions are."""
    reached: set[Fact] = {(v, x) for v, x in enumerate(task.initial)}
    reached |= {(v, 0) for v, var in enumerate(task.variables) if var.is_derived}
    applicable = [False] * len(task.operators)
    fired = [[False] * len(op.effects) for op in task.operators]
    axiom_done = [False] * len(task.axioms)
    changed = True
    while changed:
        changed = False
        for k, ax in enumerate(task.axioms):
            if not axiom_done[k] and all(c in reached for c in ax.conditions):
                axiom_done[k] = True
                if (ax.var, ax.value) not in reached:
                    reached.add((ax.var, ax.value))
                    changed = True
        for k, op in enumerate(task.operators):
            if not applicable[k]:
                if not all(f in reached for f in op.pre):
                    continue
                applicable[k] = True
                changed = True
            for j, e in enumerate(op.effects):
                if not fired[k][j] and all(c in reached for c in e.conditions):
                    fired[k][j] = True
                    if (e.var, e.value) not in reached:
                        reached.add((e.var, e.value))
                        changed = True
    return reached, applicable


def prune_unreachable(task: SASTask) -> SASTask:
    """The task without never-applicable operators, never-firing conditional effects, axioms
    with unreachable conditions and unreachable values of multi-valued state variables (see
    the module docstring for what is always kept). Variable order and names are unchanged;
    value indices are renumbered, keeping the order of the remaining values."""
    reached, applicable = reachable_facts(task)
    goal_facts = set(task.goal.facts)
    remap: list[dict[int, int]] = []
    variables: list[SASVariable] = []
    for v, var in enumerate(task.variables):
        if var.is_derived or var.values == ("false", "true"):
            keep = list(range(len(var.values)))
        else:
            keep = [x for x in range(len(var.values))
                    if (v, x) in reached or (v, x) in goal_facts or x == task.initial[v]]
        remap.append({x: k for k, x in enumerate(keep)})
        variables.append(SASVariable(var.name, tuple(var.values[x] for x in keep), var.axiom_layer))

    def fact(f: Fact) -> Fact:
        return (f[0], remap[f[0]][f[1]])

    def ok(facts) -> bool:
        return all(f in reached for f in facts)

    operators: list[Operator] = []
    old_index: list[int] = []
    for k, op in enumerate(task.operators):
        if not applicable[k]:
            continue
        effects = tuple(Effect(e.var, remap[e.var][e.value], tuple(fact(c) for c in e.conditions))
                        for e in op.effects if ok(e.conditions))
        operators.append(Operator(op.name, tuple(fact(f) for f in op.pre), effects, op.cost))
        old_index.append(k)
    axioms = [Axiom(tuple(fact(c) for c in ax.conditions), ax.var, remap[ax.var][ax.value])
              for ax in task.axioms if ok(ax.conditions)]
    new_of = {old: new for new, old in enumerate(old_index)}
    pair_costs = {}
    for (prev, op), cost in task.pair_costs.items():
        if op in new_of and (prev is None or prev in new_of):
            pair_costs[(None if prev is None else new_of[prev], new_of[op])] = cost
    initial = tuple(remap[v][x] for v, x in enumerate(task.initial))
    goal = PartialState.of([fact(f) for f in task.goal.facts])
    return SASTask(variables, initial, goal, operators, axioms, pair_costs, task.name)
