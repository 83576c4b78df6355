"""SIGINT / SIGTERM end `gnpp solve` with 130 / 143, a message and the partial result in
`--json`, wherever they land: in a solve (a real child process, the signal sent once its first
plan is printed) and while the command line is still being parsed (the signal delivered to this
process by `os.kill` from inside the parser's construction). Oracles: the exit status, the JSON
file on disk and the stderr text; no timing is asserted (benchmarks/bench_signals.py measures
the latency)."""
from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
from pathlib import Path

import pytest

import gnppdsl.cli.main as cli_main
from gnppdsl import interrupt

ROOT = Path(__file__).resolve().parents[2]
P7 = ROOT / "examples" / "planar" / "p7_relay.pntc"
P3 = ROOT / "examples" / "planar" / "p3_occupied.pntc"


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_during_a_solve(tmp_path, sig, code):
    out = tmp_path / "r.json"
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    proc = subprocess.Popen([sys.executable, "-m", "gnppdsl.cli.main", "solve", str(P7), "--json", str(out)],
                            stderr=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env, cwd=tmp_path)
    first = proc.stderr.readline()                 # "p7_relay: plans 1 ...": the search is under way
    assert "plans 1" in first, first
    proc.send_signal(sig)
    _, err = proc.communicate(timeout=120)
    assert proc.returncode != 0, "p7 ended before the signal arrived: the test needs a longer solve"
    assert proc.returncode == code, err
    assert f"interrupted by {sig.name}" in err and "Traceback" not in err
    assert json.loads(out.read_text())["status"] == "interrupted"


def _parser_hit_by(sig, monkeypatch):
    real = cli_main.build_parser

    def build(*args):
        os.kill(os.getpid(), sig)                  # as if it came during the parser's imports
        return real(*args)
    monkeypatch.setattr(cli_main, "build_parser", build)


@pytest.mark.parametrize("sig, code", [(signal.SIGINT, 130), (signal.SIGTERM, 143)])
def test_signal_while_the_command_line_is_parsed(tmp_path, monkeypatch, capsys, sig, code):
    """Before, a SIGTERM there killed the process (-15, no message, no JSON)."""
    out = tmp_path / "r.json"
    before = signal.getsignal(sig)
    _parser_hit_by(sig, monkeypatch)
    assert cli_main.main(["solve", str(P3), "--json", str(out)]) == code
    assert json.loads(out.read_text())["status"] == "interrupted"
    assert f"interrupted by {sig.name}" in capsys.readouterr().err
    assert cli_main.main(["check", str(P3)]) == code                     # any other command
    assert f"interrupted by {sig.name}" in capsys.readouterr().err
    monkeypatch.undo()
    assert cli_main.main(["check", str(P3)]) == 0                        # nothing left pending
    assert interrupt.pending() is None
    assert signal.getsignal(sig) is before                               # the handler given back


def test_a_kept_request_does_not_reach_the_next_command(tmp_path, monkeypatch):
    """`solve` refusing its options before its run: the request recorded while parsing is
    dropped, so the next solve in this process is not stopped by it."""
    _parser_hit_by(signal.SIGTERM, monkeypatch)
    assert cli_main.main(["solve", str(P3), "--time-limit", "nan"]) == 2
    monkeypatch.undo()
    out = tmp_path / "r.json"
    assert cli_main.main(["solve", str(P3), "--json", str(out), "--quiet"]) == 0
    assert json.loads(out.read_text())["status"] == "solved"
