"""gnppdsl.ir: the resolved, typed model of .pntc files (see `gnppdsl.ir.model`).

Public API (raises `gnppdsl.lang.diagnostics.DiagnosticError`, a `UserError`, on bad input):

    load_problem(problem_path, domain_path=None) -> model.Problem
    load_domain(domain_path) -> model.Domain
    load_module(module_path) -> model.Module
    check_files(paths) -> CheckReport          # what `gnpp check` runs; never raises

The submodules are imported lazily so that `import gnppdsl.ir` stays cheap.
"""
from __future__ import annotations

from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # pragma: no cover
    from gnppdsl.ir.resolve import CheckReport
    from gnppdsl.ir.model import Domain, Module, Problem

__all__ = ["load_problem", "load_domain", "load_module", "check_files"]


def load_problem(problem_path: str | Path, domain_path: str | Path | None = None) -> "Problem":
    """Parse, resolve and type-check a problem and its domain (found as in docs/design.md when
    `domain_path` is None); the scene YAML is loaded into `Problem.scene`."""
    from gnppdsl.ir.resolve import Workspace

    ws = Workspace()
    prob = ws.problem(problem_path, domain_path)
    ws.reporter.raise_if_errors()
    if prob is None:  # pragma: no cover - every None path reports an error
        raise RuntimeError("problem could not be loaded, but no diagnostic was reported")
    return prob


def load_domain(domain_path: str | Path) -> "Domain":
    from gnppdsl.ir.resolve import Workspace

    ws = Workspace()
    dom = ws.domain(domain_path)
    ws.reporter.raise_if_errors()
    if dom is None:  # pragma: no cover
        raise RuntimeError("domain could not be loaded, but no diagnostic was reported")
    return dom


def load_module(module_path: str | Path) -> "Module":
    from gnppdsl.ir.resolve import Workspace

    ws = Workspace()
    mod = ws.check_module(module_path)
    ws.reporter.raise_if_errors()
    if mod is None:  # pragma: no cover
        raise RuntimeError("module could not be loaded, but no diagnostic was reported")
    return mod


def check_files(paths) -> "CheckReport":
    from gnppdsl.ir.resolve import check_files as _check

    return _check(paths)
