"""`gnpp bench --jit`: the compiled derivative kernels made ready before the timed runs.

Why: with `--jit` every run uses the large derivative kernels as compiled C
(`gnppdsl.nlp.jit`, mode "now"); a kernel missing from the cache is compiled by the run that
meets it first, and its CPU time (the C compiler's included) is in that run's `cpu_time`: the
first run of a family then reads ~30 s slower than the others (sort_random R-LGP: 12 kernels,
~35 s of compiling) and which run pays depends on the order of the grid. What a solver set up
once per machine costs is not a run's planning time, so the benchmark builds the kernels in a
warm-up step first and says so: one untimed solve per problem file and algorithm (its first
cell: the first instance or seed), rows discarded, with a progress line per solve naming what
it compiled. The cache is keyed by the kernels' own fingerprints (`KernelCache.key`), so what
the warm-up compiled is exactly what the timed runs load (instances of a randomised family
share their templates: sort_random's instance 1 loads the 12 kernels instance 0 compiled).
A kernel only another cell needs is still compiled by that run and counted in its CPU time
and its CSV column `kernels_compiled` (the warm-up never hides a compile of a timed run).

Measured (sort_random, R-LGP, 20 instances, `--jit` after its warm-up vs `--no-jit`, side by
side): CPU mean 6.52 -> 5.32 s, the same plans, costs and base paths; docs/design.md, "Compiled
kernels in `gnpp bench --jit`".
"""
from __future__ import annotations

import sys
from dataclasses import dataclass, field
from pathlib import Path
from typing import Callable, Sequence

from gnppdsl.cli.sweep import Cell, RunSettings


@dataclass
class WarmUp:
    """What the warm-up did: per warm-up cell, (label, kernels compiled, kernels in use, CPU s)."""

    solves: list[tuple[str, int, int, float]] = field(default_factory=list)

    @property
    def compiled(self) -> int:
        return sum(s[1] for s in self.solves)

    def note(self) -> str:
        """The line the table and the markdown carry (empty when no warm-up ran)."""
        if not self.solves:
            return ""
        cpu = sum(s[3] for s in self.solves)
        return (f"kernels (--jit): large derivative kernels run as compiled C; {self.compiled} compiled "
                f"into the cache by {len(self.solves)} untimed warm-up solve(s) ({cpu:.1f} s CPU, "
                f"in no run's cpu_time); a kernel a timed run compiled itself is in its cpu_time "
                f"and its kernels_compiled column")


def warm_up_cells(cells: Sequence[Cell]) -> list[Cell]:
    """The first cell of each (problem file, algorithm) in grid order."""
    seen: dict[tuple[str, str], Cell] = {}
    for c in cells:
        seen.setdefault((c.file, c.algorithm), c)
    return list(seen.values())


def warm_up(cells: Sequence[Cell], settings: RunSettings,
            say: Callable[[str], None] = lambda s: print(s, file=sys.stderr, flush=True),
            solve: Callable[[Cell, RunSettings], dict] | None = None) -> WarmUp:
    """Solve each `warm_up_cells(cells)` once with `settings` (whose `jit` is on), discarding
    the rows; `say` gets a line before and after each solve. `solve`: `sweep.solve_cell` (a
    parameter for tests)."""
    from gnppdsl.cli.sweep import preload_solver, solve_cell

    from gnppdsl.nlp import jit

    out = WarmUp()
    if not settings.jit or jit.mode(True) == "off":      # GNPP_JIT=0: the runs compile nothing either
        return out
    todo = warm_up_cells(cells)
    if solve is None:
        preload_solver()
        solve = solve_cell
    for k, c in enumerate(todo, 1):
        label = f"{Path(c.file).stem} {c.algorithm} " + (f"instance {c.instance}" if c.instance is not None
                                                           else f"seed {c.seed}")
        say(f"gnpp bench --jit: warm-up {k}/{len(todo)} ({label}): compiling the derivative kernels "
            f"it needs into the cache (not timed)...")
        row = solve(c, settings)
        n_new, n_used = int(row.get("kernels_compiled") or 0), int(row.get("kernels_native") or 0)
        cpu = float(row.get("cpu_time") or 0.0)
        out.solves.append((label, n_new, n_used, cpu))
        say(f"gnpp bench --jit: warm-up {k}/{len(todo)} ({label}): {row.get('status')}, {n_new} kernels "
            f"compiled, {n_used} in use, {cpu:.1f} s CPU")
    return out
