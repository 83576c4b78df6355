"""The `.sas` and PDDL writers, checked by Fast Downward and the `pddl` package."""
from __future__ import annotations

import pytest

from gnppdsl.compile.pddl import pddl_name, write_pddl
from gnppdsl.compile.sas import Axiom, SASTask, SASVariable, PartialState
from gnppdsl.compile.sas_writer import check_axiom_layers, write_sas

import handmade_tasks as hm
from fd_oracle import run_fd_on_sas, translate_pddl
from sas_semantics import optimal_cost, run_plan


@pytest.mark.parametrize("name", sorted(hm.ALL))
def test_fd_solves_written_sas_optimally(name):
    task = hm.ALL[name]()
    expected = optimal_cost(task)
    result = run_fd_on_sas(write_sas(task))
    assert result.solved
    assert result.cost == expected
    states = run_plan(task, result.plan)          # independent validation of FD's plan
    assert task.goal.holds_in(states[-1])
    assert sum(task.operators[[o.name for o in task.operators].index(n)].cost for n in result.plan) == expected


def test_fd_proves_unsolvable():
    assert not run_fd_on_sas(write_sas(hm.unsolvable_task())).solved


def test_expected_blocks_optimum():
    # b2 off b1 onto a spot (1 + 2), b1 onto... hand count: pick b3? no: goal b1 on b2 on b3.
    # pick(b2,b1) place(b2,b3) pick(b1,s1) place(b1,b2): costs 1+1+1+1 = 4.
    assert optimal_cost(hm.blocks_task()) == 4


def test_sas_text_structure():
    text = write_sas(hm.counter_task())
    assert text.startswith("begin_version\n3\nend_version\nbegin_metric\n1\nend_metric\n3\n")
    # `finish` requires flag = 1 and changes flag: the precondition moves into the effect
    block = text.split("begin_operator\nfinish\n", 1)[1].split("end_operator")[0].splitlines()
    assert block[0] == "1" and block[1] == "0 0"          # prevail: counter = c0
    assert "0 1 1 0" in block                              # flag: pre 1 -> post 0
    assert block[-1] == "3"
    # noop_flag changes nothing: FD rejects effect-less operators, so it is left out
    assert "noop_flag" not in text
    assert text.count("begin_operator") == 3


def test_axiom_layer_check_rejects_unstratified():
    variables = [SASVariable("x", hm.BOOL), SASVariable("d", hm.BOOL, 0), SASVariable("e", hm.BOOL, 0)]
    bad = SASTask(variables, (0, 0, 0), PartialState(), [], [Axiom(((2, 0),), 1, 1), Axiom(((0, 1),), 2, 1)])
    with pytest.raises(ValueError, match="lower layer"):
        check_axiom_layers(bad)
    bad.variables[2] = SASVariable("e", hm.BOOL, 1)
    with pytest.raises(ValueError, match="higher layer"):
        check_axiom_layers(bad)


@pytest.mark.parametrize("name", sorted(hm.ALL))
def test_pddl_parses_with_independent_parser(name):
    from pddl.parser.domain import DomainParser
    from pddl.parser.problem import ProblemParser
    out = write_pddl(hm.ALL[name]())
    domain = DomainParser()(out.domain)
    problem = ProblemParser()(out.problem)
    assert len(domain.actions) == len(hm.ALL[name]().operators)
    assert problem.domain_name == domain.name


@pytest.mark.parametrize("name", sorted(hm.ALL))
def test_fd_translator_accepts_pddl_and_finds_same_optimum(name):
    task = hm.ALL[name]()
    out = write_pddl(task)
    sas = translate_pddl(out.domain, out.problem)
    result = run_fd_on_sas(sas)
    assert result.solved
    assert result.cost == optimal_cost(task)
    # the PDDL plan is a plan of the SAS+ task too
    plan = [out.action_names[n.split()[0]] for n in result.plan]
    states = run_plan(task, plan)
    assert task.goal.holds_in(states[-1])


def test_pddl_names_are_legal_and_injective():
    assert pddl_name("pick(b1, g, s1)") == "pick_b1_g_s1"
    assert pddl_name("_occupied(x)") == "occupied_x"
    assert pddl_name("9lives") == "x_9lives"
    assert pddl_name("and") == "x_and"
    out = write_pddl(hm.blocks_task())
    assert len(set(out.action_names)) == len(out.action_names)


def test_pddl_predicate_names_do_not_collide():
    # a derived `on(a)` (0-ary predicate on_a) and a boolean state variable `on_a` must differ
    variables = [SASVariable("on_a", hm.BOOL), SASVariable("on(a)", hm.BOOL, 0)]
    from gnppdsl.compile.sas import Operator, Effect
    task = SASTask(variables, (0, 0), PartialState.of([(1, 1)]),
                   [Operator("go", (), (Effect(0, 1),))], [Axiom(((0, 1),), 1, 1)])
    out = write_pddl(task)
    assert "(on_a)" in out.domain and "(on_a-2)" in out.domain
    result = run_fd_on_sas(translate_pddl(out.domain, out.problem))
    assert result.solved and result.cost == 1
