"""Table I beside the measurements: the transcription, the name matching, the statistics."""
from __future__ import annotations

import statistics

import pytest

from gnppdsl.cli.algorithms import parse_algorithms
from gnppdsl.cli.table1 import PAPER_CPU, PAPER_LENGTHS, markdown, paper_name, plot


def test_transcription_spot_checks_against_the_paper_text():
    # cells read by hand from the paper's Table I (mean then deviation run together)
    assert PAPER_CPU["Lab_4"]["gnpp_trn"] == (6.5, 0.6)          # "6.50.6"
    assert PAPER_CPU["Work_2"]["gnpp_tr"] == (22.7, 9.2)         # "22.79.2"
    assert PAPER_CPU["Field_5"]["gnpp_trng"] == (51.4, 6.6)      # "51.46.6"
    assert PAPER_CPU["Lab_5"]["oneway"] is None                  # "-"
    assert len(PAPER_CPU) == len(PAPER_LENGTHS) == 15
    # the figures for GNPP_trng (Work, Field, Lab) must be what the table holds
    trng = {"Work": (5.3, 16.7, 21.4, 55.4, 76.8), "Field": (3.1, 6.3, 11.7, 13.5, 51.4),
            "Lab": (3.3, 2.1, 3.2, 6.3, 19.0)}
    for scenario, times in trng.items():
        assert tuple(PAPER_CPU[f"{scenario}_{i + 1}"]["gnpp_trng"][0] for i in range(5)) == times


@pytest.mark.parametrize("name,expected", [("lab4", "Lab_4"), ("Lab_4", "Lab_4"), ("field_5", "Field_5"),
                                           ("work1", "Work_1"), ("lab4_paper", "Lab_4"), ("lab6", None), ("p3_occupied", None)])
def test_paper_names(name, expected):
    assert paper_name(name) == expected


def test_markdown_statistics_over_solved_runs_only(tmp_path):
    specs = parse_algorithms("gnpp_trn")
    cpu = [1.0, 2.0, 4.0]
    rows = [{"problem": "lab4", "algorithm": "gnpp_trn", "seed": i, "solved": True, "cpu_time": c,
             "N0": 4, "N": 9} for i, c in enumerate(cpu)]
    rows.append({"problem": "lab4", "algorithm": "gnpp_trn", "seed": 3, "solved": False, "cpu_time": 99.0,
                 "N0": 4, "N": None})
    text = markdown(["lab4"], specs, rows)
    line = next(ln for ln in text.splitlines() if ln.startswith("| lab4"))
    m, s = statistics.mean(cpu), statistics.stdev(cpu)
    assert f"{m:.1f} ± {s:.1f}" in line and "3/4" in line and "6.5 ± 0.6" in line and "4 / 9" in line


def test_plot_writes_a_png(tmp_path):
    pytest.importorskip("matplotlib", reason="matplotlib (optional external package) is not installed")
    specs = parse_algorithms("gnpp_trn")
    rows = [{"problem": "lab1", "algorithm": "gnpp_trn", "seed": 0, "solved": True, "cpu_time": 1.0}]
    plot(["lab1"], specs, rows, str(tmp_path / "t.png"))
    assert (tmp_path / "t.png").read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
