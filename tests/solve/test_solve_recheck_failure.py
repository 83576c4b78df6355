"""A solution whose factors the independent numpy re-check cannot evaluate is reported as a
solver failure with the evaluator's message, never returned as solved and never a traceback."""
from __future__ import annotations

from pathlib import Path

from gnppdsl.nlp import evaluate
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from gnppdsl.solve.result import SOLVER_FAILURE

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"


def test_a_recheck_that_cannot_evaluate_is_a_solver_failure(monkeypatch):
    def cannot(*args, **kwargs):
        raise evaluate.EvaluationError("toy: primitive 'warp' cannot be evaluated")

    monkeypatch.setattr(evaluate, "max_violation", cannot)
    compiled = load_and_compile(str(PLANAR / "p1_one_block.pntc"))
    res = solve_compiled(compiled, SolveOptions(time_limit=30))
    assert res.status == SOLVER_FAILURE and not res.solved
    assert "cannot be re-checked independently" in res.message and "'warp'" in res.message
