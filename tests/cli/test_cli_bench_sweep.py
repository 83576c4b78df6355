"""`gnpp bench` sweeps: Ray gives the serial rows, a killed sweep resumes and loses nothing,
every way a run can end is a row, a CSV that is not ours is never touched.

The oracle for the Ray sweep is the serial run in this process (deterministic counts: NLP
solves, plans, conflicts, N0, N for fixed seeds); for the resume it is the CSV written before
the kill, byte for byte.
"""
from __future__ import annotations

import csv
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from gnppdsl.cli.main import main
from gnppdsl.cli.sweep import (CSV_FIELDS, RUN_MEMORY, RUN_TIMEOUT, Cell, CsvJournal, RunSettings,
                               solve_cell_isolated)
from gnppdsl.errors import UserError

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "examples" / "planar"
SMALL = [str(PLANAR / "p1_one_block.pntc"), str(PLANAR / "p3_occupied.pntc")]
# what a fixed seed determines (times do not repeat)
DETERMINED = ("problem", "file", "algorithm", "seed", "status", "solved", "nlp_solves", "plans",
              "conflicts", "N0", "N")


def read_rows(path: Path) -> list[dict]:
    with open(path, newline="") as fh:
        return list(csv.DictReader(fh))


def determined(rows: list[dict]) -> list[tuple]:
    return sorted(tuple(r[k] for k in DETERMINED) for r in rows)


def bench(*args: str) -> int:
    return main(["bench", *args, "--quiet"])


def test_ray_two_workers_give_the_serial_rows(tmp_path, capsys):
    pytest.importorskip("ray", reason="ray (optional external package) is not installed")
    serial, ray_csv = tmp_path / "serial.csv", tmp_path / "ray.csv"
    common = [*SMALL, "--algorithms", "oneway,gnpp_trn", "--seeds", "2", "--time-limit", "30"]
    assert bench(*common, "--csv", str(serial)) == 0
    assert bench(*common, "--csv", str(ray_csv), "--workers", "2") == 0
    rows_serial, rows_ray = read_rows(serial), read_rows(ray_csv)
    assert len(rows_serial) == 2 * 2 * 2
    assert all(r["status"] == "solved" for r in rows_serial)
    assert determined(rows_ray) == determined(rows_serial)
    out = capsys.readouterr().out
    assert "p3_occupied" in out and "2/2" in out     # the table, 2 seeds per cell


def _run_sweep_in_child(csv_path: Path, files: list[str]) -> subprocess.Popen:
    code = ("import sys; from gnppdsl.cli.main import main; "
            f"sys.exit(main(['bench', *{files!r}, '--algorithms', 'oneway,gnpp_trn', '--seeds', '3', '--time-limit', '600', "
            f"'--csv', {str(csv_path)!r}, '--quiet']))")
    return subprocess.Popen([sys.executable, "-c", code], stdout=subprocess.DEVNULL,
                            stderr=subprocess.DEVNULL, cwd=ROOT)


def test_killed_sweep_resumes_and_loses_nothing(tmp_path):
    path = tmp_path / "sweep.csv"
    files = [str(PLANAR / n) for n in ("p1_one_block.pntc", "p3_occupied.pntc", "p5_handover.pntc")]
    proc = _run_sweep_in_child(path, files)
    deadline = time.monotonic() + 120
    while time.monotonic() < deadline and proc.poll() is None:
        if path.exists() and len(read_rows(path)) >= 2:
            break
        time.sleep(0.05)
    killed = proc.poll() is None
    if killed:
        proc.send_signal(signal.SIGKILL)
    proc.wait()
    before = path.read_bytes()
    n_before = len(read_rows(path))
    assert n_before >= 2
    # a row cut short by the kill (simulated for certain: a partial line at the end) is run again
    with open(path, "ab") as fh:
        fh.write(b"p9,half a row")
    assert bench(*files, "--algorithms", "oneway,gnpp_trn", "--seeds", "3", "--time-limit", "600",
                 "--csv", str(path)) == 0
    after = path.read_bytes()
    assert after.startswith(before), "rows written before the kill must stay as they were"
    rows = read_rows(path)
    keys = [(r["file"], r["algorithm"], r["seed"]) for r in rows]
    assert len(keys) == len(set(keys)) == 3 * 2 * 3, "each run exactly once"
    assert all(r["status"] in ("solved", "time_limit") for r in rows)   # (wall-clock limit: a loaded machine)
    assert b"half a row" not in after


def test_a_run_killed_for_time_or_memory_is_a_row():
    lab4 = str(ROOT / "examples" / "lab" / "lab4.pntc")      # several CPU seconds at least
    row = solve_cell_isolated(Cell(lab4, "gnpp_trn", 0), RunSettings(time_limit=60, run_timeout=1.0))
    assert row["status"] == RUN_TIMEOUT and row["solved"] is False and row["seed"] == 0
    row = solve_cell_isolated(Cell(SMALL[0], "gnpp_trn", 0), RunSettings(time_limit=10, memory_mb=100))
    assert row["status"] == RUN_MEMORY
    row = solve_cell_isolated(Cell(SMALL[0], "gnpp_trn", 1), RunSettings(time_limit=10, memory_mb=4000))
    assert row["status"] == "solved" and row["seed"] == 1 and int(row["N"]) == 2


def test_a_csv_that_is_not_a_bench_csv_is_refused_untouched(tmp_path, capsys):
    foreign = tmp_path / "data.csv"
    foreign.write_text("a,b,c\n1,2,3\n")
    assert bench(SMALL[0], "--seeds", "1", "--algorithms", "oneway", "--csv", str(foreign)) == 2
    assert foreign.read_text() == "a,b,c\n1,2,3\n"
    assert "not a gnpp bench CSV" in capsys.readouterr().err
    link = tmp_path / "link.csv"
    link.symlink_to(foreign)
    with pytest.raises(UserError, match="symbolic link"):
        CsvJournal(link)


def test_journal_header_is_the_field_list(tmp_path):
    j = CsvJournal(tmp_path / "new.csv").open()
    j.append({"problem": "p", "file": "f", "algorithm": "oneway", "seed": 0, "status": "solved", "solved": True})
    j.close()
    rows = read_rows(tmp_path / "new.csv")
    assert tuple(rows[0].keys()) == CSV_FIELDS
    assert rows[0]["status"] == "solved" and rows[0]["N0"] == ""
    assert CsvJournal(tmp_path / "new.csv").done() == {("f", "oneway", "0", "")}   # no instance


def test_csv_in_a_new_directory_is_created(tmp_path):
    path = tmp_path / "out" / "bench.csv"
    assert bench(SMALL[0], "--seeds", "1", "--algorithms", "oneway", "--csv", str(path)) == 0
    assert [r["status"] for r in read_rows(path)] == ["solved"]


def test_bench_planner_reaches_the_solver(tmp_path, capsys):
    pytest.importorskip("up_fast_downward", reason="up-fast-downward (optional external package) is not installed")
    import yaml

    expected = yaml.safe_load((PLANAR / "expected.yaml").read_text())["problems"]["p3_occupied"]
    rows = {}
    for planner in ("sequential", "fd"):
        path = tmp_path / f"{planner}.csv"
        assert bench(SMALL[1], "--seeds", "1", "--algorithms", "gnpp_trn", "--planner", planner,
                     "--csv", str(path)) == 0
        (rows[planner],) = read_rows(path)
    assert capsys.readouterr().out.count("logic mode: planner") == 2
    # sequential proves its first plan shortest: the bench's N0 is expected.yaml's; Fast Downward
    # only when its bounded searches below the plan answered "no plan", else its row has no N0
    # (docs/design.md, "Logic modes")
    assert rows["sequential"]["N0"] == str(expected["n0"]) and rows["fd"]["N0"] in ("", str(expected["n0"]))
    assert all(r["status"] == "solved" and r["N"] == str(expected["n"]) for r in rows.values())
    # Fast Downward cannot enumerate plans by length (One-way): refused before any run
    assert bench(SMALL[1], "--seeds", "1", "--algorithms", "oneway,gnpp_trn", "--planner", "fd") == 2
    assert "--planner fd serves the gnpp algorithms only, not oneway" in capsys.readouterr().err


def test_bench_refuses_options_its_runs_would_refuse_before_any_run(tmp_path, capsys):
    """--anytime with One-way (no incumbent to improve) and a last instance --seed + --instances
    - 1 beyond the seed range are refused up front, naming the options, exit 2 (they became an
    error row per run, or an instance `gnpp solve --instance` refuses)."""
    assert bench(SMALL[1], "--seeds", "1", "--algorithms", "oneway,gnpp_trn", "--anytime", "1") == 2
    assert "--anytime serves the gnpp and rlgp algorithms, not oneway" in capsys.readouterr().err
    assert bench(SMALL[1], "--algorithms", "gnpp_trn", "--seed", str(2**32 - 1), "--instances", "2") == 2
    assert "--seed + --instances - 1 4294967296" in capsys.readouterr().err
    assert bench(SMALL[1], "--algorithms", "gnpp_trn", "--seed", "-1") == 2
    assert "--seed -1" in capsys.readouterr().err
