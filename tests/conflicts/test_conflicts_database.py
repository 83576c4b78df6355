"""Semantic graphs, subgraph matching and the (persistent) database of solved subgraphs."""
from __future__ import annotations

import json
import os
import signal
import sqlite3
import subprocess
import sys
import textwrap
import time
from pathlib import Path

import pytest

from conflicts_fixture_factors import PARENT_B1, PARENT_B2, at_spot, grasp, no_overlap, same
from gnppdsl.conflicts.database import SCHEMA_VERSION, SubgraphDatabase
from gnppdsl.conflicts.semantic import contains, isomorphic, semantic_graph
from gnppdsl.errors import UserError


def chain(obj: str, start: int, length: int, val: int = 0):
    return [same(obj, start + i, val) for i in range(length)]


# ---- semantic graphs and containment ----------------------------------------------------------

def test_containment_is_time_shift_invariant():
    big = semantic_graph(chain("b1", 0, 5) + [at_spot("b1", 0, (0, 0), PARENT_B1, 0)])
    small = semantic_graph(chain("b1", 7, 2))
    assert contains(big, small)
    assert not contains(small, big)


def test_different_constants_are_different_factors():
    a = semantic_graph([at_spot("b1", 0, (0.0, 0.0), PARENT_B1, 0)])
    b = semantic_graph([at_spot("b1", 0, (0.5, 0.0), PARENT_B1, 0)])
    assert not contains(a, b) and not contains(b, a)


def test_different_objects_are_different_variables():
    a = semantic_graph(chain("b1", 0, 3))
    b = semantic_graph(chain("b2", 0, 2, 0))
    assert not contains(a, b)


def test_slot_order_matters():
    g = grasp("b1", 0, PARENT_B1, 1)
    swapped = type(g)(**{**g.__dict__, "variables": (g.variables[1], g.variables[0])})
    assert not contains(semantic_graph([g]), semantic_graph([swapped]))


def test_structure_matters_not_only_labels():
    # pattern: two same-factors sharing a variable (a chain); target: same labels, disjoint pieces
    pattern = semantic_graph(chain("b1", 0, 2))
    target = semantic_graph([same("b1", 0, 0), same("b1", 5, 0), at_spot("b1", 9, (0, 0), PARENT_B1, 0)])
    assert pattern.labels <= target.labels
    assert not contains(target, pattern)


def test_collision_pattern_inside_a_dense_step():
    target = semantic_graph(
        [no_overlap(s) for s in range(6)] + chain("b1", 0, 5) + chain("b2", 0, 5, 1)
        + [grasp("b1", 3, PARENT_B1, 1)]
    )
    pattern = semantic_graph([no_overlap(2), same("b1", 2, 0), no_overlap(3)])
    assert contains(target, pattern)
    m_pattern = semantic_graph([no_overlap(2), grasp("b1", 2, PARENT_B1, 1)])
    assert contains(target, m_pattern)     # grasp at 3 and no_overlap at 3
    assert not contains(target, semantic_graph([grasp("b1", 0, PARENT_B1, 1), grasp("b1", 1, PARENT_B1, 1),
                                                same("b1", 0, 0)]))


def test_json_round_trip_keeps_identity():
    g = semantic_graph(chain("b1", 2, 3) + [no_overlap(3), grasp("b2", 4, PARENT_B2, 2)])
    back = type(g).from_json(json.loads(json.dumps(g.to_json())))
    assert isomorphic(g, back)
    assert back.wl_hash() == g.wl_hash()


# ---- database in memory -----------------------------------------------------------------------

def test_lookup_feasible_and_infeasible():
    db = SubgraphDatabase()
    assert db.lookup(chain("b1", 0, 2)) is None
    db.add(chain("b1", 0, 4), feasible=True)
    assert db.lookup(chain("b1", 3, 3)) is True            # contained in a feasible graph
    assert db.lookup(chain("b1", 0, 5)) is None             # larger: unknown
    bad = [at_spot("b1", 0, (0, 0), PARENT_B1, 0), at_spot("b1", 0, (3, 0), PARENT_B1, 0)]
    # (two places for one pose at once: infeasible)
    db.add(bad, feasible=False)
    shifted = [at_spot("b1", 4, (0, 0), PARENT_B1, 0), at_spot("b1", 4, (3, 0), PARENT_B1, 0)]
    assert db.lookup(chain("b1", 0, 5) + shifted) is False
    assert db.stats.feasible_hits == 1 and db.stats.infeasible_hits == 1


def test_infeasible_inside_returns_the_current_factors():
    db = SubgraphDatabase()
    db.add([at_spot("b1", 0, (0, 0), PARENT_B1, 0), at_spot("b1", 0, (3, 0), PARENT_B1, 0)], feasible=False)
    here = [at_spot("b1", 4, (0, 0), PARENT_B1, 0), at_spot("b1", 4, (3, 0), PARENT_B1, 0)]
    found = db.infeasible_inside(chain("b1", 0, 6) + here)
    assert found is not None and set(found) == set(here)


def test_redundant_records_are_not_added():
    db = SubgraphDatabase()
    assert db.add(chain("b1", 0, 2), True)
    assert not db.add(chain("b1", 4, 1), True)              # contained in a known feasible one
    assert db.add(chain("b1", 0, 5), True)                  # dominates the first
    assert len(db.feasible) == 1
    assert db.add([no_overlap(0), no_overlap(1)] + chain("b1", 0, 1), False)
    assert not db.add([no_overlap(0), no_overlap(1)] + chain("b1", 0, 1) + chain("b2", 0, 1, 1), False)
    assert len(db.infeasible) == 1


# ---- persistence --------------------------------------------------------------------------------

def test_persistence_scoped_by_domain_and_fingerprint(tmp_path: Path):
    path = tmp_path / "db.sqlite"
    with SubgraphDatabase(path, scope="planar", fingerprint="abc") as db:
        db.add(chain("b1", 0, 3), True)
        db.add([at_spot("b1", 0, (0, 0), PARENT_B1, 0), at_spot("b1", 0, (3, 0), PARENT_B1, 0)], False,
               conflict=((("parent(b1)", "s1"),),))
    with SubgraphDatabase(path, scope="planar", fingerprint="abc") as db:
        assert db.stats.loaded == 2
        assert db.lookup(chain("b1", 5, 2)) is True
        assert db.infeasible[0].conflict == ((("parent(b1)", "s1"),),)
    with SubgraphDatabase(path, scope="planar", fingerprint="changed") as db:
        assert len(db) == 0 and db.lookup(chain("b1", 5, 2)) is None
    with SubgraphDatabase(path, scope="other", fingerprint="abc") as db:
        assert len(db) == 0


def test_schema_version_mismatch_and_garbage_are_user_errors(tmp_path: Path):
    path = tmp_path / "db.sqlite"
    SubgraphDatabase(path).close()
    conn = sqlite3.connect(path)
    with conn:
        conn.execute("UPDATE meta SET value = '999' WHERE key = 'schema_version'")
    conn.close()
    with pytest.raises(UserError, match="schema version 999"):
        SubgraphDatabase(path)
    junk = tmp_path / "junk.sqlite"
    junk.write_bytes(b"this is not sqlite" * 100)
    with pytest.raises(UserError, match="not a usable subgraph database"):
        SubgraphDatabase(junk)
    with pytest.raises(UserError, match="does not exist"):
        SubgraphDatabase(tmp_path / "missing" / "db.sqlite")
    assert SCHEMA_VERSION == 1


_WRITER = textwrap.dedent(
    """
    import sys, time
    sys.path.insert(0, {tests!r})
    from conflicts_fixture_factors import same
    from gnppdsl.conflicts.database import SubgraphDatabase
    db = SubgraphDatabase({path!r}, scope="planar", fingerprint="f")
    for n in range(1, {n} + 1):
        # distinct objects make every record new (no dominance between them)
        db.add([same("o%d" % n, 0, 0)], feasible=True)
    print("committed", flush=True)
    # now hold a big write transaction open and die inside it
    conn = db._conn
    conn.execute("BEGIN IMMEDIATE")
    for i in range(2000):
        conn.execute(
            "INSERT INTO subgraphs (scope, fingerprint, feasible, wl_hash, graph, conflict, created) "
            "VALUES ('planar', 'f', 1, 'x', '{{\\"nodes\\": [], \\"edges\\": []}}', NULL, 0)")
    print("in-transaction", flush=True)
    time.sleep(60)
    """
)


def test_killed_writer_never_corrupts_the_file(tmp_path: Path):
    path = tmp_path / "db.sqlite"
    script = _WRITER.format(tests=str(Path(__file__).parent), path=str(path), n=25)
    proc = subprocess.Popen([sys.executable, "-c", script], stdout=subprocess.PIPE, text=True)
    try:
        lines = []
        deadline = time.time() + 60
        while time.time() < deadline:
            line = proc.stdout.readline().strip()
            lines.append(line)
            if line == "in-transaction" or proc.poll() is not None:
                break
        assert lines[-2:] == ["committed", "in-transaction"], lines
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(timeout=10)
    finally:
        if proc.poll() is None:
            proc.kill()
    conn = sqlite3.connect(path)
    assert conn.execute("PRAGMA integrity_check").fetchone()[0] == "ok"
    conn.close()
    with SubgraphDatabase(path, scope="planar", fingerprint="f") as db:
        assert db.stats.loaded == 25                      # all committed, none of the open transaction
        for n in (1, 13, 25):
            assert db.lookup([same(f"o{n}", 3, 0)]) is True
        db.add([same("fresh", 0, 0)], True)               # still writable after the crash
    with SubgraphDatabase(path, scope="planar", fingerprint="f") as db:
        assert db.stats.loaded == 26


def test_reload_prunes_records_dominated_later(tmp_path: Path):
    path = tmp_path / "db.sqlite"
    big = [at_spot("b1", 0, (0, 0), PARENT_B1, 0), at_spot("b1", 0, (3, 0), PARENT_B1, 0)] + chain("b1", 0, 2)
    small = [at_spot("b1", 0, (0, 0), PARENT_B1, 0), at_spot("b1", 0, (3, 0), PARENT_B1, 0)]
    with SubgraphDatabase(path, scope="s", fingerprint="f") as db:
        assert db.add(big, False)
        assert db.add(small, False)          # dominates `big` in memory; both rows are on disk
        assert len(db.infeasible) == 1
    with SubgraphDatabase(path, scope="s", fingerprint="f") as db:
        assert db.stats.loaded == 2 and len(db.infeasible) == 1
        found = db.infeasible_inside(big + chain("b2", 0, 3, 1))
        assert found is not None and len(found) == 2      # the smallest known conflict


def test_object_geometry_is_part_of_factor_identity():
    from gnppdsl.compile.factors import FactorInstance
    from gnppdsl.compile.sas import PartialState
    from gnppdsl.ir.expr import Call, Constraint, Num, Obj, Slot
    from conflicts_fixture_factors import pose

    def sd(step):
        return FactorInstance("planar.no_collision", "avoid", (), frozenset({"collision"}), step, 1, (PartialState(),),
                              (pose("b1", step), pose("b2", step)),
                              (Constraint(Call("sdist2", (Obj("b1"), Slot(0), Obj("b2"), Slot(1))), ">=", Num(0.0)),))

    shapes_a = {"b1": "circle0.05", "b2": "box0.1"}
    shapes_b = {"b1": "circle0.20", "b2": "box0.1"}
    db = SubgraphDatabase(object_key=shapes_a.get)
    db.add([sd(0)], feasible=False)
    assert db.lookup([sd(3)]) is False                     # same geometry, other time: known
    other_scene = SubgraphDatabase(object_key=shapes_b.get)
    other_scene.infeasible = db.infeasible               # records learned with scene A
    assert other_scene.lookup([sd(3)]) is None            # b1 has another shape: not reused


from hypothesis import given, settings, strategies as st  # noqa: E402


def _world(n_steps: int):
    fs = []
    for i in range(n_steps):
        fs += [no_overlap(i), at_spot("b1", i, (0.0, 0.0), PARENT_B1, 0), grasp("b2", i, PARENT_B2, 2)]
        if i + 1 < n_steps:
            fs += [same("b1", i, 0), same("b2", i, 1, PARENT_B2)]
    return fs


def _shift(f, d):
    from dataclasses import replace as dc_replace

    return dc_replace(f, step=f.step + d, variables=tuple(dc_replace(v, step=v.step + d) for v in f.variables))


@settings(max_examples=40, deadline=None)
@given(st.integers(2, 5), st.data())
def test_every_subset_is_contained_at_any_time_shift(n_steps, data):
    world = _world(n_steps)
    subset = data.draw(st.lists(st.sampled_from(world), min_size=1, max_size=6, unique=True))
    shift = data.draw(st.integers(0, 7))
    assert contains(semantic_graph(world), semantic_graph([_shift(f, shift) for f in subset]))
    # and a factor the world does not have is never "contained"
    alien = at_spot("b1", 0, (9.0, 9.0), PARENT_B1, 0)
    assert not contains(semantic_graph(world), semantic_graph(subset + [alien]))


def test_unreadable_record_is_a_user_error(tmp_path: Path):
    path = tmp_path / "db.sqlite"
    with SubgraphDatabase(path, scope="s", fingerprint="f") as db:
        db.add(chain("b1", 0, 2), True)
    conn = sqlite3.connect(path)
    with conn:
        conn.execute("UPDATE subgraphs SET graph = '{not json'")
    conn.close()
    with pytest.raises(UserError, match="record 1 .* not readable"):
        SubgraphDatabase(path, scope="s", fingerprint="f")
