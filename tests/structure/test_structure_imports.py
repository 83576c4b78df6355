"""Structural check of the package (issue 18): no import cycle between gnppdsl modules, counting
imports inside functions too.

The import graph is built from the source with `ast` (every `import` / `from ... import`
anywhere in a module, relative ones resolved), not from `sys.modules`: an import hidden inside
a function is still an edge, which is what the rule forbids."""
from __future__ import annotations

import ast
from pathlib import Path

import networkx as nx

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "gnppdsl"


def _modules() -> dict[str, Path]:
    """Dotted module name -> file, for every .py file of the package (a package is its
    __init__)."""
    out = {}
    for f in PKG.rglob("*.py"):
        parts = list(f.relative_to(ROOT).with_suffix("").parts)
        if parts[-1] == "__init__":
            parts = parts[:-1]
        out[".".join(parts)] = f
    return out


def _imported(name: str, path: Path, mods: dict[str, Path]) -> set[str]:
    """The gnppdsl modules `name` imports anywhere in its source (module level, functions,
    methods, relative imports resolved). `from a.b import c` is an edge to `a.b.c` when that is
    a module, else to `a.b` (the package's __init__ defines `c`)."""
    pkg = name if path.name == "__init__.py" else name.rpartition(".")[0]
    targets: set[str] = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            targets.update(a.name for a in node.names)
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = pkg.split(".")
                base = base[:len(base) - node.level + 1]
                mod = ".".join(base + ([node.module] if node.module else []))
            else:
                mod = node.module or ""
            subs = [f"{mod}.{a.name}" for a in node.names if f"{mod}.{a.name}" in mods]
            targets.update(subs)
            if len(subs) < len(node.names):
                targets.add(mod)
    out = set()
    for t in targets:
        while t and t not in mods:
            t = t.rpartition(".")[0]
        if t and t != name and t.startswith("gnppdsl"):
            out.add(t)
    return out


def import_graph() -> nx.DiGraph:
    mods = _modules()
    g = nx.DiGraph()
    g.add_nodes_from(mods)
    for name, path in mods.items():
        for t in _imported(name, path, mods):
            g.add_edge(name, t)
    return g


def test_the_graph_sees_imports_inside_functions(tmp_path):
    """The checker itself: a function-level import is an edge, relative imports resolve."""
    src = "def f():\n    from gnppdsl.solve import loop\n    from . import certificate\n"
    p = tmp_path / "m.py"
    p.write_text(src)
    mods = {"gnppdsl.nlp.m": p, "gnppdsl.solve.loop": p, "gnppdsl.solve": p,
            "gnppdsl.nlp.certificate": p, "gnppdsl.nlp": p}
    assert _imported("gnppdsl.nlp.m", p, mods) == {"gnppdsl.solve.loop", "gnppdsl.nlp.certificate"}


def test_no_import_cycle_between_gnppdsl_modules():
    g = import_graph()
    # a package's __init__ importing its own submodules is not a cycle with them
    g.remove_edges_from([(a, b) for a, b in list(g.edges) if b.startswith(a + ".")])
    cycles = sorted(sorted(c) for c in nx.strongly_connected_components(g) if len(c) > 1)
    assert cycles == [], "import cycles (imports inside functions count): " + "; ".join(
        " -> ".join(c) for c in cycles)
