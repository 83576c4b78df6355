"""`gnpp solve` and `gnpp bench` through the real entry point (in process, output captured)."""
from __future__ import annotations

import csv
import json
from pathlib import Path

import pytest

from gnppdsl.cli.bench import format_table, parse_algorithms
from gnppdsl.cli.main import main
from gnppdsl.errors import UserError

PLANAR = Path(__file__).resolve().parents[2] / "examples" / "planar"




def test_algorithm_names():
    specs = parse_algorithms("oneway,gnpp_t,gnpp_tr,gnpp_trn,gnpp_trng,gnpp")
    assert [(s.algorithm, s.switches, s.title) for s in specs] == [
        ("oneway", "", "One-way"), ("gnpp", "t", "GNPP_t"), ("gnpp", "tr", "GNPP_tr"),
        ("gnpp", "trn", "GNPP_trn"), ("gnpp", "trng", "GNPP_trng"), ("gnpp", None, "GNPP")]
    for bad in ("gnpp_x", "foo", "gnpp_tt", ""):
        with pytest.raises(UserError):
            parse_algorithms(bad)


def test_table_layout():
    specs = parse_algorithms("oneway,gnpp_trn")
    rows = [
        {"problem": "p", "algorithm": "oneway", "solved": True, "nlp_solves": 10, "total_time": 1.0, "N0": 2, "N": 4},
        {"problem": "p", "algorithm": "oneway", "solved": True, "nlp_solves": 14, "total_time": 3.0, "N0": 2, "N": 4},
        {"problem": "p", "algorithm": "gnpp_trn", "solved": False, "nlp_solves": 5, "total_time": 9.0, "N0": 2,
         "N": None},
    ]
    text = format_table(["p"], specs, rows)
    lines = text.splitlines()
    assert "One-way" in lines[0] and "GNPP_trn" in lines[0]
    assert "12.0±2.8" in lines[3] and "2.00±1.41" in lines[3] and "2/2" in lines[3] and "0/1" in lines[3]


def test_user_errors_exit_2(capsys, tmp_path):
    assert main(["solve", str(tmp_path / "missing.pntc")]) == 2
    assert "no such file" in capsys.readouterr().err
    assert main(["solve", str(PLANAR / "p3_occupied.pntc"), "--switches", "xyz"]) == 2
    assert "subset of 'trng'" in capsys.readouterr().err
    assert main(["bench", str(tmp_path), "--algorithms", "nope"]) == 2


def test_solve_p3_occupied_json(capsys, tmp_path):
    out = tmp_path / "p3.json"
    code = main(["solve", str(PLANAR / "p3_occupied.pntc"), "--json", str(out)])
    text = capsys.readouterr().out
    assert code == 0, text
    assert "SOLVED" in text and "conflicts" in text and "parent(b1) = target" in text
    data = json.loads(out.read_text())
    assert data["solved"] and data["stats"]["N0"] == 2 and data["stats"]["N"] == 4
    assert len(data["steps"]) == 5 and data["steps"][4]["state"].count("parent(b1) = target") == 1
    assert data["stats"]["max_violation"] <= 1e-6


def test_unsolvable_exit_1_with_reason(capsys):
    code = main(["solve", str(PLANAR / "t2_unreachable.pntc"), "--max-horizon", "3", "--quiet"])
    captured = capsys.readouterr()
    assert code == 1
    assert "no plan up to horizon 3" in captured.err + captured.out


def test_time_limit_exit_1(capsys):
    code = main(["solve", str(PLANAR / "p3_occupied.pntc"), "--time-limit", "0.001", "--quiet"])
    captured = capsys.readouterr()
    assert code == 1 and "time limit" in captured.err + captured.out


def test_bench_writes_table_and_csv(capsys, tmp_path):
    out = tmp_path / "b.csv"
    code = main(["bench", str(PLANAR / "p1_one_block.pntc"), "--algorithms", "oneway,gnpp_trn", "--seeds", "2",
                 "--time-limit", "30", "--csv", str(out), "--quiet"])
    text = capsys.readouterr().out
    assert code == 0
    assert "One-way" in text and "GNPP_trn" in text and "2/2" in text
    rows = list(csv.DictReader(out.open()))
    assert len(rows) == 4 and {r["algorithm"] for r in rows} == {"oneway", "gnpp_trn"}
    assert all(r["solved"] == "True" and r["N"] == "2" for r in rows)


def test_database_file_is_reused_by_a_later_run(capsys, tmp_path):
    db = tmp_path / "planar.sqlite"
    args = ["solve", str(PLANAR / "p3_occupied.pntc"), "--db", str(db), "--json"]
    assert main(args + [str(tmp_path / "a.json")]) == 0
    assert main(args + [str(tmp_path / "b.json")]) == 0
    capsys.readouterr()
    a = json.loads((tmp_path / "a.json").read_text())
    b = json.loads((tmp_path / "b.json").read_text())
    assert a["switches"] == "trng" and a["conflicts"][0]["source"] == "nlp"
    assert b["conflicts"][0]["source"] == "database"
    assert b["conflicts"][0]["text"] == a["conflicts"][0]["text"]
    assert b["stats"]["nlp_solves"] < a["stats"]["nlp_solves"] and b["stats"]["N"] == 4


def test_bench_skips_a_broken_problem_and_says_so(capsys, tmp_path):
    import shutil

    for f in ("domain.pntc", "p1_one_block.pntc", "p1_one_block.yaml"):
        shutil.copy(PLANAR / f, tmp_path / f)
    (tmp_path / "z_broken.pntc").write_text("problem broken for planar_blocks\nobjects { b1 : blok }\n")
    code = main(["bench", str(tmp_path), "--algorithms", "oneway", "--seeds", "1", "--quiet"])
    captured = capsys.readouterr()
    assert code == 2
    assert "p1_one_block" in captured.out and "1/1" in captured.out
    assert "z_broken.pntc" in captured.out and "unknown type 'blok'" in captured.err
