"""docs/design.md's map of the layers and files matches the code: it names every module of
`gnppdsl/` (package `__init__.py` files, which only re-export, aside from the package top's,
which is the public API), and every file it names exists."""
from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "gnppdsl"


def _mapped() -> list[str]:
    text = (ROOT / "docs" / "design.md").read_text()
    section = text.split("## Map of the layers and files", 1)[1].split("\n## ", 1)[0]
    return re.findall(r"^- `([\w/]+\.py)`:", section, re.M)


def test_the_map_names_each_module_once_and_only_modules_that_exist():
    mapped = _mapped()
    assert len(mapped) == len(set(mapped)), [m for m in mapped if mapped.count(m) > 1]
    modules = {str(f.relative_to(PKG)) for f in PKG.rglob("*.py")
               if f.name != "__init__.py" or f.parent == PKG}
    assert sorted(set(mapped) - modules) == []          # named, but no such file
    assert sorted(modules - set(mapped)) == []          # a module the map does not name
