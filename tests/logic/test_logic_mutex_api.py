"""The public helpers of `logic.mutex` that `logic.lower_bound` builds on: axioms grouped by the
derived variable they define, and the state facts a conjunction of derived tests implies or
excludes (`clear(x) := not exists o . parent(o) = x`)."""
from gnppdsl.compile.sas import Axiom, PartialState, SASTask, SASVariable
from gnppdsl.logic import mutex


def _clear_task() -> SASTask:
    # parent(a), parent(b) in {table, a, b}; clear(a) := parent(b) != a (one axiom per support
    # in the negated form: not_clear(a) := parent(b) = a); held(a) := parent(a) = table
    variables = [SASVariable("parent(a)", ("table", "a", "b")),
                 SASVariable("parent(b)", ("table", "a", "b")),
                 SASVariable("covered(a)", ("false", "true"), axiom_layer=0),
                 SASVariable("on_table(a)", ("false", "true"), axiom_layer=0)]
    axioms = [Axiom(((1, 1),), 2), Axiom(((0, 0),), 3)]
    return SASTask(variables, (0, 0, 0, 0), PartialState(((0, 0),)), [], axioms, name="clear")


def test_axioms_by_var_groups_by_derived_variable():
    task = _clear_task()
    by_var = mutex.axioms_by_var(task)
    assert sorted(by_var) == [2, 3]
    assert by_var[2] == [task.axioms[0]] and by_var[3] == [task.axioms[1]]


def test_derived_consequences_implied_and_excluded():
    task = _clear_task()
    # covered(a) = false excludes parent(b) = a; on_table(a) = true (one axiom) implies parent(a) = table
    implied, excluded = mutex.derived_consequences(task, [(2, 0), (3, 1)])
    assert implied == {(0, 0)} and excluded == {(1, 1)}
    # state facts in the conjunction are the caller's: nothing follows from them
    assert mutex.derived_consequences(task, [(0, 1)], mutex.axioms_by_var(task)) == (set(), set())


def test_private_names_are_gone():
    assert not hasattr(mutex, "_axioms_by_var") and not hasattr(mutex, "_derived_consequences")
