"""The subgraph database across edits and processes, through `gnpp solve --db`:
- a re-solve of the same files reuses the saved entries (hits > 0);
- editing a template (a copy of stdlib/planar.pntc next to the problem) or an object's shape
  changes `fingerprint()` / `object_keys()` and no saved entry answers for the edited problem;
- the hashes are the same in two processes with different hash seeds;
- two processes writing one database at the same time both finish, the file stays sound and
  serves both problems afterwards;
- eight processes opening one new file at the same instant all succeed."""
from __future__ import annotations

import json
import os
import shutil
import sqlite3
import subprocess
import sys
from pathlib import Path

import pytest

from gnppdsl.conflicts.database import SubgraphDatabase

ROOT = Path(__file__).resolve().parents[2]
PLANAR = ROOT / "examples" / "planar"


@pytest.fixture
def workdir(tmp_path):
    for name in ("domain.pntc", "p3_occupied.pntc", "p3_occupied.yaml", "p4_pair.pntc", "p4_pair.yaml"):
        shutil.copy(PLANAR / name, tmp_path / name)
    shutil.copy(ROOT / "stdlib" / "planar.pntc", tmp_path / "planar.pntc")    # found before the stdlib
    return tmp_path


def _env(**extra):
    env = dict(os.environ, PYTHONPATH=str(ROOT), **extra)
    return env


def _solve(workdir: Path, problem: str, out: str, wait: bool = True):
    argv = [sys.executable, "-m", "gnppdsl.cli.main", "solve", str(workdir / problem), "--db",
            str(workdir / "db.sqlite"), "--json", str(workdir / out), "--quiet"]
    p = subprocess.Popen(argv, env=_env(), stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    return _finish(p, workdir / out) if wait else (p, workdir / out)


def _finish(p, out: Path) -> dict:
    stdout, stderr = p.communicate(timeout=600)
    assert p.returncode == 0, stderr[-2000:]
    return json.loads(out.read_text())


def _hits(r: dict) -> int:
    return r["stats"]["db_feasible_hits"] + r["stats"]["db_infeasible_hits"]


def _identity(workdir: Path, problem: str, seed: str) -> dict:
    code = ("import json, sys; from gnppdsl import load_and_compile; "
            "c = load_and_compile(sys.argv[1]); "
            "print(json.dumps({'fp': c.fingerprint, 'keys': {o: c.object_key(o) for o in sorted(c.problem.objects)}}))")
    p = subprocess.run([sys.executable, "-c", code, str(workdir / problem)], env=_env(PYTHONHASHSEED=seed),
                       capture_output=True, text=True, timeout=300)
    assert p.returncode == 0, p.stderr[-2000:]
    return json.loads(p.stdout)


def test_hashes_are_stable_across_processes(workdir):
    a, b = _identity(workdir, "p3_occupied.pntc", "1"), _identity(workdir, "p3_occupied.pntc", "2")
    assert a == b and len(a["fp"]) >= 16 and a["keys"]["b1"] != "-"


def test_editing_a_template_invalidates_the_saved_entries(workdir):
    first = _solve(workdir, "p3_occupied.pntc", "a.json")
    again = _solve(workdir, "p3_occupied.pntc", "b.json")
    assert _hits(first) == 0 and _hits(again) > 0 and first["plan"] == again["plan"]
    before = _identity(workdir, "p3_occupied.pntc", "0")
    lib = workdir / "planar.pntc"
    text = lib.read_text()
    old = "sqnorm(pos(inv(world(g)) * world(o))) <= grasp_tol ^ 2"
    assert old in text
    lib.write_text(text.replace(old, "sqnorm(pos(inv(world(g)) * world(o))) <= (0.5 * grasp_tol) ^ 2"))
    after = _identity(workdir, "p3_occupied.pntc", "0")
    assert after["fp"] != before["fp"]
    edited = _solve(workdir, "p3_occupied.pntc", "c.json")
    assert _hits(edited) == 0, edited["stats"]
    assert edited["solved"] and len(edited["plan"]) == 4


def test_editing_a_shape_changes_its_object_key_and_no_entry_with_it_answers(workdir):
    """b2 made smaller (shape and the radius attribute the planar templates read): its object
    key changes, b1's does not; the saved conflict (b2 on s2 blocks the target) was learnt for
    the old b2 and must not answer, though the new b2 still blocks the target (N stays 4)."""
    _solve(workdir, "p3_occupied.pntc", "a.json")
    again = _solve(workdir, "p3_occupied.pntc", "a2.json")
    assert again["stats"]["db_infeasible_hits"] > 0            # the entry answers while unedited
    before = _identity(workdir, "p3_occupied.pntc", "0")
    scene = workdir / "p3_occupied.yaml"
    text = scene.read_text()
    old = "b2: {shape: {circle: 0.05}, pose: [0.5, 0.0, 0.0], radius: 0.05"
    assert old in text
    scene.write_text(text.replace(old, "b2: {shape: {circle: 0.03}, pose: [0.5, 0.0, 0.0], radius: 0.03"))
    after = _identity(workdir, "p3_occupied.pntc", "0")
    assert after["keys"]["b2"] != before["keys"]["b2"] and after["keys"]["b1"] == before["keys"]["b1"]
    edited = _solve(workdir, "p3_occupied.pntc", "b.json")
    assert edited["stats"]["db_infeasible_hits"] == 0, edited["stats"]
    assert edited["solved"] and len(edited["plan"]) == 4


def test_two_processes_write_one_database_at_once(workdir):
    (p3, o3), (p4, o4) = _solve(workdir, "p3_occupied.pntc", "a.json", wait=False), \
        _solve(workdir, "p4_pair.pntc", "b.json", wait=False)
    r3, r4 = _finish(p3, o3), _finish(p4, o4)
    assert r3["solved"] and r4["solved"]
    with sqlite3.connect(workdir / "db.sqlite") as conn:
        assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
        n = conn.execute("SELECT COUNT(*) FROM subgraphs").fetchone()[0]
    assert n > 0
    # both problems' records are there: each re-solve is answered from the database
    assert _hits(_solve(workdir, "p3_occupied.pntc", "c.json")) > 0
    assert _hits(_solve(workdir, "p4_pair.pntc", "d.json")) > 0


def _open_at_barrier(path: str, barrier, failures) -> None:
    barrier.wait()
    try:
        SubgraphDatabase(path=path, scope="race").close()
    except Exception as exc:            # noqa: BLE001 -- reported to the parent, which asserts
        failures.put(repr(exc))


def test_processes_opening_a_new_database_at_the_same_instant_all_succeed(tmp_path):
    """Eight processes released by one barrier open the same new file, ten times over. The
    header row was once written SELECT-then-INSERT in a deferred transaction: two openers both saw
    no row and the second INSERT failed with 'UNIQUE constraint failed: meta.key'."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    failures = ctx.Queue()
    for trial in range(10):
        path = str(tmp_path / f"db{trial}.sqlite")
        barrier = ctx.Barrier(8)
        procs = [ctx.Process(target=_open_at_barrier, args=(path, barrier, failures)) for _ in range(8)]
        for p in procs:
            p.start()
        for p in procs:
            p.join(60)
        assert all(p.exitcode == 0 for p in procs)
        with sqlite3.connect(path) as conn:
            assert conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchall() != []
    errors = []
    while not failures.empty():
        errors.append(failures.get())
    assert errors == []
