"""Diagnostics a user can act on: `file:line:col: error: message`, the source line, a caret, a hint.

Why a collector instead of raising at the first problem: one `gnpp check` run should report every
independent mistake in a file, the way compilers do. Each phase (parse, resolve, type check,
scene) adds `Diagnostic`s to a `Reporter`; the caller raises one `DiagnosticError` carrying all
of them when the phase is done. `str(DiagnosticError)` is the rendered report, so the CLI just
prints it (exit code 2, no traceback).
"""
from __future__ import annotations

import difflib
from dataclasses import dataclass, field
from typing import Iterable

from gnppdsl.errors import UserError
from gnppdsl.lang.span import Span


@dataclass(frozen=True)
class Diagnostic:
    """One finding. `kind` is a stable machine-readable category (tests and tools key on it)."""

    message: str
    span: Span | None
    kind: str = "error"
    hint: str | None = None
    severity: str = "error"            # "error" or "warning"

    def render(self, source_line: str | None = None) -> str:
        loc = f"{self.span}: " if self.span is not None else ""
        out = [f"{loc}{self.severity}: {self.message}"]
        if self.span is not None and source_line is not None:
            text = source_line.rstrip("\n").expandtabs(1)
            num = str(self.span.line)
            pad = " " * len(num)
            col = max(self.span.column, 1)
            width = 1
            if self.span.end_line == self.span.line and self.span.end_column:
                width = max(1, self.span.end_column - self.span.column)
            width = max(1, min(width, len(text) - col + 1)) if len(text) >= col else 1
            out.append(f" {num} | {text}")
            out.append(f" {pad} | {' ' * (col - 1)}{'^' * width}")
        if self.hint:
            out.append(f"hint: {self.hint}")
        return "\n".join(out)


class SourceCache:
    """File contents by path, so diagnostics can show the offending line."""

    def __init__(self) -> None:
        self._texts: dict[str, str] = {}

    def add(self, path: str, text: str) -> None:
        self._texts[path] = text

    def line(self, path: str, line: int) -> str | None:
        text = self._texts.get(path)
        if text is None:
            try:
                with open(path, encoding="utf-8", errors="replace") as fh:
                    text = fh.read()
            except OSError:
                return None
            self._texts[path] = text
        lines = text.splitlines()
        return lines[line - 1] if 1 <= line <= len(lines) else None


@dataclass
class Reporter:
    """Collects diagnostics of one run (all files)."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    sources: SourceCache = field(default_factory=SourceCache)

    def error(self, span: Span | None, message: str, kind: str = "error",
              hint: str | None = None) -> None:
        d = Diagnostic(message, span, kind, hint)
        if d not in self.diagnostics:
            self.diagnostics.append(d)

    def warning(self, span: Span | None, message: str, kind: str = "warning",
                hint: str | None = None) -> None:
        self.diagnostics.append(Diagnostic(message, span, kind, hint, severity="warning"))

    @property
    def errors(self) -> list[Diagnostic]:
        return [d for d in self.diagnostics if d.severity == "error"]

    def has_errors(self) -> bool:
        return any(d.severity == "error" for d in self.diagnostics)

    def render(self) -> str:
        return render_all(self.diagnostics, self.sources)

    def raise_if_errors(self) -> None:
        if self.has_errors():
            raise DiagnosticError(list(self.diagnostics), self.sources)


def render_all(diagnostics: Iterable[Diagnostic], sources: SourceCache | None = None) -> str:
    sources = sources or SourceCache()
    parts = []
    for d in diagnostics:
        line = sources.line(d.span.file, d.span.line) if d.span is not None else None
        parts.append(d.render(line))
    return "\n\n".join(parts)


class DiagnosticError(UserError):
    """Bad input with one or more located diagnostics. `str()` is the full rendered report."""

    def __init__(self, diagnostics: list[Diagnostic], sources: SourceCache | None = None) -> None:
        self.diagnostics = list(diagnostics)
        self.sources = sources or SourceCache()
        super().__init__(self.__str__())

    def __str__(self) -> str:
        n = sum(1 for d in self.diagnostics if d.severity == "error")
        body = render_all(self.diagnostics, self.sources)
        return f"{body}\n\n{n} error{'s' if n != 1 else ''}" if n else body


def did_you_mean(name: str, candidates: Iterable[str]) -> str | None:
    """`did you mean 'grasp'?` for the closest candidate names, or None."""
    cands = sorted(set(c for c in candidates if c))
    close = difflib.get_close_matches(name, cands, n=2, cutoff=0.6)
    if not close:
        lowered = {c.lower(): c for c in cands}
        if name.lower() in lowered:
            close = [lowered[name.lower()]]
    if not close:
        return None
    if len(close) == 1:
        return f"did you mean '{close[0]}'?"
    return f"did you mean '{close[0]}' or '{close[1]}'?"
