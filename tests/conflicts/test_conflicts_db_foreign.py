"""`--db` opens only gnpp subgraph databases, refuses others before writing anything, and
survives kill -9 at any instant.

Oracles: the bytes (sha1) and directory listing of a foreign file before and after the refused
open; SQLite's own `PRAGMA integrity_check`; the number of records the killed writer reported
committed (printed after each commit) against the number the reopened database loads.
"""
from __future__ import annotations

import hashlib
import os
import random
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from gnppdsl.conflicts.database import APPLICATION_ID, SCHEMA_VERSION, SubgraphDatabase
from gnppdsl.errors import UserError

sys.path.insert(0, str(Path(__file__).parent))
from conflicts_fixture_factors import same  # noqa: E402


def _snapshot(path: Path):
    return hashlib.sha1(path.read_bytes()).hexdigest(), sorted(p.name for p in path.parent.iterdir())


def _foreign(path: Path, sql: str) -> None:
    conn = sqlite3.connect(path)
    with conn:
        conn.executescript(sql)
    conn.close()


@pytest.mark.parametrize("sql", [
    "CREATE TABLE notes (id INTEGER PRIMARY KEY, text TEXT); INSERT INTO notes (text) VALUES ('mine');",
    "CREATE TABLE meta (a INTEGER, b BLOB); INSERT INTO meta VALUES (1, x'00');",   # a `meta` of another shape
    "PRAGMA application_id = 1234; CREATE TABLE t (x);",
])
def test_foreign_sqlite_file_is_refused_untouched(tmp_path, sql):
    path = tmp_path / "other.sqlite"
    _foreign(path, sql)
    before = _snapshot(path)
    with pytest.raises(UserError, match="not a gnpp subgraph database"):
        SubgraphDatabase(path, scope="s", fingerprint="f")
    assert _snapshot(path) == before                 # no table, no WAL switch, no -wal/-shm file


def test_non_database_files_are_refused(tmp_path):
    text = tmp_path / "notes.txt"
    text.write_text("my notes\n" * 20)
    before = _snapshot(text)
    with pytest.raises(UserError, match="not a usable subgraph database"):
        SubgraphDatabase(text)
    assert _snapshot(text) == before
    link = tmp_path / "link.sqlite"
    link.symlink_to(tmp_path / "elsewhere.sqlite")
    with pytest.raises(UserError, match="symbolic links"):
        SubgraphDatabase(link)
    assert not (tmp_path / "elsewhere.sqlite").exists()


def test_new_database_is_stamped_and_reopened(tmp_path):
    path = tmp_path / "db.sqlite"
    with SubgraphDatabase(path, scope="s", fingerprint="f") as db:
        db.add([same("o1", 0, 0)], feasible=True)
    header = path.read_bytes()[:100]                 # the file format's header, read directly
    assert int.from_bytes(header[68:72], "big") == APPLICATION_ID
    assert int.from_bytes(header[60:64], "big") == SCHEMA_VERSION
    with SubgraphDatabase(path, scope="s", fingerprint="f") as db:
        assert db.stats.loaded == 1
    empty = tmp_path / "empty.sqlite"
    empty.write_bytes(b"")                            # `mktemp` leaves an empty file: a new database
    SubgraphDatabase(empty).close()


# One process imports gnppdsl once and forks a writer per trial (a process start with the imports
# is ~0.3 s of CPU: a third of the 100-trial test's time went into starting writers). Each writer
# is still a process of its own with its own SQLite connection, killed with SIGKILL by the test;
# the forking process relays what the writer printed (each line written with one os.write,
# after the commit it reports) until the writer's end of the pipe closes, then prints "end".
_ZYGOTE = textwrap.dedent(
    """
    import os, sys, traceback
    sys.path.insert(0, {tests!r})
    from conflicts_fixture_factors import same
    from gnppdsl.conflicts.database import SubgraphDatabase

    def write(fd, trial):
        db = SubgraphDatabase({path!r}, scope="planar", fingerprint="f")
        os.write(fd, b"open %d\\n" % db.stats.loaded)
        for n in range(10**6):
            db.add([same("t%d_%d" % (trial, n), 0, 0)], feasible=True)
            os.write(fd, b"committed\\n")

    for line in sys.stdin:
        trial = int(line)
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:                     # the writer
            os.close(r)
            try:
                write(w, trial)
            except BaseException:
                traceback.print_exc()
            os._exit(1)
        os.close(w)
        print("pid", pid, flush=True)
        with os.fdopen(r, "rb") as out:
            for text in out:
                sys.stdout.write(text.decode())
                sys.stdout.flush()
        os.waitpid(pid, 0)
        print("end", flush=True)
    """
)


def _kill_trials(tmp_path: Path, trials: int, seed: int = 0) -> None:
    """`trials` writers on one file, each killed with SIGKILL at a random instant of its
    writing; after each, SQLite's integrity check and every committed record must hold."""
    rng = random.Random(seed)
    path = tmp_path / "db.sqlite"
    committed = 0
    script = _ZYGOTE.format(tests=str(Path(__file__).parent), path=str(path))
    zygote = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE,
                              text=True)
    try:
        for trial in range(trials):
            zygote.stdin.write(f"{trial}\n")
            zygote.stdin.flush()
            pid = int(zygote.stdout.readline().split()[1])
            first = zygote.stdout.readline().split()
            assert first[:1] == ["open"], first
            assert int(first[1]) >= committed       # nothing committed earlier was lost
            time.sleep(rng.uniform(0.0, 0.3))
            os.kill(pid, signal.SIGKILL)
            lines = []
            for line in zygote.stdout:
                if line == "end\n":
                    break
                lines.append(line)
            else:
                raise AssertionError("the forking process ended")
            assert set(lines) <= {"committed\n"}, lines[:3]
            committed = int(first[1]) + len(lines)
            conn = sqlite3.connect(path)
            assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
            conn.close()
    finally:
        zygote.stdin.close()
        try:
            zygote.wait(timeout=30)
        except subprocess.TimeoutExpired:
            zygote.kill()
    with SubgraphDatabase(path, scope="planar", fingerprint="f") as db:
        assert db.stats.loaded >= committed


def test_kill_9_during_writes_keeps_the_database(tmp_path):
    _kill_trials(tmp_path, 5)


@pytest.mark.slow
def test_kill_9_during_writes_keeps_the_database_100_trials(tmp_path):
    _kill_trials(tmp_path, 100, seed=1)
