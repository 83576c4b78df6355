"""Source positions: where a piece of text came from (file, line, column).

Why here: positions are made by the parser and reported by diagnostics, so they belong to the
lowest layer; `gnppdsl.ir.expr` re-exports `Span` for the IR nodes that keep them.
"""
from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Span:
    file: str
    line: int
    column: int
    end_line: int | None = None
    end_column: int | None = None

    def __str__(self) -> str:
        return f"{self.file}:{self.line}:{self.column}"
