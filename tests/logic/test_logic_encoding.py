"""The emitted ASP text on its own: incmode's protocol (base, then step(t)/check(t) with
query(t) true only for the current t) finds the shortest plan, as the planner does."""
import clingo

from gnppdsl.logic.encoding import conflict_program, encode_task
from gnppdsl.logic.generators import reverse_tower_task
from gnppdsl.logic.validate import validate_plan


def incmode(text: str, imax: int = 20):
    """What `clingo FILE` does with `#include <incmode>.` (istop=SAT)."""
    ctl = clingo.Control(["--warn=none"])
    ctl.add("base", [], text)
    ctl.ground([("base", []), ("check", [clingo.Number(0)])])
    for t in range(0, imax + 1):
        if t > 0:
            ctl.release_external(clingo.Function("query", [clingo.Number(t - 1)]))
            ctl.ground([("step", [clingo.Number(t)]), ("check", [clingo.Number(t)])])
        ctl.assign_external(clingo.Function("query", [clingo.Number(t)]), True)
        models = []
        ctl.solve(on_model=lambda m: models.append(m.symbols(shown=True)))
        if models:
            occ = sorted((s.arguments[1].number, s.arguments[0].number)
                         for s in models[0] if s.name == "occurs")
            return [o for _, o in occ]
    return None


def test_standalone_program_finds_the_shortest_plan():
    task = reverse_tower_task(4)
    text = encode_task(task, standalone=True)
    assert text.splitlines()[1] == "#include <incmode>."
    for part in ("#program base.", "#program step(t).", "#program check(t).", "#external query(t)."):
        assert part in text
    plan = incmode(text)
    assert len(plan) == 8 and validate_plan(task, plan).valid


def test_conflict_program_text():
    from gnppdsl.compile.sas import PartialState
    text = conflict_program("c", [PartialState(((0, 1), (2, 0))), PartialState(), PartialState(((1, 3),))])
    assert text == ("#program c(t).\n:- holds(0,1,t-2), holds(2,0,t-2), holds(1,3,t), "
                    "not idle(t), t >= 2.\n")
