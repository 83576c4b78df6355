"""Fuzzing the front end and the options, bounded to a few seconds (issue 21).

Property: `gnpp check` / `gnpp solve`'s option checks either succeed or end in a located
diagnostic (file:line:col, or the option's name) with exit 2; never an exception, never a
hang (each case runs under a 20 s alarm). The mutants are those of tools/fuzz_inputs.py (the
standalone 10,000-case run), drawn here by hypothesis from the bundled examples.
GNPP_FUZZ_EXAMPLES=500 for a longer run.
"""
from __future__ import annotations

import importlib.util
import math
import os
import random
import shutil
import signal
from contextlib import contextmanager
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import gnppdsl.lang.parser as parser_mod
from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("fuzz_inputs", ROOT / "tools" / "fuzz_inputs.py")
fuzz = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(fuzz)

N = int(os.environ.get("GNPP_FUZZ_EXAMPLES", "12"))
SETTINGS = settings(max_examples=N, deadline=None, suppress_health_check=list(HealthCheck))
CASE_SECONDS = 20


class Hang(Exception):
    pass


@contextmanager
def time_box(seconds: int):
    def on_alarm(signum, frame):
        raise Hang(f"no answer within {seconds} s")

    old = signal.signal(signal.SIGALRM, on_alarm)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


@pytest.fixture(autouse=True)
def _no_ast_cache(monkeypatch):
    monkeypatch.setattr(parser_mod, "_cache_dir", lambda: None)


def _located(stderr: str, paths: list[str]) -> None:
    """Every `error:` line starts with one of the checked files' `path:line:col:`."""
    for line in stderr.splitlines():
        if ": error: " in line:
            head = line.split(": error: ")[0]
            assert any(head.startswith(p + ":") for p in paths), line
            assert head.rsplit(":", 2)[-1].isdigit() and head.rsplit(":", 2)[-2].isdigit(), line


def _check_mutant(tmp_path: Path, capsys, folder: str, target: str, data: bytes, problem: str) -> None:
    d = tmp_path / "ex"
    if d.exists():
        shutil.rmtree(d)
    shutil.copytree(ROOT / "examples" / folder, d)
    (d / target).write_bytes(data)
    files = [str(d / "domain.pntc"), str(d / problem)]
    capsys.readouterr()
    with time_box(CASE_SECONDS):
        code = main(["check", *files])
    err = capsys.readouterr().err
    assert code in (0, 2)
    assert "Traceback" not in err
    if code == 2:
        _located(err, [str(d / f.name) for f in d.iterdir()] + [str(ROOT / "stdlib" / m.name)
                                                                for m in (ROOT / "stdlib").glob("*.pntc")])


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), folder=st.sampled_from(sorted(fuzz.FOLDERS)),
       which=st.sampled_from(["domain", "problem"]))
def test_mutated_pntc(tmp_path, capsys, seed, folder, which):
    dom, prob, _ = fuzz.FOLDERS[folder]
    target = dom if which == "domain" else prob
    text = (ROOT / "examples" / folder / target).read_text()
    _check_mutant(tmp_path, capsys, folder, target, fuzz.mutate(text, random.Random(seed), False), prob)


@SETTINGS
@given(seed=st.integers(0, 2**32 - 1), folder=st.sampled_from(sorted(fuzz.FOLDERS)))
def test_mutated_scene(tmp_path, capsys, seed, folder):
    _, prob, scene = fuzz.FOLDERS[folder]
    text = (ROOT / "examples" / folder / scene).read_text()
    _check_mutant(tmp_path, capsys, folder, scene, fuzz.mutate(text, random.Random(seed), True), prob)


NUMBERS = st.one_of(st.floats(allow_nan=True, allow_infinity=True),
                    st.sampled_from([0.0, -1.0, 1e-30, 1e3, 1e-6, 60.0, 2.0**40]))


@settings(max_examples=4 * N, deadline=None, suppress_health_check=list(HealthCheck))
@given(option=st.sampled_from(["--tolerance", "--time-limit", "--seed", "--max-horizon"]), value=NUMBERS)
def test_solve_options(tmp_path, capsys, option, value):
    """Out-of-range option values exit 2 naming the option before any solve; in-range ones
    are accepted (checked with a missing problem file, so nothing is solved)."""
    text = repr(int(value)) if option in ("--seed", "--max-horizon") and math.isfinite(value) else repr(value)
    capsys.readouterr()
    try:
        with time_box(CASE_SECONDS):
            code = main(["solve", str(tmp_path / "missing.pntc"), option, text])
    except SystemExit as exc:                  # argparse: not a number of the option's type
        code = exc.code
    err = capsys.readouterr().err
    assert code == 2 and "Traceback" not in err
    from gnppdsl.ir.model import SETTING_RANGES

    lo, hi = SETTING_RANGES[option[2:].replace("-", "_")]
    v = float(text)
    if math.isfinite(v) and lo <= v <= hi:
        assert "missing.pntc" in err, err     # accepted: the next complaint is the file
    else:
        assert option in err, err
