"""Lazy package exports: `from gnppdsl.<pkg> import Name` without importing every submodule.

Why: `gnpp --help`, `gnpp check` and a test of one module should not pay for casadi, clingo or
pinocchio because a package's `__init__` names something from a heavy submodule. Each package
keeps a table name -> submodule and lets this module's `__getattr__` (PEP 562) import the
submodule on first use.
"""
from __future__ import annotations

import importlib
from typing import Any, Callable, Mapping


def lazy_getattr(package: str, where: Mapping[str, str]) -> Callable[[str], Any]:
    """A module-level `__getattr__` for `package` that loads `name` from `where[name]`."""

    def __getattr__(name: str) -> Any:
        if name in where:
            return getattr(importlib.import_module(where[name]), name)
        raise AttributeError(f"module {package!r} has no attribute {name!r}")

    return __getattr__
