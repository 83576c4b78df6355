"""Structural check of the package (issue 18): each file one idea, so none is long. The limits
are the quality rules': no gnppdsl module over 900 lines, none of gnppdsl/solve over 600."""
from __future__ import annotations

from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
PKG = ROOT / "gnppdsl"


def test_module_sizes():
    """Each file one idea: none over 900 lines, none of gnppdsl/solve over 600."""
    too_long = []
    for f in sorted(PKG.rglob("*.py")):
        n = len(f.read_text().splitlines())
        limit = 600 if f.relative_to(PKG).parts[0] == "solve" else 900
        if n > limit:
            too_long.append(f"{f.relative_to(ROOT)}: {n} > {limit}")
    assert too_long == []
