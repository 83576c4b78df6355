"""Database of solved subgraphs (paper 000, Sec. VI-E), in memory and optionally in SQLite.

Why: different plans' graph-NLPs share subgraphs. Before an NLP is solved we ask
- is it contained in a subgraph already found *feasible*? then it is feasible (Property 4.4);
- does it contain a subgraph already found *infeasible*? then it is infeasible.
Both are label-preserving subgraph monomorphisms on semantic graphs (`semantic.py`), decided
by networkx's VF2 matcher.

Persistence (`--db PATH`): every verdict is one SQLite transaction in WAL mode, so a process
killed at any instant (crash, Ctrl-C, SIGKILL) leaves the file consistent: either the whole
record is there or none of it. Records are scoped by the domain name plus a fingerprint (a
hash of the domain's templates, chosen by the caller), so stale data is never reused after the
domain changes; the geometry of the objects a factor names (which factor bodies do not contain)
is part of the factor's label (`object_key`), so problems of one domain with different scenes
share what holds for both and nothing else. The schema is versioned;
an unknown version is refused with a clear message instead of being misread.
"""
from __future__ import annotations

import json
import time
from contextlib import contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Iterable, Iterator

from gnppdsl.compile.factors import FactorInstance
from gnppdsl.conflicts.semantic import MATCH_STATS, SemanticGraph, contains, isomorphic, monomorphism, semantic_graph
from gnppdsl.errors import UserError

if TYPE_CHECKING:
    import sqlite3       # imported where used: only a database with a file needs it

SCHEMA_VERSION = 1
#: SQLite `PRAGMA application_id` of a gnpp subgraph database ("GNPP"); `user_version` holds
#: SCHEMA_VERSION. Both live in the file's 100-byte header, read before anything is written.
APPLICATION_ID = 0x474E5050
_HEADER_MAGIC = b"SQLite format 3\x00"

_SCHEMA = """
CREATE TABLE IF NOT EXISTS meta (
    key   TEXT PRIMARY KEY,
    value TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS subgraphs (
    id          INTEGER PRIMARY KEY,
    scope       TEXT NOT NULL,      -- domain name
    fingerprint TEXT NOT NULL,      -- hash of templates + scene geometry
    feasible    INTEGER NOT NULL,   -- 1 feasible, 0 infeasible
    wl_hash     TEXT NOT NULL,      -- Weisfeiler-Lehman hash of the semantic graph
    graph       TEXT NOT NULL,      -- JSON: nodes [[id, label]], edges [[u, v, slots]]
    conflict    TEXT,               -- JSON: partial states as [[var, value], ...] per step
    created     REAL NOT NULL
);
CREATE INDEX IF NOT EXISTS subgraphs_scope ON subgraphs (scope, fingerprint, feasible);
"""

def _identify(path: Path) -> bool:
    """True if `path` is to become a new database (missing or empty); else checks that the
    existing file is a gnpp subgraph database (`UserError` if not), from its header bytes alone (nothing is
    opened for writing, so a foreign file is left exactly as it was). Files written before
    the identity pragmas existed (application_id 0) are accepted when their schema is this
    module's, read through a read-only connection."""
    import os
    import stat

    from gnppdsl.inputs import describe_os_error

    try:
        st = os.lstat(path)
    except FileNotFoundError:
        if not path.parent.exists():
            raise UserError(f"{path}: directory {path.parent} does not exist") from None
        return True
    except (OSError, ValueError) as exc:
        raise UserError(f"{path}: {describe_os_error(exc)}") from None
    if stat.S_ISDIR(st.st_mode):
        raise UserError(f"{path}: is a directory, expected a database file")
    if stat.S_ISLNK(st.st_mode) or not stat.S_ISREG(st.st_mode):
        raise UserError(f"{path}: not a regular file (symbolic links are not followed)")
    if st.st_size == 0:
        return True
    try:
        with open(path, "rb") as fh:
            header = fh.read(100)
    except OSError as exc:
        raise UserError(f"{path}: {describe_os_error(exc)}") from None
    if len(header) < 100 or not header.startswith(_HEADER_MAGIC):
        raise UserError(f"{path}: not a usable subgraph database (not an SQLite file); "
                        "choose another --db path")
    user_version = int.from_bytes(header[60:64], "big")
    app_id = int.from_bytes(header[68:72], "big")
    if app_id == APPLICATION_ID:
        if user_version != SCHEMA_VERSION:
            raise UserError(f"{path}: subgraph database has schema version {user_version}, this gnpp "
                            f"uses version {SCHEMA_VERSION}; remove the file or choose another --db path")
        return False
    if app_id == 0 and user_version == 0 and _legacy_schema(path):
        return False
    raise UserError(f"{path}: not a gnpp subgraph database (an SQLite file of another application, "
                    f"application_id {app_id:#x}); it was not modified; choose another --db path")


def _legacy_schema(path: Path) -> bool:
    """An unstamped file whose tables are exactly `_SCHEMA`'s (read-only connection)."""
    import sqlite3
    from urllib.parse import quote

    want = {}
    for stmt in filter(str.strip, _SCHEMA.split(";")):
        words = stmt.replace("IF NOT EXISTS ", "").split()
        want[words[2]] = " ".join(words)             # CREATE TABLE|INDEX name ...
    try:
        conn = sqlite3.connect(f"file:{quote(str(path.resolve()))}?mode=ro", uri=True, timeout=30.0)
        try:
            rows = conn.execute("SELECT name, sql FROM sqlite_master WHERE name NOT LIKE 'sqlite_%'").fetchall()
        finally:
            conn.close()
    except sqlite3.Error:
        return False
    have = {name: " ".join((sql or "").split()) for name, sql in rows}
    return have == want


Names = tuple[tuple[tuple[str, str], ...], ...]   # partial states by name, one tuple per step


@dataclass
class Entry:
    graph: SemanticGraph
    feasible: bool
    conflict: Names | None = None
    wl_hash: str = ""


@dataclass
class DatabaseStats:
    queries: int = 0
    feasible_hits: int = 0       # NLPs skipped because contained in a known feasible subgraph
    infeasible_hits: int = 0     # NLPs skipped because they contain a known infeasible subgraph
    stored: int = 0              # new records this session
    loaded: int = 0              # records read from the file at open
    match_time: float = 0.0      # seconds matching graphs in lookup / add / loading the file (subgraph monomorphisms)
    budget_exceeded: int = 0     # matches that gave up at `semantic.MATCH_BUDGET` (answered "unknown")


def _journal_mode_wal(conn: sqlite3.Connection, deadline: float) -> None:
    """Switch to write-ahead logging, retrying while another process holds the lock it needs.

    The connection's busy timeout does not cover this PRAGMA: SQLite returns SQLITE_BUSY at once,
    without calling the busy handler, when waiting could deadlock (sqlite3_busy_handler's
    documentation), and it does so when several processes open a new file at the same instant
    (two of eight openers failed with "database is locked" in CI). Retried with a short back-off
    until the same 30 s the busy timeout allows elsewhere."""
    import sqlite3

    delay = 0.005
    while True:
        try:
            conn.execute("PRAGMA journal_mode=WAL")
            return
        except sqlite3.OperationalError as exc:
            if "locked" not in str(exc) or time.monotonic() + delay > deadline:
                raise
        time.sleep(delay)
        delay = min(2 * delay, 0.25)


@dataclass
class SubgraphDatabase:
    """Feasible and infeasible subgraph-NLPs, keyed by their semantic structure."""

    path: str | Path | None = None
    scope: str = ""
    fingerprint: str = ""
    feasible: list[Entry] = field(default_factory=list)
    infeasible: list[Entry] = field(default_factory=list)
    stats: DatabaseStats = field(default_factory=DatabaseStats)
    # identity of an object's geometry (shape, robot model) for factor labels; None: the
    # fingerprint must then cover the scene's geometry
    object_key: Any = field(default=None, repr=False)

    def __post_init__(self) -> None:
        self._conn: sqlite3.Connection | None = None
        if self.path is not None:
            self._open(Path(self.path))

    # ---- persistence -------------------------------------------------------------------------
    def _open(self, path: Path) -> None:
        import sqlite3

        fresh = _identify(path)                 # refuses a foreign file before any write
        try:
            conn = sqlite3.connect(str(path), timeout=30.0)
            if fresh:
                # identity first, in rollback-journal mode, so it is in the main file's header
                # (not only in a WAL a kill -9 could leave behind) before any record exists; one
                # explicit transaction, so another process reading the header sees both ids or
                # neither (each PRAGMA committed on its own: a process starting at the same
                # moment read application_id without user_version and refused the file)
                with conn:
                    conn.execute("BEGIN IMMEDIATE")
                    conn.execute(f"PRAGMA application_id = {APPLICATION_ID}")
                    conn.execute(f"PRAGMA user_version = {SCHEMA_VERSION}")
                    for stmt in filter(str.strip, _SCHEMA.split(";")):
                        conn.execute(stmt)
            _journal_mode_wal(conn, deadline=time.monotonic() + 30.0)
            conn.execute("PRAGMA synchronous=NORMAL")
            with conn:
                for stmt in filter(str.strip, _SCHEMA.split(";")):
                    conn.execute(stmt)
                # INSERT OR IGNORE, not SELECT-then-INSERT: two processes opening a new file at
                # once both saw no row under a deferred transaction and the second INSERT failed
                # with "UNIQUE constraint failed: meta.key"
                conn.execute("INSERT OR IGNORE INTO meta (key, value) VALUES ('schema_version', ?)",
                             (str(SCHEMA_VERSION),))
                row = conn.execute("SELECT value FROM meta WHERE key = 'schema_version'").fetchone()
            version = row[0]
            if version != str(SCHEMA_VERSION):
                conn.close()
                raise UserError(
                    f"{path}: subgraph database has schema version {version}, this gnpp uses "
                    f"version {SCHEMA_VERSION}; remove the file or choose another --db path"
                )
            rows = conn.execute(
                "SELECT feasible, wl_hash, graph, conflict FROM subgraphs "
                "WHERE scope = ? AND fingerprint = ? ORDER BY id",
                (self.scope, self.fingerprint),
            ).fetchall()
        except sqlite3.DatabaseError as exc:
            raise UserError(f"{path}: not a usable subgraph database ({exc})") from None
        self._conn = conn
        with self._timed():     # the domination checks at load match graphs too (quadratic in records)
            self._load(rows)
        self.stats.loaded = len(rows)

    def _load(self, rows: list) -> None:
        for k, (feasible, wl, graph, conflict) in enumerate(rows):
            try:
                entry = Entry(SemanticGraph.from_json(json.loads(graph)), bool(feasible),
                              _names_from_json(conflict), wl)
            except (ValueError, KeyError, TypeError) as exc:
                self._conn.close()
                self._conn = None
                raise UserError(f"{self.path}: record {k + 1} of domain '{self.scope}' is not readable ({exc}); "
                                f"remove the file or choose another --db path") from None
            # records written before a dominating one was found are pruned in memory
            self._insert(entry)

    def _persist(self, entry: Entry) -> None:
        from gnppdsl import interrupt

        if self._conn is None or interrupt.pending():
            return        # a verdict reached after SIGINT/SIGTERM may rest on a cut-short run
        conflict = json.dumps([[list(f) for f in p] for p in entry.conflict]) if entry.conflict is not None else None
        with self._conn:   # one transaction per record: all or nothing
            self._conn.execute(
                "INSERT INTO subgraphs (scope, fingerprint, feasible, wl_hash, graph, conflict, created) "
                "VALUES (?, ?, ?, ?, ?, ?, ?)",
                (self.scope, self.fingerprint, int(entry.feasible), entry.wl_hash,
                 json.dumps(entry.graph.to_json()), conflict, time.time()),
            )

    def close(self) -> None:
        if self._conn is not None:
            self._conn.close()
            self._conn = None

    def __enter__(self) -> "SubgraphDatabase":
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---- queries -----------------------------------------------------------------------------
    def graph_of(self, subgraph: Any) -> SemanticGraph:
        if isinstance(subgraph, SemanticGraph):
            return subgraph
        return semantic_graph(subgraph, object_key=self.object_key)

    def infeasible_inside(self, subgraph: Any) -> tuple[FactorInstance, ...] | None:
        """The factors of `subgraph` that form a known infeasible subgraph, or None.

        Mapping them back with `to_partial_states` gives a sound conflict for the *current*
        task even when the record was learned on another problem of the same domain.
        """
        sg = self.graph_of(subgraph)
        for e in self.infeasible:
            m = monomorphism(e.graph, sg)
            if m is not None:
                return tuple(sg.factor_of[n] for n in m if n in sg.factor_of)
        return None

    def lookup(self, subgraph: Any) -> bool | None:
        """True: known feasible; False: known infeasible; None: unknown (solve it). A match that
        exceeds its budget counts as "not contained", so it can only turn a hit into a miss."""
        sg = self.graph_of(subgraph)
        self.stats.queries += 1
        with self._timed():
            if any(contains(sg, e.graph) for e in self.infeasible):
                self.stats.infeasible_hits += 1
                return False
            if any(contains(e.graph, sg) for e in self.feasible):
                self.stats.feasible_hits += 1
                return True
            return None

    @contextmanager
    def _timed(self) -> Iterator[None]:
        t0, given_up = time.perf_counter(), MATCH_STATS.budget_exceeded
        try:
            yield
        finally:
            self.stats.match_time += time.perf_counter() - t0
            self.stats.budget_exceeded += MATCH_STATS.budget_exceeded - given_up

    # ---- updates -----------------------------------------------------------------------------
    def add(self, subgraph: Any, feasible: bool, conflict: Names | None = None) -> bool:
        """Record a verdict. Returns False when it adds nothing (an equal or stronger record exists).

        Redundant records are not stored: a feasible graph contained in a known feasible one, an
        infeasible graph containing a known infeasible one.
        """
        sg = self.graph_of(subgraph)
        if sg.graph.number_of_nodes() == 0:
            return False
        entry = Entry(sg, feasible, conflict, "")
        with self._timed():
            inserted = self._insert(entry)
        if not inserted:
            return False
        entry.wl_hash = sg.wl_hash()
        self._persist(entry)
        self.stats.stored += 1
        return True

    def _insert(self, entry: Entry) -> bool:
        """Add to the in-memory lists unless dominated; drop the records it dominates.
        Infeasible records stay sorted by size so the smallest known conflict is found first."""
        sg = entry.graph
        if entry.feasible:
            if any(contains(e.graph, sg) for e in self.feasible):
                return False
            self.feasible = [e for e in self.feasible if not contains(sg, e.graph)]
            self.feasible.append(entry)
        else:
            if any(contains(sg, e.graph) for e in self.infeasible):
                return False
            self.infeasible = [e for e in self.infeasible if not contains(e.graph, sg)]
            self.infeasible.append(entry)
            self.infeasible.sort(key=lambda e: (e.graph.n_factors, e.graph.graph.number_of_nodes()))
        return True

    def __len__(self) -> int:
        return len(self.feasible) + len(self.infeasible)


def names_of(task: Any, partial_states: Iterable[Any]) -> Names:
    """Partial states (SAS indices) -> names, so they survive across tasks with other indices."""
    out = []
    for p in partial_states:
        facts = []
        for var, val in p.facts:
            v = task.variables[var]
            facts.append((v.name, v.values[val]))
        out.append(tuple(facts))
    return tuple(out)


def _names_from_json(text: str | None) -> Names | None:
    if text is None:
        return None
    return tuple(tuple((str(a), str(b)) for a, b in p) for p in json.loads(text))


__all__ = ["SubgraphDatabase", "DatabaseStats", "Entry", "names_of", "SCHEMA_VERSION", "isomorphic"]
