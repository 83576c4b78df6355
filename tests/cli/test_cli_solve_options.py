"""Every option of `gnpp solve` exercised through the real entry point, its effect checked
against something outside the solver where one exists (the planar reference model of
tests/examples/planar_reference.py, built from the files; Pillow reading the rendered PNGs),
plus `--version` and the options' error paths (exit 2, one line naming the option)."""
from __future__ import annotations

import json
import math
import sys
from importlib.metadata import version
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "examples" / "planar"
LAB = ROOT / "examples" / "lab"
sys.path.insert(0, str(ROOT / "tests" / "examples"))
from planar_reference import read_problem, solution_violation, states_of_plan, Logic  # noqa: E402


def _solve_json(tmp_path, problem: Path, *opts: str, name: str = "r.json") -> dict:
    out = tmp_path / name
    assert main(["solve", str(problem), "--json", str(out), "--quiet", *opts]) == 0
    return json.loads(out.read_text())


def _values(result: dict) -> dict:
    """{(kind, object, step): value} from the JSON's steps (keys like `pose(b1)`)."""
    out = {}
    for st in result["steps"]:
        for key, val in st["values"].items():
            kind, obj = key[:-1].split("(")
            out[kind, obj, st["index"]] = np.asarray(val, float)
    return out


def _reference_check(problem: Path, result: dict, tol: float = 1e-6) -> float:
    v = solution_violation(read_problem(problem), result["plan"], _values(result))
    assert v <= tol, v
    return v


def test_version_is_the_installed_distributions(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["--version"])
    assert exc.value.code == 0
    assert capsys.readouterr().out.strip() == f"gnpp {version('gnppdsl')}"


def test_seed_is_recorded_and_reproducible(tmp_path):
    a = _solve_json(tmp_path, PLANAR / "p3_occupied.pntc", "--seed", "5", name="a.json")
    b = _solve_json(tmp_path, PLANAR / "p3_occupied.pntc", "--seed", "5", name="b.json")
    c = _solve_json(tmp_path, PLANAR / "p3_occupied.pntc", "--seed", "6", name="c.json")
    assert a["seed"] == b["seed"] == 5 and c["seed"] == 6
    assert a["plan"] == b["plan"] and a["steps"] == b["steps"]     # same seed: same numbers
    for r in (a, c):
        _reference_check(PLANAR / "p3_occupied.pntc", r)


@pytest.mark.parametrize("order", ["full_first", "relaxed_first", "staged"])
def test_every_order_finds_n_and_a_solution_the_reference_accepts(tmp_path, order):
    r = _solve_json(tmp_path, PLANAR / "p3_occupied.pntc", "--order", order)
    assert r["solved"] and len(r["plan"]) == 4          # N of p3 (expected.yaml, reference model)
    _reference_check(PLANAR / "p3_occupied.pntc", r)


def test_tolerance_bounds_the_reported_and_the_reference_violation(tmp_path):
    loose = _solve_json(tmp_path, PLANAR / "p5_handover.pntc", "--tolerance", "1e-3", name="l.json")
    tight = _solve_json(tmp_path, PLANAR / "p5_handover.pntc", "--tolerance", "1e-9", name="t.json")
    assert loose["stats"]["max_violation"] <= 1e-3 and tight["stats"]["max_violation"] <= 1e-9
    _reference_check(PLANAR / "p5_handover.pntc", loose, tol=1e-3)
    _reference_check(PLANAR / "p5_handover.pntc", tight, tol=1e-9)


def test_verbose_prints_each_plan_and_conflict_quiet_one_line(capsys):
    assert main(["solve", str(PLANAR / "p3_occupied.pntc"), "--verbose"]) == 0
    out = capsys.readouterr().out
    # p3: the 2-step plan fails (b2 occupies the target), a conflict is learnt, the 4-step holds
    assert "pick(b1, g, s1)" in out and "conflict" in out.lower()
    assert out.count("\n") > 10
    assert main(["solve", str(PLANAR / "p3_occupied.pntc"), "--quiet"]) == 0
    quiet = capsys.readouterr().out
    assert quiet.strip() == "p3_occupied: solved, N = 4"


def test_render_writes_one_png_per_keyframe_and_world_states_follow_the_reference(tmp_path, capsys):
    from PIL import Image

    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.solve.keyframes import world_states
    from gnppdsl import load_and_compile

    problem = PLANAR / "p3_occupied.pntc"
    out = tmp_path / "frames"
    r = _solve_json(tmp_path, problem, "--render", str(out))
    files = sorted(out.glob("*.png"))
    assert len(files) == len(r["plan"]) + 1
    images = [np.asarray(Image.open(f).convert("RGB"), float) for f in files]
    assert all(im.size and im.std() > 0 for im in images)           # not blank
    for a, b in zip(images, images[1:]):                             # something moves every step
        assert a.shape == b.shape and np.abs(a - b).max() > 0
    # world_states: a block's world pose is its parent's frame composed with its relative pose,
    # the parent read from the reference logic and the frame from the scene file
    c = load_and_compile(str(problem))
    states = plan_states(c.task, parse_plan(c.task, "; ".join(r["plan"])))
    values = {v: np.asarray(x) for v, x in zip(*_json_vars(c, states, r))}
    worlds = world_states(c, states, values)
    ref = read_problem(problem)
    ref_states = states_of_plan(ref, r["plan"])
    lg = Logic(ref)
    vals = _values(r)
    for i, (st, w) in enumerate(zip(ref_states, worlds)):
        for bi, b in enumerate(lg.blocks):
            parent = st[0][bi]
            frame = vals["q", parent, i] if parent in lg.grippers else np.asarray(ref.scene["objects"][parent]["pose"], float)
            want = _compose(frame, vals["pose", b, i])
            got = np.asarray(w[b], float).reshape(-1)[:3]
            assert np.allclose(got[:2], want[:2], atol=1e-9), (i, b, got, want)


def _compose(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    return np.array([a[0] + c * b[0] - s * b[1], a[1] + s * b[0] + c * b[1], a[2] + b[2]])


def _json_vars(c, states, r):
    variables = c.factory.variables(states)
    by = {(v.key, v.step): v for v in variables}
    keys, vals = [], []
    for st in r["steps"]:
        for key, val in st["values"].items():
            keys.append(by[key, st["index"]])
            vals.append(val)
    return keys, vals


@pytest.mark.slow          # two Lab solves: ~10 s CPU each
@pytest.mark.parametrize("flag", ["--distance-curvature", "--no-distance-curvature"])
def test_distance_curvature_both_ways_solve_lab1_and_verify(tmp_path, flag):
    from types import SimpleNamespace

    from gnppdsl import load_and_compile
    from gnppdsl.solve.verify_solution import verify_solution

    r = _solve_json(tmp_path, LAB / "lab1.pntc", flag)
    assert r["solved"] and r["stats"]["max_violation"] <= 1e-6
    # the JSON's keyframes and waypoints, verified with pinocchio + coal (the logic is checked by
    # the solve tests; here what the flag changes: the continuous solution)
    steps = [SimpleNamespace(state=s["state"], values=s["values"], trajectories=s["trajectories"])
             for s in r["steps"]]
    rep = verify_solution(load_and_compile(str(LAB / "lab1.pntc")).geometry,
                          SimpleNamespace(steps=steps, extras={}), check_logic=False)
    assert rep.ok and rep.keyframes == len(r["plan"]) + 1 and rep.waypoints > 0, str(rep)


@pytest.mark.slow          # a mobile solve: the session's `gnpp solve pick_place --algorithm rlgp` (tests/conftest.py)
def test_algorithm_rlgp_end_to_end(pick_place_rlgp):
    assert pick_place_rlgp.code == 0
    r = pick_place_rlgp.json
    assert r["solved"] and r["algorithm"] == "rlgp"
    assert r["stats"]["max_violation"] <= 1e-6


@pytest.mark.slow          # lab1's kernels through the C compiler (the session's lab1_kernels, tests/conftest.py)
def test_jit_flag_compiles_kernels_into_the_cache(lab1_kernels):
    """`--jit` in a fresh process with an empty cache: kernels compiled as C (the session's
    compile, which tests/solve/test_solve_jit_default.py starts from), and a second process
    finds them in the cache (native, none compiled again)."""
    from shared_solves import jit_env, solve_lab1_child

    first = lab1_kernels.first["stats"]
    second = solve_lab1_child(lab1_kernels.cache.parent / "jit_second.json", jit_env(lab1_kernels.cache),
                              "--jit", timeout=600)["stats"]
    assert first["kernels_compiled"] > 0 and first["kernels_failed"] == 0, first
    assert second["kernels_compiled"] == 0 and second["kernels_native"] >= first["kernels_compiled"], second
    assert any(lab1_kernels.cache.rglob("*.so"))


@pytest.mark.parametrize("argv,option", [
    (["--time-limit", "-1"], "--time-limit"),
    (["--time-limit", "0"], "--time-limit"),
    (["--max-horizon", "-1"], "--max-horizon"),
    (["--switches", "trx"], "--switches"),
    (["--tolerance", "-1"], "--tolerance"),
    (["--tolerance", "nan"], "--tolerance"),
    (["--time-limit", "nan"], "--time-limit"),
    (["--seed", "-1"], "--seed"),
])
def test_option_range_errors_exit_2_with_one_line_naming_the_option(capsys, argv, option):
    code = main(["solve", str(PLANAR / "p1_one_block.pntc"), *argv])
    err = capsys.readouterr().err
    lines = [ln for ln in err.strip().splitlines() if ln.strip()]
    assert code == 2 and len(lines) == 1 and option in lines[0] and "Traceback" not in err, (code, err)


@pytest.mark.parametrize("argv", [["--order", "sideways"], ["--algorithm", "astar"], ["--seed", "x"],
                                  ["--tolerance", "small"]])
def test_argparse_rejects_bad_choices_with_exit_2(capsys, argv):
    with pytest.raises(SystemExit) as exc:
        main(["solve", str(PLANAR / "p1_one_block.pntc"), *argv])
    assert exc.value.code == 2
    assert argv[0] in capsys.readouterr().err


@pytest.mark.parametrize("setting, argv, expected", [
    (None, [], (True, False, True)),                                # SolveOptions' defaults
    (None, ["--no-interleave-conflicts"], (False, False, True)),
    (None, ["--stretch-conflicts"], (True, True, True)),
    ("interleave_conflicts = true  stretch_conflicts = true", [], (True, True, True)),
    ("interleave_conflicts = false", ["--interleave-conflicts"], (True, False, True)),   # the command line wins
    ("interleave_conflicts = false", [], (False, False, True)),
    (None, ["--no-batch-lazy"], (True, False, False)),
    ("batch_lazy = false", [], (True, False, False)),
    ("batch_lazy = false", ["--batch-lazy"], (True, False, True)),
])
def test_conflict_generalisations_reach_the_loop_from_the_setting_and_the_command_line(
        tmp_path, monkeypatch, setting, argv, expected):
    """`--interleave-conflicts` / `--stretch-conflicts` / `--batch-lazy` and the solver settings of the same names
    arrive in the options the loop gets (the loop's use of them is tested in tests/conflicts)."""
    import gnppdsl

    seen = []

    def capture(compiled, options, progress=None):
        seen.append((options.interleave_conflicts, options.stretch_conflicts, options.batch_lazy))
        raise KeyboardInterrupt

    problem = PLANAR / "p1_one_block.pntc"
    if setting is not None:
        for f in PLANAR.glob("*"):
            (tmp_path / f.name).write_bytes(f.read_bytes())
        text = (tmp_path / "p1_one_block.pntc").read_text()
        problem = tmp_path / "p1_one_block.pntc"
        problem.write_text(text + f"\nsolver {{ {setting} }}\n")
    monkeypatch.setattr(gnppdsl, "solve_problem", capture)
    main(["solve", str(problem), "--quiet", *argv])
    assert seen == [expected]
