"""gnppdsl.lang: the .pntc grammar, parser (text -> `gnppdsl.lang.ast` with spans) and
diagnostics (`file:line:col`, source line, caret, hint).

    parse_file(path, reporter) -> ast.FileAst | None
    Reporter, Diagnostic, DiagnosticError (a gnppdsl.errors.UserError)
"""
from gnppdsl.lang.diagnostics import Diagnostic, DiagnosticError, Reporter
from gnppdsl.lang.parser import parse_file, parse_text

__all__ = ["parse_file", "parse_text", "Diagnostic", "DiagnosticError", "Reporter"]
