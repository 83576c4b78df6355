"""Progress of `gnpp solve` / `gnpp bench` (gnppdsl.cli.status): a line per plan on a pipe whose
count equals the plans the result reports, nothing with --quiet, a redrawn and finally erased
line on a terminal (the ticker keeps redrawing between solver events)."""
from __future__ import annotations

import io
import json
import re
from pathlib import Path

from gnppdsl.cli.main import main
from gnppdsl.cli.status import BenchStatus, SolveStatus
from gnppdsl.solve.result import Stats

P3 = Path(__file__).resolve().parents[2] / "examples" / "planar" / "p3_occupied.pntc"


class _Tty(io.StringIO):
    def isatty(self) -> bool:
        return True


def test_plain_lines_one_per_plan_and_quiet_is_silent(capsys, tmp_path):
    out = tmp_path / "r.json"
    assert main(["solve", str(P3), "--json", str(out)]) == 0
    err = capsys.readouterr().err
    data = json.loads(out.read_text())
    lines = [ln for ln in err.splitlines() if ln.startswith("p3_occupied: plans")]
    assert len(lines) == data["stats"]["plans"] == 2
    assert [int(re.search(r"plans (\d+)", ln).group(1)) for ln in lines] == [1, 2]
    assert "(length 2)" in lines[0] and "(length 4)" in lines[1] and "of 60 s" in lines[0]
    assert "\x1b" not in err and "\r" not in err
    assert main(["solve", str(P3), "--quiet"]) == 0
    assert capsys.readouterr().err == ""


def test_terminal_line_is_redrawn_and_erased():
    from gnppdsl.solve import load_and_compile, solve_compiled

    compiled = load_and_compile(str(P3))
    stream = _Tty()
    with SolveStatus("p3", 60.0, stream=stream, interval=0.01) as status:
        result = solve_compiled(compiled, progress=status)
    text = stream.getvalue()
    draws = text.count("\r") - 1
    assert result.solved and "\n" not in text
    assert draws > 5                              # events and ticks
    assert text.endswith("\r\x1b[K")              # nothing left on the terminal
    assert f"plans {result.stats.plans}" in text.split("\r")[-2]


def test_watched_stats_and_echo():
    stats = Stats(plans=3, conflicts=2, nlp_solves=7)
    echoed = []
    stream = _Tty()
    status = SolveStatus("p", 10, stream=stream, echo=echoed.append)
    status.watch(stats)
    status("plan #3 (length 4): a, b")
    assert echoed == ["plan #3 (length 4): a, b"]
    assert "plans 3 (length 4) · conflicts 2 · NLPs 7" in status.text() and "of 10 s" in status.text()


def test_bench_status():
    stream = _Tty()
    with BenchStatus(2, stream=stream, interval=10) as status:
        status.print_row("p1  gnpp: solved")
        assert "bench: 1 of 2 runs · last p1  gnpp" in status.text() and "left" in status.text()
    assert "p1  gnpp: solved\n" in stream.getvalue()


def test_bench_status_live_run_and_per_run_figures():
    """The bench line shows the running solve's plans and NLPs (its live `Stats`) and, once
    rows come in, plans and NLPs per run; both checked against the solve's own `Result`."""
    from gnppdsl.cli.sweep import Cell, result_row
    from gnppdsl.solve import load_and_compile, solve_compiled

    compiled = load_and_compile(str(P3))
    stream = _Tty()
    with BenchStatus(2, stream=stream, interval=10) as status:
        progress = status.run_progress("p3 gnpp seed 0")
        result = solve_compiled(compiled, progress=progress)
        live = status.text()
        s = result.stats
        assert f"now p3 gnpp seed 0: plans {s.plans}, NLPs {s.nlp_solves}" in live, live
        row = result_row(Cell(str(P3), "gnpp", 0), result)
        status.print_row("p3 gnpp seed 0: solved", row)
        status.print_row("p3 gnpp seed 1: error", {"plans": None, "nlp_solves": None})
        after = status.text()
    assert "now " not in after and "last p3 gnpp seed 1" in after
    assert f"per run {s.plans / 2:.1f} plans, {s.nlp_solves / 2:.1f} NLPs" in after, after
    assert s.plans == 2 and s.nlp_solves > 0          # p3 needs the second plan
    drawn = stream.getvalue()                         # redrawn live at the solver's messages
    assert "now p3 gnpp seed 0: plans 1," in drawn and "now p3 gnpp seed 0: plans 2," in drawn
