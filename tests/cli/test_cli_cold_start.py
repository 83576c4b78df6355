"""What a fresh `gnpp solve` process spends before and around the solve (issue 20, "cold-process
overhead"): each cut keeps its behaviour and has a test here that fails without it.

- the parser imports only the sub-command it runs (`gnppdsl.cli.main.build_parser(command)`);
- `gnpp solve` as a program leaves without the interpreter's teardown (`_leave_now`);
- the generated methods of dataclasses come from a code cache (`gnppdsl.classcode`) and are
  the same functions as compiled ones.

Timings are in benchmarks/bench_coldstart.py, never asserted here."""
from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from gnppdsl.cli import main as cli_main

ROOT = Path(__file__).resolve().parents[2]
P3 = ROOT / "examples" / "planar" / "p3_occupied.pntc"


def _python(code: str, env: dict | None = None, *args: str) -> subprocess.CompletedProcess:
    e = dict(os.environ, PYTHONPATH=str(ROOT))
    e.update(env or {})
    return subprocess.run([sys.executable, "-c", code, *args], cwd=ROOT, env=e,
                          capture_output=True, text=True, timeout=300)


# ---- the parser ---------------------------------------------------------------------------
def test_a_solve_imports_no_other_sub_command(tmp_path):
    """Before: `build_parser` imported every sub-command's module (bench, view, export,
    compile, check) for any command."""
    code = ("import sys, json\nfrom gnppdsl.cli.main import main\n"
            "code = main(sys.argv[1:])\n"
            "print(json.dumps(sorted(sys.modules)))\n"
            "sys.exit(code)\n")
    p = _python(code, None, "solve", str(P3), "--quiet", "--json", str(tmp_path / "r.json"))
    assert p.returncode == 0, p.stderr
    mods = set(json.loads(p.stdout.strip().splitlines()[-1]))
    assert "gnppdsl.cli.solve_cmd" in mods
    others = {m for _, (m, _) in cli_main.SUBCOMMANDS.items()} - {"gnppdsl.cli.solve_cmd"}
    assert mods & (others | {"gnppdsl.cli.sweep", "gnppdsl.cli.table1"}) == set()
    assert not any(m.startswith("gnppdsl.view") for m in mods)
    # what only some runs need: a database file (--db), a misspelt name's suggestions
    assert mods & {"sqlite3", "difflib"} == set()


def test_the_package_and_the_parser_do_not_import_dataclasses():
    """`gnpp --help`: the code cache waits for `dataclasses` to be imported by what needs it."""
    code = ("import sys\nimport gnppdsl.cli.main as m\nm.build_parser('')\n"
            "assert 'dataclasses' not in sys.modules, 'imported'\n"
            "from gnppdsl import classcode\nclasscode.install()\n"
            "assert 'dataclasses' not in sys.modules, 'imported by install'\n"
            "import dataclasses\n"
            "assert dataclasses.exec is classcode.cached_exec\n"
            "assert classcode._WhenImported not in sys.meta_path\n")
    p = _python(code)
    assert p.returncode == 0, p.stderr


def test_only_the_gnpp_program_installs_the_code_cache():
    """A library user's process (`import gnppdsl`, the API, `main([...])` from their code) keeps
    plain `dataclasses`: the patch would reach their own classes; `gnpp` itself (`main()`)
    installs it."""
    lib = ("import sys, dataclasses, gnppdsl, gnppdsl.cli.main as m\n"
           "from gnppdsl import load_and_compile\n"
           f"m.main(['check', {str(P3)!r}])\n"
           "assert 'exec' not in vars(dataclasses), 'patched'\n")
    p = _python(lib)
    assert p.returncode == 0, p.stderr + p.stdout
    prog = ("import sys, dataclasses, gnppdsl.cli.main as m\n"
            f"sys.argv = ['gnpp', 'check', {str(P3)!r}]\n"
            "code = m.main()\n"
            "from gnppdsl import classcode\n"
            "assert vars(dataclasses).get('exec') is classcode.cached_exec, 'not installed'\n"
            "sys.exit(code)\n")
    p = _python(prog)
    assert p.returncode == 0, p.stderr + p.stdout


def test_the_command_is_the_first_word_that_is_not_an_option():
    assert cli_main.command_of(["solve", "x.pntc", "--quiet"]) == "solve"
    assert cli_main.command_of(["--help"]) == ""
    assert cli_main.command_of(["slove", "x"]) == ""
    assert cli_main.command_of([]) == ""


def test_help_lists_every_command_without_importing_them(capsys):
    with pytest.raises(SystemExit):
        cli_main.build_parser("").parse_args(["--help"])
    out = capsys.readouterr().out
    assert all(name in out for name in cli_main.SUBCOMMANDS)
    parser = cli_main.build_parser("check")       # the one named has its arguments
    args = parser.parse_args(["check", str(P3)])
    assert args.command == "check" and args._run is not None


# ---- the quick exit -----------------------------------------------------------------------
def test_the_program_leaves_without_teardown_after_a_solve(monkeypatch):
    """`gnpp solve` (main without argv) ends in `os._exit` after flushing; called with argv
    (from Python) it returns; other commands end normally."""
    exits = []

    def fake_main(argv):
        cli_main._command = command
        return 0
    monkeypatch.setattr(cli_main, "_main", fake_main)
    monkeypatch.setattr(cli_main.os, "_exit", lambda code: exits.append(code))
    for command, expect in (("solve", [0]), ("check", []), ("bench", [])):
        exits.clear()
        assert cli_main.main() == 0
        assert exits == expect, command
    command = "solve"
    exits.clear()
    assert cli_main.main(["solve", "x"]) == 0 and exits == []
    monkeypatch.setattr(cli_main.sys, "getprofile", lambda: object())   # under a profiler:
    assert cli_main.main() == 0 and exits == []                          # it writes at exit


def test_a_solve_process_writes_everything_before_it_leaves(tmp_path):
    """The real program: exit status, stdout and the JSON all there, no exit handler runs."""
    out = tmp_path / "r.json"
    code = ("import atexit, sys\nfrom gnppdsl.cli.main import main\n"
            "atexit.register(lambda: print('TEARDOWN', flush=True))\n"
            "sys.argv = ['gnpp', *sys.argv[1:]]\nsys.exit(main())\n")
    buffered = {"PYTHONUNBUFFERED": ""}                 # stdout a buffered pipe: flushed?
    p = _python(code, buffered, "solve", str(P3), "--quiet", "--json", str(out))
    assert p.returncode == 0, p.stderr
    assert "solved" in p.stdout and "TEARDOWN" not in p.stdout
    assert json.loads(out.read_text())["status"] == "solved"
    p = _python(code, None, "check", str(P3))           # not a solve: the normal teardown
    assert p.returncode == 0 and "TEARDOWN" in p.stdout


# ---- the dataclass code cache -------------------------------------------------------------
CLASSES = '''
import dataclasses, json, sys
from dataclasses import dataclass, field
from typing import Any
if len(sys.argv) > 1:                  # the reference: dataclasses alone, no gnppdsl
    classcode = None
else:
    from gnppdsl import classcode
    classcode.install()                # as the `gnpp` program does

@dataclass(frozen=True)
class A:
    x: int
    y: "str" = "a"
    z: Any = field(default=None, compare=False, repr=False)

@dataclass(order=True)
class B:
    n: float
    items: list = field(default_factory=list)

@dataclass(frozen=True, eq=False, slots=True, kw_only=True)
class C:
    a: int = 1

@dataclass(unsafe_hash=True)
class D:
    n: float
    m: tuple = ()

@dataclass
class E(B):
    k: int = 0

def code(c):
    return [c.co_name, c.co_code.hex(), [code(k) if hasattr(k, "co_code") else repr(k)
                                         for k in c.co_consts],
            c.co_names, c.co_varnames, c.co_freevars, c.co_firstlineno, c.co_filename]

def shape(f):
    return [f.__qualname__, code(f.__code__), repr(f.__defaults__), repr(f.__kwdefaults__),
            repr(f.__annotations__)]

out = {}
for cls in (A, B, C, D, E):
    for name, f in sorted(vars(cls).items()):
        f = getattr(f, "__wrapped__", f)
        if hasattr(f, "__code__"):
            out[cls.__name__ + "." + name] = shape(f)
out["values"] = [repr(A(1)), A(1) == A(1, z=2), hash(A(1)) == hash(A(1, z=3)), repr(B(2.0)),
                 B(1.0) < B(2.0), repr(C()), repr(D(1.0, (2,))), hash(D(1.0, (2,)))
                 == hash(D(1.0, (2,))), repr(E(1.0, [2], 3)), A.__doc__, B.__doc__]
try:
    A(1).x = 2
except dataclasses.FrozenInstanceError:
    out["frozen"] = True
out["stats"] = classcode.stats if classcode else None
out["installed"] = classcode is not None and vars(dataclasses).get("exec") is classcode.cached_exec
print(json.dumps(out))
'''


def _classes(cache: str | None) -> dict:
    """The classes' methods and values: with gnppdsl's cache in directory `cache` ("off": none
    but still through `cached_exec`), or None: plain `dataclasses`, gnppdsl not imported."""
    if cache is None:
        p = _python(CLASSES, None, "reference")
    else:
        p = _python(CLASSES, {"GNPP_CODE_CACHE": cache})
    assert p.returncode == 0, p.stderr
    return json.loads(p.stdout)


def test_cached_dataclass_methods_equal_compiled_ones(tmp_path):
    """Off (compiled as by `dataclasses`), a cold cache, a warm one: the same methods (code,
    constants, names, annotations, defaults) and the same behaviour."""
    plain = _classes(None)
    off = _classes("off")
    cold = _classes(str(tmp_path / "cc"))
    warm = _classes(str(tmp_path / "cc"))
    assert not plain["installed"] and off["installed"] and cold["installed"] and warm["installed"]
    assert off["stats"]["misses"] > 0 and cold["stats"]["misses"] > 0
    assert warm["stats"]["misses"] == 0 and warm["stats"]["hits"] > 20
    from gnppdsl import classcode                        # the warm run folded the appended
    (f,) = list((tmp_path / "cc").iterdir())             # records into one snapshot
    (snapshot,) = list(classcode._records(f.read_bytes()))
    assert type(snapshot) is dict and len(snapshot) > 20
    for r in (plain, off, cold, warm):
        r.pop("stats"), r.pop("installed")
    assert plain == off == cold == warm
    assert plain["frozen"] is True


def test_a_broken_table_file_counts_up_to_its_last_complete_record(tmp_path):
    d = tmp_path / "cc"
    _classes(str(d))
    (f,) = list(d.iterdir())
    full = f.read_bytes()
    f.write_bytes(full + b"\xff\x00garbage")              # a torn or corrupt tail
    r = _classes(str(d))
    assert r["stats"]["misses"] == 0
    f.write_bytes(full[: len(full) // 2])                # cut in the middle of a record
    r = _classes(str(d))
    assert 0 < r["stats"]["misses"] and r["stats"]["hits"] > 0
    assert r["values"] == _classes(None)["values"]


def test_a_directory_others_can_write_to_is_not_used(tmp_path):
    real = tmp_path / "real"
    real.mkdir(mode=0o777)
    if os.getuid() == 0:
        os.chown(real, 12345, 12345)                      # another user's
        d = real
    else:
        d = tmp_path / "cc"
        d.symlink_to(real)                                # not a directory of its own
    r = _classes(str(d))
    assert r["stats"]["hits"] == 0
    assert list(real.iterdir()) == []


# ---- the parse cache holds the layout warnings --------------------------------------------
def test_a_cached_parse_reports_its_layout_warnings_without_the_walk(tmp_path, monkeypatch):
    """Before, every parse (cached ones too) walked the tree for layout warnings
    (`lint.layout_warnings`); now the cache entry holds them."""
    from gnppdsl.lang import lint
    from gnppdsl.lang import parser as parser_mod
    from gnppdsl.lang.diagnostics import Reporter

    monkeypatch.setattr(parser_mod, "_cache_dir", lambda: tmp_path)
    text = ("domain d\ncontinuous p : R[2] tags object\ntemplate t(lo: R, hi: R) tags object {\n"
            "  p[0] >= lo\n  -p[1] >= -hi\n}\n")          # tests/lang/test_lang_lint.py's case

    def parse():
        r = Reporter()
        tree = parser_mod.parse_text(text, "t.pntc", r)
        return tree, [(str(d.span), d.message, d.hint) for d in r.diagnostics]
    tree, first = parse()                        # a miss: parsed, linted, stored
    assert tree is not None and len(first) == 1 and "'-'" in first[0][1]
    assert len(list(tmp_path.iterdir())) == 1
    monkeypatch.setattr(lint, "layout_warnings", lambda *a: pytest.fail("walked again"))
    again, second = parse()                      # a hit: the stored warnings
    assert again == tree and second == first
