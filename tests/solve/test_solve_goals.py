"""A disjunctive goal through the whole loop: GNPP's solution length equals brute force's (every
logical plan in order of length, each full graph-NLP solved from several starts, no conflicts:
`gnppdsl.solve.brute`), and `solve_checks.check_solution` re-validates the plan against the
compiled goal and re-evaluates every factor."""
from __future__ import annotations

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from solve_checks import check_solution  # noqa: E402

from gnppdsl.solve.brute import brute_force  # noqa: E402
from gnppdsl.solve.compiled import load_and_compile  # noqa: E402
from gnppdsl.solve.loop import solve_compiled  # noqa: E402
from gnppdsl.solve.options import SolveOptions  # noqa: E402

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"


def test_disjunctive_goal_gnpp_length_equals_brute_force(tmp_path):
    # b1 into the occupied target (needs b2 moved first) or both blocks into the side region
    goal = "goal { parent(b1) = target or (parent(b1) = side and parent(b2) = side) }"
    (tmp_path / "domain.pntc").write_text((PLANAR / "domain.pntc").read_text())
    text = (PLANAR / "p3_occupied.pntc").read_text()
    (tmp_path / "p3_occupied.pntc").write_text(text.replace("goal { parent(b1) = target }", goal))
    (tmp_path / "p3_occupied.yaml").write_text((PLANAR / "p3_occupied.yaml").read_text())
    comp = load_and_compile(str(tmp_path / "p3_occupied.pntc"))
    bf = brute_force(comp, 4)
    assert bf.exhausted and bf.shortest == 4
    r = solve_compiled(comp, SolveOptions.from_settings(comp.problem.settings, time_limit=120))
    assert r.solved, r.message
    assert r.stats.N0 == 2 and r.stats.N == bf.shortest
    check_solution(comp, r)
