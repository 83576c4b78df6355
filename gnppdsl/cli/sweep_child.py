"""The child process of an isolated benchmark run: one cell in, one CSV row out (JSON lines).

`sweep.solve_cell_isolated` starts it with a wall-clock and a memory cap, so whatever happens to
the solver here (a hang, a crash, memory exhausted) ends this process only, and the parent
records the ending as a row. The row goes to stdout as the last line starting with `{`; the
solver's own warnings may print before it.
"""
from __future__ import annotations

import json
import sys

from gnppdsl.cli.sweep import Cell, RunSettings, preload_solver, solve_cell


def main() -> int:
    request = json.load(sys.stdin)
    cell = Cell(**request["cell"])
    settings = RunSettings(**request["settings"])
    preload_solver()          # start-up, not the run's time (`sweep.preload_solver`)
    row = solve_cell(cell, settings)
    sys.stdout.write("\n" + json.dumps(row, default=str) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
