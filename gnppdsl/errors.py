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


class NumericalFault(SolveFailure):
    """A factor evaluates to NaN or infinity at the solver's point (a square root of a negative
    number, a division by zero in a template): a fault of the model reported with the factor's
    name (exit code 1), never mistaken for an infeasible plan ("no plan")."""
