"""Solve the ASP that `gnpp compile --emit asp` writes, with clingo, as `clingo FILE` would.

The file is written for clingo's incremental mode (`#include <incmode>`: parts base, step(t),
check(t), external query(t)). `python -m clingo` (the only clingo executable the PyPI package
ships) does not run the incmode loop, so this helper runs it through the clingo Python API as
clingo's documented incmode does: ground base and check(0), then step(t) and check(t) for
t = 1, 2, ...; at each t set query(t) true and solve; the first satisfiable t is the plan length.
It shares nothing with gnppdsl.logic (which builds its own encoding in memory).
"""
from __future__ import annotations

from dataclasses import dataclass

import clingo


@dataclass
class ASPPlan:
    length: int | None                # None: no plan up to the step limit
    operators: list[int]              # op indices (the emitted `op(O)`), in order


def solve_incremental(text: str, max_steps: int = 30) -> ASPPlan:
    ctl = clingo.Control(["--warn=none"])
    ctl.add("base", [], text)
    parts = [("base", []), ("check", [clingo.Number(0)])]
    for t in range(0, max_steps + 1):
        if t > 0:
            parts = [("step", [clingo.Number(t)]), ("check", [clingo.Number(t)])]
        ctl.ground(parts)
        query = clingo.Function("query", [clingo.Number(t)])
        ctl.assign_external(query, True)
        found: list[list[tuple[int, int]]] = []
        ctl.solve(on_model=lambda m: found.append(
            [(a.arguments[1].number, a.arguments[0].number) for a in m.symbols(shown=True)
             if a.name == "occurs" and len(a.arguments) == 2]))
        ctl.release_external(query)
        if found:
            return ASPPlan(t, [o for _, o in sorted(found[-1])])
    return ASPPlan(None, [])
