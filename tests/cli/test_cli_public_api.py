"""The public API at the package top (issue 18): `gnppdsl.solve_problem`, `load_and_compile`,
`SolveOptions` and `Result` exist with their documented signatures (the package docstring),
`import gnppdsl` loads none of the solver's libraries, and the command line (`gnpp solve`,
`gnpp bench`) solves through exactly these names: spies put on the package's attributes see
every call, and what the spy of `solve_problem` returns is what `gnpp solve` prints."""
from __future__ import annotations

import dataclasses
import inspect
import os
import subprocess
import sys
from pathlib import Path

import gnppdsl
from gnppdsl.cli.main import main

ROOT = Path(__file__).resolve().parents[2]
P1 = ROOT / "examples" / "planar" / "p1_one_block.pntc"


def test_the_public_names_have_their_documented_signatures():
    assert {"solve_problem", "load_and_compile", "SolveOptions", "Result"} <= set(gnppdsl.__all__)
    sig = inspect.signature(gnppdsl.solve_problem)
    assert list(sig.parameters) == ["problem", "options", "progress", "overrides"]
    assert sig.parameters["options"].default is None and sig.parameters["progress"].default is None
    assert sig.parameters["overrides"].kind is inspect.Parameter.VAR_KEYWORD
    assert list(inspect.signature(gnppdsl.load_and_compile).parameters) == ["paths", "instance"]
    assert inspect.signature(gnppdsl.load_and_compile).parameters["instance"].default is None
    defaults = {f.name: f.default for f in dataclasses.fields(gnppdsl.SolveOptions)}
    assert {k: defaults[k] for k in ("algorithm", "switches", "time_limit", "seed")} == \
        {"algorithm": "gnpp", "switches": "trn", "time_limit": 60.0, "seed": 0}
    assert list(inspect.signature(gnppdsl.SolveOptions.from_settings).parameters) == ["settings", "overrides"]
    fields = {f.name for f in dataclasses.fields(gnppdsl.Result)}
    assert {"status", "plan", "steps", "conflicts", "stats"} <= fields
    assert callable(gnppdsl.Result.summary) and callable(gnppdsl.Result.write_json)
    # the implementation's objects, not copies
    from gnppdsl.solve import compiled, loop, options, result
    assert (gnppdsl.solve_problem, gnppdsl.load_and_compile, gnppdsl.SolveOptions, gnppdsl.Result) == \
        (loop.solve_problem, compiled.load_and_compile, options.SolveOptions, result.Result)


def test_importing_the_package_loads_no_solver_library():
    code = ("import sys, gnppdsl; assert gnppdsl.__version__; "
            "print(sorted(m for m in ('casadi', 'clingo', 'pinocchio', 'numpy', 'gnppdsl.solve.loop') "
            "if m in sys.modules))")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env, check=True)
    assert out.stdout.strip() == "[]"



def test_the_command_line_loads_no_solver_library_before_a_command_needs_it():
    """`import gnppdsl.cli.main`, its parser and `gnpp --help` / `gnpp solve --help` import none
    of the heavy libraries (issue 20: a cold `gnpp solve` pays for what it uses, nothing
    before). A module-level `import casadi` (or pinocchio, coal, networkx, ...) anywhere on the
    command line's import path fails this."""
    heavy = ("casadi", "pinocchio", "coal", "clingo", "networkx", "numpy", "yaml", "lark",
             "sqlite3", "trimesh", "scipy", "gnppdsl.solve.loop", "gnppdsl.nlp.feasibility")
    code = ("import sys\nimport gnppdsl.cli.main as m\n"
            "for argv in (['--help'], ['solve', '--help'], ['bench', '--help'], ['view', '--help']):\n"
            "    try:\n        m.main(argv)\n    except SystemExit:\n        pass\n"
            f"print(sorted(x for x in {heavy!r} if x in sys.modules), file=sys.stderr)\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True, cwd=ROOT)
    assert "usage: gnpp solve" in out.stdout          # the help ran
    assert out.stderr.strip().splitlines()[-1] == "[]", out.stderr


def test_a_solve_without_conflicts_does_not_import_networkx():
    """A graph-NLP is `gnppdsl.nlp.graph.Graph`, not a networkx graph: a solve that learns no
    conflict (planar p1) never imports networkx (~0.1 s CPU of every cold `gnpp solve`, issue
    20); the conflict matching imports it when it runs."""
    code = ("import sys\nimport gnppdsl.cli.main as m\n"
            f"rc = m.main(['solve', {str(P1)!r}, '--quiet'])\n"
            "print(rc, 'networkx' in sys.modules, 'casadi' in sys.modules, file=sys.stderr)\n")
    env = {**os.environ, "PYTHONPATH": str(ROOT)}
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, env=env,
                         check=True, cwd=ROOT)
    assert "solved" in out.stdout
    assert out.stderr.strip().splitlines()[-1] == "0 False True", out.stderr

def _spies(monkeypatch) -> list:
    """Spies on the four public names (calling through); the list records (name, args)."""
    calls: list = []
    real_solve, real_load, real_options = gnppdsl.solve_problem, gnppdsl.load_and_compile, gnppdsl.SolveOptions

    def solve_problem(problem, options=None, progress=None, **overrides):
        calls.append(("solve_problem", problem, options))
        r = real_solve(problem, options, progress, **overrides)
        assert isinstance(r, gnppdsl.Result)
        return dataclasses.replace(r, message=r.message + " [through gnppdsl.solve_problem]")

    def load_and_compile(paths, instance=None):
        calls.append(("load_and_compile", paths, instance))
        return real_load(paths, instance=instance)

    class SolveOptions(real_options):
        @staticmethod
        def from_settings(settings=None, **overrides):
            calls.append(("SolveOptions.from_settings", settings, overrides))
            return real_options.from_settings(settings, **overrides)

    for name, spy in (("solve_problem", solve_problem), ("load_and_compile", load_and_compile),
                      ("SolveOptions", SolveOptions)):
        monkeypatch.setattr(gnppdsl, name, spy, raising=False)
    return calls


def test_gnpp_solve_goes_through_the_public_api(monkeypatch, capsys):
    calls = _spies(monkeypatch)
    assert main(["solve", str(P1), "--seed", "3"]) == 0
    out = capsys.readouterr().out
    assert "[through gnppdsl.solve_problem]" in out            # what the public function returned
    assert [c[0] for c in calls] == ["load_and_compile", "SolveOptions.from_settings", "solve_problem"]
    from gnppdsl.solve.options import SolveOptions

    options = calls[-1][2]
    assert isinstance(options, SolveOptions) and options.seed == 3


def test_gnpp_bench_goes_through_the_public_api(monkeypatch, capsys):
    calls = _spies(monkeypatch)
    assert main(["bench", str(P1), "--algorithms", "oneway,gnpp_trn", "--seeds", "2", "--quiet"]) == 0
    names = [c[0] for c in calls]
    assert names.count("load_and_compile") == 1                # compiled once, solved four times
    assert names.count("solve_problem") == 4
    assert sorted((c[2].algorithm, c[2].seed) for c in calls if c[0] == "solve_problem") == \
        [("gnpp", 0), ("gnpp", 1), ("oneway", 0), ("oneway", 1)]


def test_the_readme_example_runs(monkeypatch, capsys):
    """README's Python example, run as written (from the checkout's root)."""
    import re

    text = (ROOT / "README.md").read_text()
    code = re.search(r"```python\n(.*?)```", text, re.S).group(1)
    assert "gnppdsl.solve_problem" in code
    monkeypatch.chdir(ROOT)
    exec(compile(code, "README.md", "exec"), {})
    out = capsys.readouterr().out.splitlines()
    assert len(out) == 3 and all(line.startswith("solved ") for line in out)
