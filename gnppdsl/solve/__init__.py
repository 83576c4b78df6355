"""gnppdsl.solve: the Graph-NLP Planner loop (paper 000, Fig. 3), the One-way baseline, results.

    solve_problem(problem_or_path, options=None, **overrides) -> Result
    load_and_compile(paths) -> Compiled;  solve_compiled(compiled, options) -> Result
    SolveOptions, Result, brute_force (reference enumeration for tests)

Names are loaded lazily so that importing a submodule stays cheap.
"""
from __future__ import annotations

from gnppdsl.lazy import lazy_getattr

__all__ = ["solve_problem", "solve_compiled", "load_and_compile", "compile_problem", "SolveOptions",
           "Compiled", "Result", "brute_force"]

_WHERE = {
    "solve_problem": "gnppdsl.solve.loop", "solve_compiled": "gnppdsl.solve.loop",
    "load_and_compile": "gnppdsl.solve.compiled", "compile_problem": "gnppdsl.solve.compiled",
    "SolveOptions": "gnppdsl.solve.options", "Compiled": "gnppdsl.solve.compiled",
    "Result": "gnppdsl.solve.result", "brute_force": "gnppdsl.solve.brute",
}


__getattr__ = lazy_getattr(__name__, _WHERE)
