"""Errors a user can cause and act on.

Why: the CLI must never show a traceback for bad input. Every layer raises a `UserError`
(or a subclass, e.g. `gnppdsl.lang.diagnostics.DiagnosticError` carrying file:line:col
diagnostics); `gnppdsl.cli.main` prints `str(error)` and exits with `exit_code`.
"""
from __future__ import annotations


class UserError(Exception):
    """A problem with the user's input or request (exit code 2)."""

    exit_code = 2


class SolveFailure(UserError):
    """The problem could not be solved: no plan, time limit, solver failure (exit code 1)."""

    exit_code = 1
