"""An admissible lower bound on the length of any plan of a SAS+ task (issue 19).

Why: the sequential clingo planner returns shortest plans by proving every shorter horizon
empty, one solve call per horizon. Those proofs are most of its cost on the first call
(lab5_paper: horizons 0..11 took 0.7 of the 0.9 s to its first plan, the plan at horizon 12
itself 0.2 s), and they prove what a cheap relaxation already knows: each of the six blocks
must be picked and then put down, 12 steps. Starting the search at such a bound skips those
solve calls and keeps every guarantee: no plan of the task is shorter than the bound, and
conflicts and blocked plans only remove plans, so no plan under them is shorter either.

The bound: atomic projections (one state variable each, its domain transition graph) with
cost partitioning (Katz & Domshlak 2008; Seipp & Helmert's "Additive abstraction heuristics").
The projection onto variable v keeps v's value and drops every other variable; an operator
that assigns v (unconditionally or under conditions) is an edge x -> y for every value x it can
meet: its precondition or effect condition on v, else every value that h^2 (`logic.mutex`)
reaches together with its other preconditions (blocks world's place(b, x) tests only
holding = b, which h^2 knows implies on(b) = hand). Every plan of the task maps to a path from
s0[v] in the projection, and the goal's value of v must be reached. An operator
costs one step in total: it is split among the chosen variables it can change (cost
partitioning: the sum of its shares is at most 1), so the sum over the chosen variables of the
cheapest path to the goal value is at most the number of steps of any plan. Two partitionings
are tried, the larger bound kept: goal variables no two of which any operator changes together
(each gets the whole step: on the Lab domain the parent(b) variables, 2 steps per moved block),
and all goal variables with each operator's step split evenly. Derived variables and goal facts
on them are left out (a weaker bound, still sound). A goal value unreachable in its projection
means no plan at all: the bound is then `None`.

Cost: one Dijkstra per goal variable on its domain (a few hundred edges on the Lab problems),
milliseconds.
"""
from __future__ import annotations

import heapq
import math
from fractions import Fraction

from gnppdsl.compile.sas import SASTask


def _edges(task: SASTask) -> dict[int, list[tuple[int, frozenset[int], int]]]:
    """Per state variable: (operator, source values, target value) of every assignment an
    operator can make to it in a reachable state. The sources are the values of the variable
    that h^2 (`mutex.h2_matrix`) reaches together with each of the operator's state
    preconditions, effect conditions and the state facts its derived preconditions imply (a
    value mutex with one of them never holds when the operator applies), restricted to the
    precondition or condition on the variable itself when there is one."""
    from gnppdsl.logic.mutex import axioms_by_var, derived_consequences, h2_matrix

    inv, _, R = h2_matrix(task)
    index = {f: i for i, f in enumerate(inv)}
    reached = R.diagonal()
    by_var = axioms_by_var(task)
    out: dict[int, list[tuple[int, frozenset[int], int]]] = {}
    for o, op in enumerate(task.operators):
        derived = tuple(sorted(f for f in op.pre if task.variables[f[0]].is_derived))
        implied, excluded = derived_consequences(task, derived, by_var)
        pre = {(v, x) for v, x in op.pre if not task.variables[v].is_derived} | implied
        if len({v for v, _ in pre}) != len(pre) or pre & excluded:
            continue                                      # contradictory: never applicable
        for e in op.effects:
            if task.variables[e.var].is_derived:
                continue
            need = {f for f in pre | {c for c in e.conditions if not task.variables[c[0]].is_derived}}
            fixed = {x for v, x in need if v == e.var}
            if len(fixed) > 1:
                continue                                  # never fires
            others = [index[f] for f in need if f[0] != e.var]
            if not all(reached[i] for i in others) or not reached[index[(e.var, e.value)]]:
                continue
            sources = frozenset(
                x for x in (fixed or range(len(task.variables[e.var].values)))
                if x != e.value and (e.var, x) not in excluded and reached[index[(e.var, x)]]
                and all(R[index[(e.var, x)], i] for i in others))
            if sources:
                out.setdefault(e.var, []).append((o, sources, e.value))
    return out


def _distance(task: SASTask, var: int, edges: list[tuple[int, frozenset[int], int]],
              cost: dict[int, Fraction]) -> Fraction | None:
    """Cheapest path from s0[var] to the goal's value of `var` in its projection (operator o
    costs cost[o]); None when the goal value is unreachable."""
    goal = dict(task.goal.facts)[var]
    start = task.initial[var]
    if start == goal:
        return Fraction(0)
    n = len(task.variables[var].values)
    best: list[Fraction | None] = [None] * n
    best[start] = Fraction(0)
    queue = [(Fraction(0), start)]
    while queue:
        d, x = heapq.heappop(queue)
        if d != best[x]:
            continue
        if x == goal:
            return d
        for o, src, y in edges:
            if x not in src:
                continue
            nd = d + cost[o]
            if best[y] is None or nd < best[y]:
                best[y] = nd
                heapq.heappush(queue, (nd, y))
    return None


def plan_length_bound(task: SASTask) -> int | None:
    """A number of steps no plan of `task` is shorter than (see the module docstring); None
    when the task has no plan at all (a goal value unreachable in its projection)."""
    return LengthBound(task).bound


class LengthBound:
    """`plan_length_bound` of one task, and the same bound raised by learned conflicts (`under`).

    `bound`: the bound of the task (None: no plan at all). `under(conflicts)`: a number of steps
    no plan avoiding every conflict is shorter than (conflicts raised by the continuous level,
    `LearnedConstraints.conflicts`). Why: a conflict of one partial state whose facts are goal
    facts except a few others (lab5_paper: `{parent(b4) = pad_r, parent(o2) = table, not
    moved(o2)}`, the pad is covered by an obstacle) says that at the end of every plan those
    others do not all hold: o2 has to be picked and, with both hands empty in the goal, set down
    again, 2 more steps. The sequential planner proved those 4 horizons (12..15) empty with
    clasp: 11.8 s CPU, where the bound is 16 at once.

    How (sound, never above the shortest plan under the conflicts): for each such conflict a
    pattern abstraction over the variables of its other facts (at most PATTERN_STATES abstract
    states): breadth-first search from the initial state's projection; an operator applies
    where its state preconditions (and the facts its derived ones imply or exclude,
    `mutex.derived_consequences`) on the pattern hold and every pattern fact is reached by h^2
    together with its other preconditions; abstract states holding a fact pair that h^2 never
    reaches are left out; the abstract goal is every state that holds no conflict's facts on
    the pattern (conflicts whose facts outside the pattern are all goal facts), no fact h^2
    never reaches with a goal fact, and none of a conflict that lies within the pattern. Every
    plan maps to an abstract path to such a state, so its length is at least the abstract
    distance counted in the operators that change the pattern. These distances and the goal
    variables' (the projections above) are summed over items no two of which any operator
    changes together (greedy, longest first): each step is counted once.
    """

    PATTERN_STATES = 4096

    def __init__(self, task: SASTask) -> None:
        self.task = task
        self.edges = _edges(task)
        self.goal = dict(task.goal.facts)
        goal_vars = [v for v, _ in task.goal.facts if not task.variables[v].is_derived]
        self.changers = {v: frozenset(o for o, _, _ in self.edges.get(v, ())) for v in goal_vars}
        whole = {o: Fraction(1) for o in range(len(task.operators))}
        self.unit: dict[int, Fraction] = {}
        self.bound: int | None = None
        for v in goal_vars:
            d = _distance(task, v, self.edges.get(v, []), whole)
            if d is None:
                return
            self.unit[v] = d
        disjoint = _disjoint_sum([(self.unit[v], self.changers[v], (0, v)) for v in goal_vars])
        # every goal variable, each operator's step split evenly among those it changes
        share: dict[int, int] = {}
        for v in goal_vars:
            for o in self.changers[v]:
                share[o] = share.get(o, 0) + 1
        even_cost = {o: Fraction(1, share[o]) if o in share else Fraction(1) for o in range(len(task.operators))}
        even = Fraction(0)
        for v in goal_vars:
            d = _distance(task, v, self.edges.get(v, []), even_cost)
            if d is None:
                return
            even += d
        self.bound = math.ceil(max(disjoint, even))
        self._patterns: dict[tuple[int, ...], tuple[Fraction | None, frozenset[int]]] = {}
        self._seen = 0                       # conflicts looked at (the list only grows)
        self._ends: list[tuple] = []         # per end conflict: its facts off the goal
        self._raised = self.bound

    def under(self, conflicts) -> int | None:
        """The bound under `conflicts` (sequences of `PartialState`; a list that only grows
        between calls: each conflict is looked at once); never below `bound`. None only when
        the task itself has no plan (`bound` None)."""
        if self.bound is None:
            return None
        fresh = list(conflicts)[self._seen:]
        self._seen += len(fresh)
        ends = []
        for seq in fresh:
            if len(seq) != 1:
                continue
            facts = seq[0].facts
            rest = tuple(sorted((v, x) for v, x in facts if self.goal.get(v) != x))
            if not rest or any(self.task.variables[v].is_derived or v in self.goal for v, _ in rest):
                continue                      # holds no fact off the goal, or cannot hold at the end
            ends.append(rest)
        if not ends:
            return self._raised
        self._ends += ends
        patterns = sorted({tuple(sorted({v for v, _ in rest})) for rest in self._ends})
        for pattern in patterns:
            key = pattern
            hold = tuple(rest for rest in self._ends if {v for v, _ in rest} <= set(pattern))
            if self._patterns.get(key, (None, None, ()))[2:] == (hold,):
                continue
            dist = self._pattern_distance(pattern, hold, [tuple(s) for s in conflicts])
            changers = frozenset(o for o, op in enumerate(self.task.operators)
                                 if any(e.var in pattern for e in op.effects))
            self._patterns[key] = (dist, changers, hold)
        items = [(self.unit[v], self.changers[v], (0, v)) for v in self.unit]
        # a pattern whose abstract goal is unreachable (no plan at all under the conflicts) adds
        # nothing: the planner's search proves that case
        items += [(dist, changers, (1, key)) for key, (dist, changers, _) in self._patterns.items()
                  if dist is not None]
        self._raised = max(self._raised, math.ceil(_disjoint_sum(items)))
        return self._raised

    def _pattern_distance(self, pattern: tuple[int, ...], ends, conflicts) -> Fraction | None:
        """Abstract distance from the initial state to a state holding none of `ends` (see the
        class docstring); None if no such state is reachable in the abstraction."""
        from gnppdsl.logic.mutex import axioms_by_var, derived_consequences, h2_matrix

        task = self.task
        size = 1
        for v in pattern:
            size *= len(task.variables[v].values)
        if size > self.PATTERN_STATES:
            return Fraction(0)
        inv, _, R = h2_matrix(task)
        index = {f: i for i, f in enumerate(inv)}
        reached = R.diagonal()
        pos = {v: k for k, v in enumerate(pattern)}
        goal_idx = [index[(v, x)] for v, x in self.goal.items() if not task.variables[v].is_derived]
        inner = [tuple((pos[v], x) for v, x in s[0].facts) for s in conflicts
                 if len(s) == 1 and s[0].facts and all(v in pos for v, _ in s[0].facts)]

        def valid(state) -> bool:
            idx = [index[(v, x)] for v, x in zip(pattern, state)]
            if not all(reached[i] for i in idx):
                return False
            if any(not R[i, j] for a, i in enumerate(idx) for j in idx[a + 1:]):
                return False
            return not any(all(state[k] == x for k, x in c) for c in inner)

        def is_goal(state) -> bool:
            if any(all(state[pos[v]] == x for v, x in rest) for rest in ends):
                return False
            idx = [index[(v, x)] for v, x in zip(pattern, state)]
            return all(R[i, g] for i in idx for g in goal_idx)

        by_var = axioms_by_var(task)
        moves = []                             # (required {k: x}, excluded {(k, x)}, others, effects)
        for op in task.operators:
            effects = [e for e in op.effects if e.var in pos]
            if not effects:
                continue
            derived = tuple(sorted(f for f in op.pre if task.variables[f[0]].is_derived))
            implied, excluded = derived_consequences(task, derived, by_var)
            pre = {(v, x) for v, x in op.pre if not task.variables[v].is_derived} | implied
            if len({v for v, _ in pre}) != len(pre) or pre & excluded:
                continue
            if not all(reached[index[f]] for f in pre):
                continue
            need = {pos[v]: x for v, x in pre if v in pos}
            others = [index[f] for f in pre if f[0] not in pos]
            out = {(pos[v], x) for v, x in excluded if v in pos}
            moves.append((need, out, others, effects))
        start = tuple(task.initial[v] for v in pattern)
        if not valid(start):
            return None
        dist = {start: 0}
        frontier = [start]
        while frontier:
            nxt = []
            for state in frontier:
                if is_goal(state):
                    return Fraction(dist[state])
                idx = [index[(v, x)] for v, x in zip(pattern, state)]
                for need, out, others, effects in moves:
                    if any(state[k] != x for k, x in need.items()) or any(state[k] == x for k, x in out):
                        continue
                    if any(not R[i, j] for i in idx for j in others):
                        continue
                    for succ in self._successors(state, effects, pos):
                        if succ not in dist and valid(succ):
                            dist[succ] = dist[state] + 1
                            nxt.append(succ)
            frontier = nxt
        return None

    def _successors(self, state, effects, pos):
        """The abstract states an operator's effects on the pattern can lead to: unconditional
        effects always, a conditional one fires or not (its conditions on the pattern decide
        when they fail; conditions elsewhere are unknown)."""
        outs = [list(state)]
        for e in effects:
            if e.conditions:
                local = [(pos[v], x) for v, x in e.conditions if v in pos]
                grown = []
                fires = all(state[k] == x for k, x in local)    # conditions read the state before
                for s in outs:
                    grown.append(s)
                    if fires:
                        t = list(s)
                        t[pos[e.var]] = e.value
                        grown.append(t)
                outs = grown
            else:
                for s in outs:
                    s[pos[e.var]] = e.value
        return {tuple(s) for s in outs if tuple(s) != tuple(state)}


def _disjoint_sum(items) -> Fraction:
    """Sum of the distances of items (distance, operators that change it, tie-break key) no two
    of which share an operator: greedy, the longest first (goal variables before conflict
    patterns at equal distance, as `plan_length_bound` always chose)."""
    total, used = Fraction(0), set()
    for d, changers, _ in sorted(items, key=lambda it: (-it[0], it[2])):
        if d > 0 and not changers & used:
            total += d
            used |= changers
    return total
