"""`gnpp bench --jit`: the derivative kernels are compiled in an untimed warm-up solve per
problem file and algorithm before the timed runs (gnppdsl.cli.kernel_warmup), and the output
says so. Oracle: the solves `bench` asks for (recorded around `sweep.solve_cell`) and the CSV
it writes; without `--jit` no warm-up solve happens."""
from __future__ import annotations

import csv
from pathlib import Path

from gnppdsl.cli import sweep
from gnppdsl.cli.kernel_warmup import WarmUp, warm_up_cells
from gnppdsl.cli.main import main
from gnppdsl.cli.sweep import Cell

ROOT = Path(__file__).resolve().parents[2]
P1 = str(ROOT / "examples" / "planar" / "p1_one_block.pntc")
P3 = str(ROOT / "examples" / "planar" / "p3_occupied.pntc")


def _recorded(monkeypatch, csv_path: Path) -> list[tuple]:
    calls: list[tuple] = []
    real = sweep.solve_cell

    def solve_cell(cell, settings, compiled=None, progress=None):
        rows_before = len(list(csv.DictReader(open(csv_path)))) if csv_path.exists() else 0
        calls.append((cell.file, cell.algorithm, cell.seed, settings.jit, rows_before))
        return real(cell, settings, compiled, progress)

    monkeypatch.setattr(sweep, "solve_cell", solve_cell)
    return calls


def test_jit_bench_warms_up_once_per_problem_and_algorithm_before_timed_runs(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("GNPP_JIT", "1")              # the suite's conftest turns jit off
    monkeypatch.setenv("GNPP_JIT_CACHE", str(tmp_path / "jit"))
    out_csv, md = tmp_path / "runs.csv", tmp_path / "table.md"
    calls = _recorded(monkeypatch, out_csv)
    assert main(["bench", P1, P3, "--algorithms", "gnpp_trn,oneway", "--seeds", "2", "--time-limit", "60",
                 "--jit", "--csv", str(out_csv), "--markdown", str(md), "--quiet"]) == 0
    rows = list(csv.DictReader(open(out_csv)))
    assert len(rows) == 2 * 2 * 2                      # only the timed runs are rows
    warm, timed = calls[:4], calls[4:]
    assert len(timed) == 8
    # one warm-up per (file, algorithm), the first seed, all before any row was written
    assert sorted((f, a, s) for f, a, s, _, _ in warm) == sorted(
        (f, a, 0) for f in (P1, P3) for a in ("gnpp_trn", "oneway"))
    assert all(jit and before == 0 for _, _, _, jit, before in warm)
    assert all(jit for _, _, _, jit, _ in timed)
    out = capsys.readouterr().out
    assert "untimed warm-up" in out and "in no run's cpu_time" in out
    assert "untimed warm-up" in md.read_text()


def test_bench_without_jit_has_no_warm_up(tmp_path, monkeypatch, capsys):
    out_csv = tmp_path / "runs.csv"
    calls = _recorded(monkeypatch, out_csv)
    assert main(["bench", P1, "--algorithms", "gnpp_trn", "--seeds", "2", "--time-limit", "60",
                 "--csv", str(out_csv), "--quiet"]) == 0
    assert len(calls) == 2 and not any(c[3] for c in calls)
    assert "warm-up" not in capsys.readouterr().out


def test_warm_up_cells_first_of_each_file_and_algorithm():
    cells = [Cell("a.pntc", "rlgp", 0, i) for i in range(3)] + [Cell("a.pntc", "gnpp", 0, i) for i in range(3)] \
        + [Cell("b.pntc", "rlgp", s) for s in (2, 3)]
    assert warm_up_cells(cells) == [Cell("a.pntc", "rlgp", 0, 0), Cell("a.pntc", "gnpp", 0, 0), Cell("b.pntc", "rlgp", 2)]
    assert WarmUp().note() == ""


def test_no_warm_up_when_the_environment_turns_jit_off(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("GNPP_JIT", "0")
    out_csv = tmp_path / "runs.csv"
    calls = _recorded(monkeypatch, out_csv)
    assert main(["bench", P1, "--algorithms", "gnpp_trn", "--seeds", "2", "--time-limit", "60", "--jit",
                 "--csv", str(out_csv), "--quiet"]) == 0
    assert len(calls) == 2                                # the timed runs only
    assert "warm-up" not in capsys.readouterr().out
