"""The loop's evaluation order "staged" (small relaxations, the full graph, then the large ones)
and the `order` key of `solver { }` blocks: the order of levels follows from the factor counts,
the answers are the same as the other orders' and are checked independently, and a bad order
in a solver block is a located diagnostic."""
from __future__ import annotations

import textwrap
from pathlib import Path

import pytest

from gnppdsl.errors import UserError
from gnppdsl.solve import loop
from gnppdsl.solve.loop import SolveOptions, load_and_compile, solve_compiled
from solve_checks import check_conflict_infeasible, check_solution

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"


class _G:
    """A stand-in for a GraphNLP: only the factor counts matter to the level order."""

    def __init__(self, n: int, modes: int | None = None):
        self.n_factors, self._modes = n, modes

    def apply_relaxation(self, dropped, name=""):
        assert set(dropped) == {loop.TRAJ}
        return _G(self._modes)


def test_staged_puts_small_levels_first_and_large_ones_after_the_full_graph():
    full = (None, _G(300, modes=100))
    a, b, c, d = ("a", _G(30)), ("b", _G(50)), ("c", _G(51)), ("d", _G(90))
    # a and b have at most half of the 100 mode-switch factors; c and d more
    assert loop._Run.staged(full[1], [a, b, c, d, full]) == [a, b, full, c, d, full]
    # no large level: the full graph once, last (Alg. 1 searches it if it is infeasible)
    assert loop._Run.staged(full[1], [a, b, full]) == [a, b, full]
    # no trajectories: the mode-switch graph is the full graph
    plain = (None, _G(80, modes=0))
    assert loop._Run.staged(plain[1], [a, c, plain]) == [a, plain, c, plain]


@pytest.mark.parametrize("name, n", [("p3_occupied", 4), ("t1_swap", None)])
def test_staged_answers_are_checked_independently(name, n):
    c = load_and_compile(str(PLANAR / f"{name}.pntc"))
    staged = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, order="staged"))
    full = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, order="full_first"))
    assert staged.solved and full.solved
    assert staged.stats.N == full.stats.N and (n is None or staged.stats.N == n)
    check_solution(c, staged)
    for conflict in staged.conflicts:
        check_conflict_infeasible(c, conflict)


def _problem(tmp_path, solver_line: str) -> Path:
    dom = (PLANAR / "domain.pntc").read_text()
    (tmp_path / "domain.pntc").write_text(dom)
    prob = (PLANAR / "p1_one_block.pntc").read_text()
    (tmp_path / "p1_one_block.pntc").write_text(prob + "\n" + solver_line + "\n")
    for extra in PLANAR.glob("*.yaml"):
        (tmp_path / extra.name).write_text(extra.read_text())
    return tmp_path / "p1_one_block.pntc"


def test_order_in_a_solver_block_reaches_the_options_and_the_command_line_wins(tmp_path):
    c = load_and_compile(str(_problem(tmp_path, "solver { order = staged }")))
    assert c.problem.settings.order == "staged"
    assert SolveOptions.from_settings(c.problem.settings).order == "staged"
    assert SolveOptions.from_settings(c.problem.settings, order="relaxed_first").order == "relaxed_first"
    # without the key: the solver's default
    plain = load_and_compile(str(PLANAR / "p1_one_block.pntc"))
    assert plain.problem.settings.order is None
    assert SolveOptions.from_settings(plain.problem.settings).order == SolveOptions().order


def test_unknown_order_in_a_solver_block_is_a_located_error(tmp_path):
    path = _problem(tmp_path, "solver { order = stagd }")
    with pytest.raises(UserError) as e:
        load_and_compile(str(path))
    text = str(e.value)
    assert "unknown order 'stagd'" in text and "staged" in text
    line = len(path.read_text().splitlines())
    assert f"p1_one_block.pntc:{line}:" in text, text


def test_unknown_order_option_is_a_user_error():
    with pytest.raises(UserError, match="full_first, relaxed_first or staged"):
        SolveOptions(order="sideways").validated()
