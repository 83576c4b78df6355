"""Collision screening (`gnppdsl.solve.screening`): a graph with many collision factors is
first solved with only those near at its start, and its answer is accepted only when numpy finds
every factor of the whole graph holds; a screened NLP that fails or whose point breaks a
dropped factor is no verdict. Also: a motion between fixed keyframes carries no factor whose
variables are all fixed, with or without idle trajectories (`TrajectoryPhase.solve_motion`).
On the 1-D toy with trajectories (its `apart` factors are the collisions), the screening
threshold lowered so that its few collision factors qualify; every solution re-checked."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.feasibility import FeasibilitySolver
from gnppdsl.solve import screening
from gnppdsl.solve.feasibility_check import FeasibilityCheck
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from solve_checks import check_solution
from solve_toy import occupied_problem

OPTIONS = SolveOptions(switches="trn", time_limit=60, max_horizon=6, order="staged")


def _spy_nlps(monkeypatch) -> list:
    seen = []
    real = FeasibilitySolver.solve

    def spy(self, g, *a, **k):
        r = real(self, g, *a, **k)
        seen.append((g, r.feasible))
        return r

    monkeypatch.setattr(FeasibilitySolver, "solve", spy)
    return seen


def _screen_everything(monkeypatch):
    monkeypatch.setattr(screening, "SCREEN_MIN_FACTORS", 1)
    monkeypatch.setattr(screening, "SCREEN_KEEP_FRACTION", 1.0)


def _spy_screened(monkeypatch) -> list:
    """(graph, result) of every `screened` call that returned a result."""
    out = []
    real = FeasibilityCheck.screened

    def spy(self, g, warm):
        r = real(self, g, warm)
        if r is not None:
            out.append((self, g, r))
        return r

    monkeypatch.setattr(FeasibilityCheck, "screened", spy)
    return out


def _solved(options=OPTIONS):
    compiled = occupied_problem(waypoints=4)
    res = solve_compiled(compiled, options)
    assert res.solved and res.stats.N == 4, res.message
    check_solution(compiled, res)
    return res


def test_a_graph_with_many_collision_factors_is_solved_with_the_near_ones_and_verified(monkeypatch):
    _screen_everything(monkeypatch)
    seen = _spy_nlps(monkeypatch)
    answers = _spy_screened(monkeypatch)
    res = _solved()
    screened = [g for g, _ in seen if "{screened" in g.name]
    assert screened and res.stats.screened_solves >= len(screened)
    assert res.stats.screened_dropped > 0
    # a screened NLP leaves collision factors out, never anything else
    for _, g, r in answers:
        assert r.feasible
        # the accepted point satisfies every factor of the whole graph (numpy)
        point = {v: r.values[v] for v in g.variables}
        assert max_violation(g.factor_instances, point)[0] <= 1e-6
    assert answers


def test_without_screening_no_screened_nlp(monkeypatch):
    """The counterfactual (it can fail): screen_collisions off, the same solve has none."""
    _screen_everything(monkeypatch)
    seen = _spy_nlps(monkeypatch)
    res = _solved(replace(OPTIONS, screen_collisions=False))
    assert not [g for g, _ in seen if "{screened" in g.name]
    assert res.stats.screened_solves == 0


def test_a_screened_point_that_breaks_a_dropped_factor_is_not_accepted(monkeypatch):
    """Every screened NLP returns a 'solution' with the two blocks on top of each other at
    every step (it breaks the dropped `apart` factors): numpy rejects it each round, so no
    screened result is returned, the graphs are solved whole, and the solution is valid."""
    _screen_everything(monkeypatch)
    real = FeasibilityCheck.screened_solve
    lies = []

    def lying(self, sub, point, **kw):
        r = real(self, sub, point, **kw)
        if r.feasible:
            values = dict(r.values)
            for v in values:
                if v.kind == "pose" and v.args == ("b2",):
                    other = next((u for u in values if u.kind == "pose" and u.args == ("b1",) and u.step == v.step),
                                 None)
                    if other is not None:
                        values[v] = np.asarray(values[other]).copy()
            lies.append(sub.name)
            r = replace(r, values=values)
        return r

    monkeypatch.setattr(FeasibilityCheck, "screened_solve", lying)
    answers = _spy_screened(monkeypatch)
    _solved()
    assert lies
    assert not answers


def test_a_failed_screened_nlp_is_no_verdict(monkeypatch):
    """Every screened NLP 'fails' (a lie): the graphs are solved whole instead, and the solve
    ends with the same plan, no conflict more than without screening."""
    _screen_everything(monkeypatch)
    plain = _solved(replace(OPTIONS, screen_collisions=False))
    real = FeasibilityCheck.screened_solve
    failed = []

    def failing(self, sub, point, **kw):
        r = real(self, sub, point, **kw)
        failed.append(sub.name)
        return replace(r, feasible=False, max_violation=max(r.max_violation, 1.0))

    monkeypatch.setattr(FeasibilityCheck, "screened_solve", failing)
    res = _solved()
    assert failed
    assert res.plan == plain.plan
    assert len(res.conflicts) == len(plain.conflicts)


def test_motions_without_idle_trajectories_carry_no_fixed_factor(monkeypatch):
    """No trajectory is held idle: each phase NLP still leaves out the factors whose variables
    are all fixed (its keyframes' own), checked once with numpy instead."""
    monkeypatch.setattr(FeasibilityCheck, "idle_motions", lambda self, s, i: {})
    seen = _spy_nlps(monkeypatch)
    _solved()
    phases = [g for g, _ in seen if "{motion" in g.name]
    assert phases
    for g in phases:
        for ref in g.factor_refs:
            assert any(u.lower is None or u.lower != u.upper for u in g.graph.neighbors(ref)), \
                (g.name, g.factor(ref).label)


def test_a_screened_nlp_that_fails_linearised_is_tried_once_with_the_distances_curvature(monkeypatch):
    """With `distance_curvature = false`, a screened NLP that fails (here: the linearised run is
    made to fail) is solved once more from the same point by a solver whose distance rows keep
    their second derivatives; its answer is accepted only after numpy checks every factor of
    the whole graph. With the setting on, there is no second try (nothing else to try)."""
    _screen_everything(monkeypatch)
    real = FeasibilityCheck.screened_solve
    calls = []

    def linearised_fails(self, sub, point, distance_curvature=False):
        r = real(self, sub, point, distance_curvature=distance_curvature)
        solver = self._curved_solver if distance_curvature else self.solver
        if not distance_curvature:
            r = replace(r, feasible=False, max_violation=max(r.max_violation, 1.0))
        calls.append((sub.name, distance_curvature, solver.options.distance_curvature, dict(point), r.feasible))
        return r

    monkeypatch.setattr(FeasibilityCheck, "screened_solve", linearised_fails)
    answers = _spy_screened(monkeypatch)
    _solved(replace(OPTIONS, distance_curvature=False))
    tries = [c for c in calls if c[1]]
    assert tries, "no second try with the distances' curvature"
    assert all(c[2] for c in tries) and all(not c[2] for c in calls if not c[1])
    # the first try with the curvature is a second try: it starts where the failed linearised
    # one started. After it succeeded (`Run.screen_curved`) the screened NLPs start with the
    # curvature, and a linearised run is only the second try of one that failed with it.
    rescue = next(i for i, c in enumerate(calls) if c[1])
    assert rescue > 0

    def second_try(i):
        first = calls[i - 1]
        assert first[1] != calls[i][1] and first[0] == calls[i][0] and not first[4]
        assert all(np.array_equal(np.asarray(first[3][v]), np.asarray(calls[i][3][v])) for v in calls[i][3])

    second_try(rescue)
    assert calls[rescue][4] and len(calls) > rescue + 1
    assert all(calls[i][1] or second_try(i) is None for i in range(rescue + 1, len(calls)))
    assert answers
    for _, g, r in answers:
        point = {v: r.values[v] for v in g.variables}
        assert max_violation(g.factor_instances, point)[0] <= 1e-6
    calls.clear()
    _solved(replace(OPTIONS, distance_curvature=True))
    assert calls and not [c for c in calls if c[1]]


def test_a_plans_own_keyframes_are_screened_only_when_huge(monkeypatch):
    """The mode-switch graph of the plan itself (solved before its motions) is screened when
    it has at least SCREEN_KEYFRAMES_MIN collision factors (stack_32), not below (clutter_4)."""
    _screen_everything(monkeypatch)
    seen = _spy_nlps(monkeypatch)

    def solved():
        # an initial guess for every block pose: the screen needs a start for every variable
        compiled = occupied_problem(waypoints=4)
        compiled.factory.initial_guess = lambda v, states=None: [1.5] if v.kind == "pose" else None
        res = solve_compiled(compiled, OPTIONS)
        assert res.solved and res.stats.N == 4, res.message
        check_solution(compiled, res)
        return res

    monkeypatch.setattr(screening, "SCREEN_KEYFRAMES_MIN", 10 ** 9)
    solved()
    assert not [g for g, _ in seen if g.name.startswith("G[modes]{screened")]
    seen.clear()
    monkeypatch.setattr(screening, "SCREEN_KEYFRAMES_MIN", 1)
    solved()
    own = [g for g, _ in seen if g.name.startswith("G[modes]{screened")]
    assert own


def test_numpy_checks_skip_factors_that_held_at_the_same_values(monkeypatch):
    """`Run.violation` does not evaluate again a factor it found holding at the same values of
    its variables (it answers from `Run.held`), evaluates it again at other values, and never
    remembers a call that found a violation. The solve still ends with a checked solution."""
    from gnppdsl.nlp import evaluate
    from gnppdsl.solve.run import Run, _values_key

    evaluated = []                 # (id(f), values key, call holds) of every factor evaluated
    runs = []
    real_max = evaluate.max_violation

    inside = []                    # only the evaluations `Run.violation` makes

    def spy_max(factors, values, geometry=None):
        factors = list(factors)
        out = real_max(factors, values, geometry)
        if inside:
            evaluated.extend((id(f), _values_key(f, values), out[0] <= 1e-6) for f in factors)
        return out

    real_violation = Run.violation

    def spy_violation(self, factors, point, variables=()):
        runs.append(self)
        inside.append(1)
        try:
            return real_violation(self, factors, point, variables)
        finally:
            inside.pop()

    monkeypatch.setattr(evaluate, "max_violation", spy_max)
    monkeypatch.setattr(Run, "violation", spy_violation)
    _solved()
    run = runs[-1]
    assert run.held, "nothing remembered"
    held_once = set()
    for fid, key, holds in evaluated:
        assert (fid, key) not in held_once, "a factor that held was evaluated again at the same values"
        if holds:
            held_once.add((fid, key))
    # at other values the factor is evaluated again; a violated call is not remembered
    f, keys = next(iter(run.held.values()))
    point = {u: np.asarray(next(iter(keys)) and 0.0) + 1e3 for u in f.variables}
    n = len(evaluated)
    first = run.violation([f], point)
    assert len(evaluated) == n + 1
    if first > 1e-6:
        run.violation([f], point)
        assert len(evaluated) == n + 2



def test_a_plans_relaxation_levels_before_its_full_graph_are_screened(monkeypatch):
    """A relaxation level without trajectories that `evaluate` solves once before the plan's
    full graph (`plan_level`: local_first; here every level, order relaxed_first) is screened
    like the huge keyframes; the mode-switch graph is not by that rule (the level no_traj has
    its factors: only when `huge`), nor the subgraphs of Alg. 1's search. On the toy the first
    plan's no_time_traj level is infeasible: its screened NLP fails, which is no verdict (the
    level is solved whole and the solve ends with the same plan and conflicts as without).
    The counterfactual (it can fail): with `plan_level` off, no level is screened."""
    _screen_everything(monkeypatch)
    monkeypatch.setattr(screening, "SCREEN_KEYFRAMES_MIN", 10 ** 9)
    options = replace(OPTIONS, order="relaxed_first")
    seen = _spy_nlps(monkeypatch)
    levels = []
    real = FeasibilityCheck.plan_level

    def spy(self, g):
        out = real(self, g)
        levels.append((g.name, out, self.local_first))
        return out

    monkeypatch.setattr(FeasibilityCheck, "plan_level", spy)
    res = _solved(options)
    screened = [(g.name, ok) for g, ok in seen if "{screened" in g.name]
    assert any(n.startswith("G[no_time_traj]{screened") for n, _ in screened), screened
    assert not [n for n, _ in screened if n.startswith(("G[modes]", "G[no_traj]"))]
    assert all(local for _, out, local in levels if out)
    assert not [n for n, out, _ in levels if out and (n == "G" or "#" in n or "traj]" not in n)]

    seen.clear()
    monkeypatch.setattr(FeasibilityCheck, "plan_level", lambda self, g: False)
    plain = _solved(options)
    assert not [g.name for g, _ in seen if g.name.startswith("G[no_") and "{screened" in g.name]
    assert res.plan == plain.plan and len(res.conflicts) == len(plain.conflicts)


def test_a_screened_level_that_fails_gets_no_second_try_with_the_curvature(monkeypatch):
    """With `distance_curvature = false`, a screened relaxation level (`plan_level`) that fails
    is solved whole at once, without the second screened run with the distances' curvature
    that the keyframes get (the first plan's no_time_traj level of the toy is infeasible)."""
    _screen_everything(monkeypatch)
    monkeypatch.setattr(screening, "SCREEN_KEYFRAMES_MIN", 10 ** 9)
    real = FeasibilityCheck.screened_solve
    calls = []

    def spy(self, sub, point, distance_curvature=False):
        r = real(self, sub, point, distance_curvature=distance_curvature)
        calls.append((sub.name, distance_curvature, r.feasible))
        return r

    monkeypatch.setattr(FeasibilityCheck, "screened_solve", spy)
    _solved(replace(OPTIONS, order="relaxed_first", distance_curvature=False))
    level = [c for c in calls if c[0].startswith("G[no_time_traj]{screened")]
    assert level and [c for c in level if not c[2]], calls
    assert not [c for c in level if c[1]], level


def _first_tries(monkeypatch) -> list:
    """(level?, distance_curvature of its first screened NLP) of every `screened` call that ran one."""
    real_screened, real_solve = FeasibilityCheck.screened, FeasibilityCheck.screened_solve
    out, current = [], []

    def screened(self, g, warm):
        current.append([self.plan_level(g), None])
        try:
            return real_screened(self, g, warm)
        finally:
            level, first = current.pop()
            if first is not None:
                out.append((level, first))

    def screened_solve(self, sub, point, distance_curvature=False):
        if current and current[-1][1] is None:
            current[-1][1] = distance_curvature
        return real_solve(self, sub, point, distance_curvature=distance_curvature)

    monkeypatch.setattr(FeasibilityCheck, "screened", screened)
    monkeypatch.setattr(FeasibilityCheck, "screened_solve", screened_solve)
    return out


def test_a_start_deep_in_collision_is_screened_with_the_curvature_first(monkeypatch):
    """With `distance_curvature = false`, a screened graph whose start has a collision row at
    least SCREEN_DEEP deep starts with the distance rows' curvature (stack_32's keyframes stalled
    linearised first, 11.6 s CPU, every solve); a shallower one starts linearised, and so does a
    relaxation level (`plan_level`: one linearised run) however deep. Only the order of the same
    two runs changes; every answer is still re-checked by numpy (`_solved`)."""
    _screen_everything(monkeypatch)
    first = _first_tries(monkeypatch)
    monkeypatch.setattr(screening, "SCREEN_DEEP", -np.inf)      # every start counts as deep
    _solved(replace(OPTIONS, order="relaxed_first", distance_curvature=False))
    assert any(not level for level, _ in first) and any(level for level, _ in first)
    assert all(curved != level for level, curved in first), first
    first.clear()
    monkeypatch.setattr(screening, "SCREEN_DEEP", np.inf)       # none: linearised first
    _solved(replace(OPTIONS, order="relaxed_first", distance_curvature=False))
    assert first and not any(curved for _, curved in first), first


def test_a_plans_keyframes_with_a_few_hundred_collision_factors_are_screened():
    """`huge` (a plan's own keyframes screened after its relaxations) holds from as few
    collision factors as any screened graph needs (SCREEN_MIN_FACTORS): Field_3's last plan has
    248 (10 near), Field_4's 302, whose keyframes solved whole cost 52 iterations and 6 s CPU,
    screened 14 and 0.4 s. Not below SCREEN_MIN_FACTORS, not counting other factors."""
    from types import SimpleNamespace

    def graph(collisions: int, others: int = 100):
        tags = [{"collision"}] * collisions + [set()] * others
        return SimpleNamespace(factor_refs=list(range(len(tags))),
                               factor=lambda r: SimpleNamespace(tags=tags[r]))

    assert screening.CollisionScreen.huge(graph(248))
    assert screening.CollisionScreen.huge(graph(screening.SCREEN_MIN_FACTORS, 0))
    assert not screening.CollisionScreen.huge(graph(screening.SCREEN_MIN_FACTORS - 1, 1000))
