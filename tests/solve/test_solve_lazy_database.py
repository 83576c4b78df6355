"""The solve's database builds a record's semantic graph only when a query could match it
(`gnppdsl.solve.lazy_database`): the same answers as `SubgraphDatabase` given the same calls,
fewer semantic graphs."""
from __future__ import annotations

import hashlib
from pathlib import Path

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.compile.sas import PartialState
from gnppdsl.conflicts import database, semantic
from gnppdsl.conflicts.database import SubgraphDatabase
from gnppdsl.ir.expr import Call, Constraint, Num, Obj, Slot, Vec
from gnppdsl.solve import lazy_database, run as run_module
from gnppdsl.solve.compiled import load_and_compile
from gnppdsl.solve.lazy_database import LazyDatabase, coarse_labels, coarse_of_graph
from gnppdsl.solve.loop import solve_compiled
from gnppdsl.solve.options import SolveOptions
from solve_toy import occupied_problem


def pose(obj: str, step: int) -> VarInstance:
    return VarInstance("pose", (obj,), step, "SE2", 3, frozenset({"object"}))


def same(obj: str, step: int) -> FactorInstance:
    p = PartialState.of({0: 0})
    return FactorInstance(template="planar.same", rule="stay", bindings=(("o", obj),), tags=frozenset({"time"}),
                          step=step, span=2, generator=(p, p), variables=(pose(obj, step), pose(obj, step + 1)),
                          body=(Constraint(Slot(0), "==", Slot(1)),))


def at(obj: str, step: int, x: float) -> FactorInstance:
    return FactorInstance(template="planar.on", rule="on", bindings=(("o", obj),), tags=frozenset({"place"}),
                          step=step, span=1, generator=(PartialState.of({0: 0}),), variables=(pose(obj, step),),
                          body=(Constraint(Call("pos_se2", (Slot(0),)), "==", Vec((Num(x), Num(0.0)))),))


def chain(obj: str, start: int, length: int) -> list[FactorInstance]:
    return [same(obj, start + i) for i in range(length)]


def counting(monkeypatch) -> list[int]:
    """Count the semantic graphs built (by the database or the lazy records)."""
    built: list[int] = []
    real = database.semantic_graph

    def build(*args, **kw):
        built.append(1)
        return real(*args, **kw)

    monkeypatch.setattr(database, "semantic_graph", build)
    monkeypatch.setattr(lazy_database, "semantic_graph", build)
    return built


def test_coarse_labels_are_those_of_the_built_graph():
    factors = chain("b1", 2, 3) + [at("b1", 2, 0.5), at("b2", 7, 1.0)]
    assert coarse_labels(tuple(factors), ()) == coarse_of_graph(database.semantic_graph(factors))


def test_same_answers_as_the_plain_database_and_no_graph_for_a_query_nothing_could_match(monkeypatch):
    bad = [at("b1", 0, 0.0), at("b1", 0, 3.0)]          # two places for one pose: infeasible
    calls = [("add", chain("b1", 0, 4), True), ("lookup", chain("b1", 3, 3)), ("lookup", chain("b1", 0, 5)),
             ("add", bad, False), ("lookup", chain("b1", 0, 5) + [at("b1", 4, 0.0), at("b1", 4, 3.0)]),
             ("inside", chain("b2", 0, 3)), ("inside", chain("b1", 0, 2) + [at("b1", 1, 0.0), at("b1", 1, 3.0)]),
             ("lookup", [at("b2", 0, 1.0)]), ("add", [at("b2", 0, 1.0)], True), ("lookup", [at("b2", 5, 1.0)])]

    def replay(db) -> list:
        out = []
        for call in calls:
            if call[0] == "add":
                db.add(call[1], call[2])
            elif call[0] == "lookup":
                out.append(db.lookup(call[1]))
            else:
                found = db.infeasible_inside(call[1])
                out.append(None if found is None else sorted(f.label for f in found))
        return out

    plain = replay(SubgraphDatabase())
    assert plain == [True, None, False, None, sorted(f.label for f in [at("b1", 1, 0.0), at("b1", 1, 3.0)]),
                     None, True]
    lazy = LazyDatabase()
    assert replay(lazy) == plain
    # a query no record could match: "unknown" without building its semantic graph
    built = counting(monkeypatch)
    db = LazyDatabase()
    db.add(chain("b1", 0, 4), True)
    db.add(bad, False)
    assert db.lookup([at("b2", 0, 1.0)]) is None and db.infeasible_inside(chain("b2", 0, 6)) is None
    assert built == [] and db.skipped_queries == 2 and len(db.pending) == 2
    assert db.lookup(chain("b1", 2, 2)) is True          # could match: every record built, then matched
    assert len(built) == 3 and db.pending == [] and db.built_queries == 1


def test_pending_records_are_written_to_a_file_at_close(tmp_path):
    path = tmp_path / "db.sqlite"
    with LazyDatabase(path, scope="planar", fingerprint="x") as db:
        db.add(chain("b1", 0, 3), True)
        assert db.pending
    with SubgraphDatabase(path, scope="planar", fingerprint="x") as db:
        assert db.stats.loaded == 1 and db.lookup(chain("b1", 5, 2)) is True


def test_a_solve_builds_fewer_semantic_graphs_with_the_same_result(monkeypatch):
    """The toy's solve (one conflict, then a feasible plan) with the lazy and with the plain
    database: the same plans, conflicts and NLPs; fewer semantic graphs built."""
    options = SolveOptions(switches="trng", time_limit=60, max_horizon=6)
    built = counting(monkeypatch)
    lazy = solve_compiled(occupied_problem(), options)
    n_lazy = len(built)
    built.clear()
    class Plain(SubgraphDatabase):
        def knows_infeasible(self) -> bool:
            return bool(self.infeasible)

    monkeypatch.setattr(run_module, "LazyDatabase", Plain)
    plain = solve_compiled(occupied_problem(), options)
    n_plain = len(built)
    assert lazy.solved and plain.solved and lazy.stats.N == plain.stats.N == 4
    assert [c.text for c in lazy.conflicts] == [c.text for c in plain.conflicts]
    assert (lazy.stats.plans, lazy.stats.nlp_solves) == (plain.stats.plans, plain.stats.nlp_solves)
    assert n_lazy < n_plain


def _objects_by_walk(body) -> frozenset[str]:
    """The objects of a body by walking its tree (what `semantic.body_objects` computed before
    it read them from the body's repr)."""
    names: set[str] = set()
    stack = [body]
    while stack:
        e = stack.pop()
        if isinstance(e, Obj):
            names.add(e.name)
        elif isinstance(e, (tuple, list)):
            stack.extend(e)
        elif hasattr(e, "__dataclass_fields__"):
            stack.extend(getattr(e, name) for name in e.__dataclass_fields__ if name != "span")
    return frozenset(names)


def test_body_objects_from_the_repr_are_those_of_the_tree():
    """Every factor body of a solved Lab plan (fk, sdist, grasps, the table): the objects read
    from its repr are the `Obj` nodes of its tree, and the hash is that of the repr."""
    c = load_and_compile(str(Path(__file__).resolve().parents[2] / "examples" / "lab" / "lab1.pntc"))
    r = solve_compiled(c, SolveOptions.from_settings(c.problem.settings, time_limit=120))
    assert r.status == "solved", r.message
    factors = r.extras["graph"].factor_instances
    assert len(factors) > 50
    seen = set()
    for f in factors:
        assert semantic.body_objects(f.body) == _objects_by_walk(f.body), f.label
        assert semantic.body_hash(f.body) == hashlib.sha256(repr(f.body).encode()).hexdigest()[:20]
        seen |= semantic.body_objects(f.body)
    assert {"b1", "b2", "left_arm", "right_arm"} <= seen
