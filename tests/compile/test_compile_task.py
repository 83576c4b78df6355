"""IR -> SAS+ task: checked with Fast Downward, the `pddl` parser and a naive interpreter."""
from __future__ import annotations

import pytest

import planar_ir
from fd_oracle import run_fd_on_sas, translate_pddl
from sas_semantics import initial, optimal_cost, run_plan

from gnppdsl.compile.pddl import write_pddl
from gnppdsl.compile.sas_writer import write_sas
from gnppdsl.compile.task import build_task
from gnppdsl.errors import UserError
from gnppdsl.ir import model as m
from gnppdsl.ir.expr import Obj, Param

# (problem, with_clear) -> optimal plan length of the logical task alone (hand-counted)
CASES = [("p1", False, 2), ("p2", False, 4), ("p5", False, 2), ("p1", True, 2), ("p2", True, 4)]


@pytest.mark.parametrize("name,clear,expected", CASES)
def test_fd_finds_expected_optimum(name, clear, expected):
    task = build_task(planar_ir.problem(name, with_clear=clear))
    result = run_fd_on_sas(write_sas(task))
    assert result.solved and result.cost == expected == len(result.plan)
    assert optimal_cost(task) == expected
    assert task.goal.holds_in(run_plan(task, result.plan)[-1])


@pytest.mark.parametrize("name,clear,expected", CASES)
def test_pddl_round_trip_through_fd_translator(name, clear, expected):
    task = build_task(planar_ir.problem(name, with_clear=clear))
    out = write_pddl(task)
    from pddl.parser.domain import DomainParser
    from pddl.parser.problem import ProblemParser
    DomainParser()(out.domain)
    ProblemParser()(out.problem)
    result = run_fd_on_sas(translate_pddl(out.domain, out.problem))
    assert result.solved and result.cost == expected


def test_variables_domains_and_initial_state():
    task = build_task(planar_ir.problem("p2"), prune=False)
    names = [v.name for v in task.variables]
    assert names == ["parent(b1)", "parent(b2)", "holding(g)", "initial"]
    assert task.variables[0].values == ("s1", "s2", "ra", "rb", "g")      # place | gripper
    assert task.variables[2].values == ("b1", "b2", "none")
    assert task.state_str(task.initial) == "{parent(b1) = s1, parent(b2) = s2, holding(g) = none, initial}"
    assert task.partial_state_str(task.goal) == "{parent(b1) = rb, parent(b2) = ra}"
    # relaxed reachability: b1 never rests on s2 (place only puts into regions), b2 never on s1
    pruned = build_task(planar_ir.problem("p2"))
    assert [v.name for v in pruned.variables] == names
    assert pruned.variables[0].values == ("s1", "ra", "rb", "g")
    assert pruned.variables[1].values == ("s2", "ra", "rb", "g")
    assert pruned.state_str(pruned.initial) == task.state_str(task.initial)
    assert pruned.partial_state_str(pruned.goal) == task.partial_state_str(task.goal)
    assert {op.name for op in pruned.operators} < {op.name for op in task.operators}
    assert "pick(b1, g, s2)" in {op.name for op in task.operators} - {op.name for op in pruned.operators}


def test_grounding_drops_impossible_operators_and_sets_marker():
    task = build_task(planar_ir.problem("p5"))
    names = {op.name for op in task.operators}
    # handover needs g != h: the two self-handovers are dropped
    assert {"handover(b1, g1, g2)", "handover(b1, g2, g1)"} <= names
    assert "handover(b1, g1, g1)" not in names
    # pick from any place (spot or region), place only into regions
    assert "pick(b1, g1, s1)" in names and "place(b1, g1, s1)" not in names
    marker = task.var_index("initial")
    for op in task.operators:
        assert any(e.var == marker and e.value == 0 and not e.conditions for e in op.effects)


def test_not_exists_compiles_to_stratified_axioms():
    task = build_task(planar_ir.problem("p2", with_clear=True))
    clear = task.var_index("clear(ra)")
    aux = [a for a in task.axioms if a.var == clear]
    assert len(aux) == 1 and len(aux[0].conditions) == 1
    (v, val), = aux[0].conditions
    assert val == 0 and task.variables[v].is_derived
    assert task.variables[v].axiom_layer < task.variables[clear].axiom_layer
    # the auxiliary variable is `exists o . parent(o) = ra`: one axiom per block
    assert sorted(task.fact_str(a.conditions[0]) for a in task.axioms if a.var == v) == \
        ["parent(b1) = ra", "parent(b2) = ra"]
    # clear(ra) holds initially, fails once b1 is placed there
    states = run_plan(task, ["pick(b1, g, s1)", "place(b1, g, ra)"])
    assert states[0][clear] == 1 and states[2][clear] == 0
    # place into an occupied region is now impossible: b2 cannot join b1 in ra
    with pytest.raises(AssertionError, match="not applicable"):
        run_plan(task, ["pick(b1, g, s1)", "place(b1, g, ra)", "pick(b2, g, s2)", "place(b2, g, ra)"])


def test_neq_precondition_on_multivalued_variable_uses_derived_variable():
    p = planar_ir.problem("p1")
    act = p.domain.actions["pick"]
    # add `parent(o) != r1` (cannot pick from r1) to pick
    act2 = m.Action(act.name, act.params, act.pre + (m.StateLit("parent", (Param("o"),), Obj("r1"), True),),
                    act.effects, act.cost)
    dom = m.Domain(**{**p.domain.__dict__, "actions": {**p.domain.actions, "pick": act2}})
    p2 = m.Problem(**{**p.__dict__, "domain": dom})
    task = build_task(p2)
    neq = task.var_index("parent(b1) != r1")
    assert task.variables[neq].is_derived
    assert sorted(task.fact_str(a.conditions[0]) for a in task.axioms if a.var == neq) == \
        ["parent(b1) = g", "parent(b1) = s1"]
    assert optimal_cost(task) == 2
    res = run_fd_on_sas(write_sas(task))
    assert res.cost == 2


def test_missing_initial_value_is_a_user_error():
    p = planar_ir.problem("p1", drop_init=[("parent", "b1")])
    with pytest.raises(UserError, match=r"no initial value for parent\(b1\)"):
        build_task(p)


def test_missing_boolean_and_none_default():
    p = planar_ir.problem("p1", drop_init=[("holding", "g")])
    task = build_task(p)
    assert task.state_str(initial(task)).startswith("{parent(b1) = s1, holding(g) = none")


def test_bad_initial_value_is_a_user_error():
    p = planar_ir.problem("p1", init_overrides={("parent", "b1"): "b1"})
    with pytest.raises(UserError, match="not a possible value"):
        build_task(p)


def _with_derived(problem, derived: dict, goal=None):
    dom = m.Domain(**{**problem.domain.__dict__, "derived": {**problem.domain.derived, **derived}})
    fields = {**problem.__dict__, "domain": dom}
    if goal is not None:
        fields["goal"] = goal
    return m.Problem(**fields)


def test_recursive_derived_predicate_with_negation_on_top():
    # above(x, y) := parent(x) = y or exists z . parent(x) = z and above(z, y)   (positive recursion)
    # free(y) := not exists x . above(x, y)                                        (negation on top)
    P, tp = Param, planar_ir.tp
    above = m.Derived("above", (tp("x", "block"), tp("y", "place", "block")), m.Or((
        m.StateLit("parent", (P("x"),), P("y")),
        m.Exists((tp("z", "block"),), m.And((m.StateLit("parent", (P("x"),), P("z")),
                                             m.DerivedLit("above", (P("z"), P("y")))))))))
    free = m.Derived("free", (tp("y", "place"),),
                     m.Not(m.Exists((tp("x", "block"),), m.DerivedLit("above", (P("x"), P("y"))))))
    p = planar_ir.problem("p2")
    # let blocks stack: parent may be a block too
    sv = p.domain.state_vars["parent"]
    dom = m.Domain(**{**p.domain.__dict__, "state_vars": {**p.domain.state_vars, "parent": m.StateVar(
        "parent", sv.params, ("place", "gripper", "block"))}})
    p = m.Problem(**{**p.__dict__, "domain": dom})
    p = _with_derived(p, {"above": above, "free": free},
                      goal=(m.DerivedLit("free", (Obj("s1"),)), m.DerivedLit("above", (Obj("b2"), Obj("rb")))))
    task = build_task(p)
    lay = {v.name: v.axiom_layer for v in task.variables if v.is_derived}
    assert lay["above(b1, s1)"] == lay["above(b2, b1)"]          # one recursive stratum
    assert lay["free(s1)"] > lay["above(b1, s1)"]
    # optimum 3: pick(b2, g, s2), place(b2, g, rb), pick(b1, g, s1) (b1 held: nothing above s1)
    assert optimal_cost(task) == 3
    res = run_fd_on_sas(write_sas(task))
    assert res.solved and res.cost == 3
    assert task.goal.holds_in(run_plan(task, res.plan)[-1])


def test_negation_through_recursion_is_rejected():
    P, tp = Param, planar_ir.tp
    bad = m.Derived("bad", (tp("x", "place"),), m.Not(m.DerivedLit("bad", (P("x"),))))
    with pytest.raises(UserError, match="not stratified"):
        build_task(_with_derived(planar_ir.problem("p1"), {"bad": bad}))
