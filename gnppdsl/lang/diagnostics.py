"""Diagnostics a user can act on: `file:line:col: error: message`, the source line, a caret, a hint.

Why a collector instead of raising at the first problem: one `gnpp check` run should report every
independent mistake in a file, the way compilers do. Each phase (parse, resolve, type check,
scene) adds `Diagnostic`s to a `Reporter`; the caller raises one `DiagnosticError` carrying all
of them when the phase is done. `str(DiagnosticError)` is the rendered report, so the CLI just
prints it (exit code 2, no traceback).
"""
from __future__ import annotations

from dataclasses import dataclass, field
from functools import lru_cache
from typing import Iterable

from gnppdsl.errors import UserError
from gnppdsl.lang.span import Span

#: characters of the source line shown around the caret (a 100 KB line is cut to this window)
ECHO_WINDOW = 120
#: errors rendered per file; the rest are counted ("... and 3,990 more errors in FILE")
MAX_ERRORS_PER_FILE = 50
#: characters of a message or a hint shown (they may quote a name of any length)
MAX_MESSAGE = 300


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
        message = _printable(self.message)
        if len(message) > MAX_MESSAGE:      # a message quoting a 10,000-character name
            message = message[:MAX_MESSAGE] + f"... ({len(message):,} characters)"
        out = [f"{loc}{self.severity}: {message}"]
        if self.span is not None and source_line is not None:
            text = _printable(source_line.rstrip("\n").expandtabs(1))
            num = str(self.span.line)
            pad = " " * len(num)
            col = max(self.span.column, 1)
            width = 1
            if self.span.end_line == self.span.line and self.span.end_column:
                width = max(1, self.span.end_column - self.span.column)
            width = max(1, min(width, len(text) - col + 1)) if len(text) >= col else 1
            text, col, width = _window(text, col, width)
            out.append(f" {num} | {text}")
            out.append(f" {pad} | {' ' * (col - 1)}{'^' * width}")
        if self.hint:
            hint = _printable(self.hint)
            out.append(f"hint: {hint[:MAX_MESSAGE]}{'...' if len(hint) > MAX_MESSAGE else ''}")
        return "\n".join(out)


def _printable(text: str) -> str:
    """Control characters (NUL, escape sequences of a hostile file) shown as U+FFFD, one
    column each, so the caret stays under the right character and the terminal is safe."""
    if text.isprintable():
        return text
    return "".join(c if c.isprintable() or c == " " else "\ufffd" for c in text)


def _window(text: str, col: int, width: int) -> tuple[str, int, int]:
    """At most `ECHO_WINDOW` characters of a line around the caret, cut ends marked `...`.
    Why: echoing a whole 100 KB line per diagnostic made output grow with the square of it."""
    if len(text) <= ECHO_WINDOW:
        return text, col, width
    width = min(width, ECHO_WINDOW // 2)
    start = max(0, col - 1 - ECHO_WINDOW // 3)
    end = min(len(text), start + ECHO_WINDOW)
    start = max(0, min(start, end - ECHO_WINDOW))
    head = "..." if start > 0 else ""
    tail = "..." if end < len(text) else ""
    return head + text[start:end] + tail, col - start + len(head), width


class SourceCache:
    """File contents by path, so diagnostics can show the offending line.

    Only texts the front end has read (and so accepted as .pntc / scene YAML) are echoed: a
    diagnostic about any other file shows no line (`gnppdsl.inputs`: a mistaken
    `scene "/etc/shadow"` must not print the file). Lines are split once per file.
    """

    def __init__(self) -> None:
        self._texts: dict[str, str] = {}
        self._lines: dict[str, list[str]] = {}

    def add(self, path: str, text: str) -> None:
        self._texts[path] = text
        self._lines.pop(path, None)

    def line(self, path: str, line: int) -> str | None:
        if path not in self._lines:
            text = self._texts.get(path)
            if text is None:
                return None
            self._lines[path] = text.splitlines()
        lines = self._lines[path]
        return lines[line - 1] if 1 <= line <= len(lines) else None


@dataclass
class Reporter:
    """Collects diagnostics of one run (all files)."""

    diagnostics: list[Diagnostic] = field(default_factory=list)
    sources: SourceCache = field(default_factory=SourceCache)
    _seen: set = field(default_factory=set, repr=False)
    _count: int = field(default=0, repr=False)     # diagnostics already in `_seen`

    def error(self, span: Span | None, message: str, kind: str = "error",
              hint: str | None = None) -> None:
        self.add(Diagnostic(message, span, kind, hint))

    def warning(self, span: Span | None, message: str, kind: str = "warning",
                hint: str | None = None) -> None:
        self.diagnostics.append(Diagnostic(message, span, kind, hint, severity="warning"))
        self._seen.add(self.diagnostics[-1])
        self._count += 1

    def add(self, d: Diagnostic) -> None:
        """Add `d` unless the same diagnostic is already there (a set: 4,000 errors in one
        file stay linear; a list scan made them quadratic)."""
        if len(self.diagnostics) != self._count:       # appended directly: resync
            self._seen = set(self.diagnostics)
            self._count = len(self.diagnostics)
        if d in self._seen:
            return
        self._seen.add(d)
        self.diagnostics.append(d)
        self._count += 1

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
    """Every diagnostic, at most `MAX_ERRORS_PER_FILE` errors (and as many warnings) per file,
    then one line per file with the number left out."""
    sources = sources or SourceCache()
    parts = []
    shown: dict[tuple[str, str], int] = {}
    left: dict[tuple[str, str], int] = {}
    for d in diagnostics:
        key = (d.span.file if d.span is not None else "", d.severity)
        if shown.get(key, 0) >= MAX_ERRORS_PER_FILE:
            left[key] = left.get(key, 0) + 1
            continue
        shown[key] = shown.get(key, 0) + 1
        line = sources.line(d.span.file, d.span.line) if d.span is not None else None
        parts.append(d.render(line))
    for (file, severity), n in left.items():
        parts.append(f"{file or 'gnpp'}: ... and {n:,} more {severity}{'s' if n != 1 else ''}")
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


def read_source(reporter: Reporter, path: str, ref: Span | None = None,
                suffixes: tuple[str, ...] | None = None, what: str = "file",
                max_bytes: int | None = None) -> str | None:
    """The text of a user file (`gnppdsl.inputs.read_text`: regular, bounded, by suffix), or
    None with the reason reported: invalid UTF-8 at its line and column in the file (its
    text kept for the echo), anything else at `ref`, where the file is named."""
    from gnppdsl.inputs import InputError, read_text

    try:
        text = read_text(path, suffixes, what, max_bytes)
    except InputError as exc:
        shown = path if len(path) <= 80 else f"{path[:80]}... ({len(path):,} characters)"
        if exc.line is not None:
            reporter.sources.add(path, exc.text or "")
            reporter.error(Span(path, exc.line, exc.column or 1), exc.message, "unreadable-file")
        elif exc.too_large and ref is None:    # a file named on the command line: at its start
            reporter.error(Span(path, 1, 1), f"{what} is {exc.message}", "unreadable-file",
                           "split it into modules (`use`) or generate fewer objects per file")
        elif exc.message == "no such file":
            reporter.error(ref, f"{what} not found: {shown}", "missing-file")
        else:
            reporter.error(ref, f"cannot read {what} {shown}: {exc.message}", "unreadable-file")
        return None
    reporter.sources.add(path, text)
    return text


def did_you_mean(name: str, candidates: Iterable[str], prefix: str = "") -> str | None:
    """`did you mean 'grasp'?` for the closest candidate names, or None. Memoised on the name
    and the candidate set: a file naming one unknown name 100,000 times (a fuzz mutant) spent
    7 of 39 s in difflib, once per occurrence. `prefix` is put before the suggested names, not
    matched: a dotted name (`manipulation.paralel_grasp`) is compared by its last part, where a
    shared module prefix would make every template of the module look close, and suggested
    whole (`manipulation.parallel_grasp`), as it must be written."""
    return _did_you_mean(name, tuple(sorted(set(c for c in candidates if c))), prefix)


@lru_cache(maxsize=4096)
def _did_you_mean(name: str, cands: tuple[str, ...], prefix: str = "") -> str | None:
    import difflib      # here: only a misspelt name needs it (not every `gnpp solve`'s start)

    close = difflib.get_close_matches(name, cands, n=2, cutoff=0.6)
    if not close:
        lowered = {c.lower(): c for c in cands}
        if name.lower() in lowered:
            close = [lowered[name.lower()]]
    if not close:
        return None
    if len(close) == 1:
        return f"did you mean '{prefix}{close[0]}'?"
    return f"did you mean '{prefix}{close[0]}' or '{prefix}{close[1]}'?"
