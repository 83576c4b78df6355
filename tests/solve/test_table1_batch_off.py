"""The Table I problems whose solver settings turn the renamed-conflict batch off
(`batch_conflicts = 0`, docs/design.md "Table I: where the time goes, 28 Nov"): lab1_paper,
lab3_paper, field2 and field3, measured faster without it and with the same plans; the rows whose
plans the batch spares (lab4_paper, lab5_paper, work1-3, field4) keep it."""
from pathlib import Path

import pytest

from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.options import SolveOptions

ROOT = Path(__file__).resolve().parents[2] / "examples"
OFF = ["lab/lab1_paper.pntc", "lab/lab3_paper.pntc", "field/field2.pntc", "field/field3.pntc"]
ON = ["scalability/lab4_paper.pntc", "workshop/work1.pntc", "field/field4.pntc"]


def options(rel: str) -> SolveOptions:
    compiled = load_and_compile(ROOT / rel)
    return SolveOptions.from_settings(compiled.problem.settings, switches="trng")


@pytest.mark.parametrize("rel", OFF)
def test_batch_off_where_measured_faster(rel):
    opts = options(rel)
    assert opts.batch_conflicts == 0
    assert opts.switches == "trng"          # the command line still overrides the problem's settings


@pytest.mark.parametrize("rel", ON)
def test_batch_kept_where_it_spares_plans(rel):
    assert options(rel).batch_conflicts > 0
