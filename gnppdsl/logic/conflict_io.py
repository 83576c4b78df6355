"""Conflict files: sequences of partial states in DSL syntax, one conflict per line.

    # comments and blank lines are ignored
    <{parent(b1) = right, parent(b2) = s2}, {holding(g) = none}>
    <{free(g), not clear(s1)}>
    {parent(b1) = s1} -> {parent(b1) = g}          # the form solver logs print

Why names and not indices: conflicts are written by people and by earlier runs whose SAS+
indices may differ; they are resolved against a compiled `SASTask` by variable and value name
(whitespace inside names is ignored, so `above(b1,b2)` finds `above(b1, b2)`). A fact is
`VAR = VALUE`, `VAR` (boolean true) or `not VAR` (boolean false); anything else that names a
boolean variable, such as the compiler's auxiliary `parent(b1) != s1`, is that variable.
Every mistake is reported with file:line:col (all of them, not just the first).
"""
from __future__ import annotations

from pathlib import Path
from typing import Iterable, Sequence

from gnppdsl.compile.sas import PartialState, SASTask
from gnppdsl.errors import UserError
from gnppdsl.ir.expr import Span
from gnppdsl.lang.diagnostics import Diagnostic, DiagnosticError, SourceCache, did_you_mean

Conflict = tuple[PartialState, ...]
BOOL = ("false", "true")


def _norm(name: str) -> str:
    return "".join(name.split())


class _Line:
    """A scanner over one line that records 1-based columns for diagnostics."""

    def __init__(self, path: str, lineno: int, text: str, out: list[Diagnostic]) -> None:
        self.path, self.lineno, self.text, self.out = path, lineno, text, out
        self.i = 0

    def span(self, start: int, end: int | None = None) -> Span:
        return Span(self.path, self.lineno, start + 1, self.lineno, (end if end is not None else start + 1) + 1)

    def error(self, start: int, message: str, end: int | None = None, hint: str | None = None) -> None:
        self.out.append(Diagnostic(message, self.span(start, end), "conflict-syntax", hint))

    def skip(self) -> None:
        while self.i < len(self.text) and self.text[self.i] in " \t\r":
            self.i += 1

    def peek(self, s: str) -> bool:
        self.skip()
        return self.text.startswith(s, self.i)

    def eat(self, s: str) -> bool:
        if self.peek(s):
            self.i += len(s)
            return True
        return False

    def at_end(self) -> bool:
        self.skip()
        return self.i >= len(self.text) or self.text[self.i] == "#"


def _resolve(task: SASTask, index: dict[str, int], text: str, line: _Line, start: int):
    """One fact text -> (var, value), or None after reporting a diagnostic."""
    end = start + len(text)
    stripped = text.strip()

    def lookup(name: str, at: int):
        v = index.get(_norm(name))
        if v is None:
            line.error(at, f"unknown variable '{name.strip()}' in task {task.name}", at + len(name),
                       did_you_mean(name.strip(), (x.name for x in task.variables)))
        return v

    depth, eq = 0, -1
    for k, ch in enumerate(text):
        depth += ch == "("
        depth -= ch == ")"
        if ch == "=" and depth == 0 and (k == 0 or text[k - 1] not in "!<>") and text[k + 1:k + 2] != "=":
            eq = k
    if _norm(stripped) in index:                       # a whole boolean name, e.g. `x != y`
        v = index[_norm(stripped)]
        if task.variables[v].values != BOOL:
            line.error(start, f"'{stripped}' is not boolean: write '{stripped} = VALUE'", end)
            return None
        return (v, 1)
    if eq >= 0:
        name, value = text[:eq], text[eq + 1:].strip()
        v = lookup(name, start)
        if v is None:
            return None
        values = task.variables[v].values
        if value not in values:
            after = text[eq + 1:]
            line.error(start + eq + 1 + len(after) - len(after.lstrip()), f"'{value}' is not a value of {task.variables[v].name} "
                       f"(values: {', '.join(values)})", end, did_you_mean(value, values))
            return None
        return (v, values.index(value))
    negated = stripped.startswith("not ")
    name = stripped[4:] if negated else stripped
    v = lookup(name, start)
    if v is None:
        return None
    if task.variables[v].values != BOOL:
        line.error(start, f"'{task.variables[v].name}' is not boolean: write "
                   f"'{task.variables[v].name} = VALUE'", end)
        return None
    return (v, 0 if negated else 1)


def _partial_state(task: SASTask, index: dict[str, int], line: _Line) -> PartialState | None:
    open_at = line.i
    if not line.eat("{"):
        line.error(line.i, "expected '{' to start a partial state")
        return None
    facts: dict[int, tuple[int, int]] = {}
    ok = True
    if line.eat("}"):
        return PartialState()
    while True:
        line.skip()
        start, depth = line.i, 0
        while line.i < len(line.text):
            ch = line.text[line.i]
            if depth == 0 and ch in ",}":
                break
            depth += ch == "("
            depth -= ch == ")"
            line.i += 1
        text = line.text[start:line.i]
        if not text.strip():
            line.error(start, "expected a fact (VAR = VALUE, VAR or not VAR)")
            return None
        fact = _resolve(task, index, text.rstrip(), line, start)
        if fact is None:
            ok = False
        elif fact[0] in facts and facts[fact[0]][1] != fact[1]:
            line.error(start, f"{task.variables[fact[0]].name} gets two values in one partial state",
                       start + len(text.rstrip()))
            ok = False
        else:
            facts[fact[0]] = fact
        if line.eat(","):
            continue
        if line.eat("}"):
            break
        line.error(open_at, "unclosed '{'", line.i)
        return None
    return PartialState(tuple(facts.values())) if ok else None


def parse_conflicts(text: str, task: SASTask, path: str = "<conflicts>") -> list[Conflict]:
    """All conflicts in `text`; raises DiagnosticError (a UserError) listing every mistake."""
    index: dict[str, int] = {}
    for i, var in enumerate(task.variables):
        index.setdefault(_norm(var.name), i)
    out: list[Diagnostic] = []
    conflicts: list[Conflict] = []
    for lineno, raw in enumerate(text.splitlines(), start=1):
        line = _Line(path, lineno, raw, out)
        if line.at_end():
            continue
        errors_before = len(out)
        angled = line.eat("<")
        seq: list[PartialState | None] = []
        while True:
            seq.append(_partial_state(task, index, line))
            if seq[-1] is None and len(out) > errors_before and not line.peek(",") and not line.peek("->"):
                break
            if line.eat("->") or line.eat(","):
                continue
            break
        if len(out) == errors_before:
            if angled and not line.eat(">"):
                line.error(line.i, "expected '>' to close the conflict")
            elif not line.at_end():
                line.error(line.i, f"unexpected text '{line.text[line.i:].strip()}'")
        if len(out) == errors_before:
            conflicts.append(tuple(p for p in seq if p is not None))
    if out:
        sources = SourceCache()
        sources.add(path, text)
        raise DiagnosticError(out, sources)
    return conflicts


def read_conflicts(path: str | Path, task: SASTask) -> list[Conflict]:
    """Read a conflict file; a missing file is a UserError too."""
    from gnppdsl.inputs import InputError, read_text

    try:
        text = read_text(path)
    except InputError as exc:
        raise UserError(f"{path}: cannot read conflict file: {exc.message}") from None
    return parse_conflicts(text, task, str(path))


def format_conflict(task: SASTask, seq: Sequence[PartialState]) -> str:
    """`<{...}, {...}>` in the syntax `parse_conflicts` reads."""
    return "<" + ", ".join(task.partial_state_str(p) for p in seq) + ">"


def write_conflicts(task: SASTask, seqs: Iterable[Sequence[PartialState]]) -> str:
    return "".join(format_conflict(task, s) + "\n" for s in seqs)
