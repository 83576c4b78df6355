"""Locate the grammar and the standard library, installed or in a source checkout.

Why: an installed wheel carries them under `gnppdsl/data/`; a source checkout (editable install,
tests) keeps them at the repository's top level. Everything that needs them asks here.
"""
from __future__ import annotations

from pathlib import Path

_PACKAGE = Path(__file__).resolve().parent


def _find(name: str) -> Path:
    installed = _PACKAGE / "data" / name
    if installed.is_dir():
        return installed
    source = _PACKAGE.parent / name
    if source.is_dir():
        return source
    raise FileNotFoundError(f"gnppdsl installation is incomplete: no '{name}' directory found")


def grammar_dir() -> Path:
    """Directory holding the lark grammar files."""
    return _find("grammar")


def stdlib_dir() -> Path:
    """Directory holding the standard library modules (`*.pntc`)."""
    return _find("stdlib")
