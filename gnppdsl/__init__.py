"""gnppdsl: a modelling language, compiler and conflict-driven solver for TAMP posed as PNTC.

Layers (data flows one way): lang -> ir -> compile -> solve (logic, nlp, conflicts) -> cli.
geometry sits under nlp; reach is R-LGP.

The public API (internal modules may change, these names and signatures do not; the `gnpp`
command line is built on exactly them):

    load_and_compile(paths, instance=None) -> Compiled
        a problem file (its domain found next to it), or [domain, problem] in either order;
        `instance=K`: its randomised instance K (scene `random_xy` ranges drawn with seed K)
    SolveOptions(algorithm="gnpp", switches="trn", time_limit=60.0, seed=0, ...)
        SolveOptions.from_settings(problem.settings, **overrides): the problem's `solver { }`
        block with overrides (None keeps the setting)
    solve_problem(problem, options=None, progress=None, **overrides) -> Result
        problem: a path, a list of paths, an IR Problem or a Compiled (compiled once, solved
        many times); progress: a callback receiving the loop's messages
    Result: status, plan, steps (values, trajectories), conflicts, stats; `summary()`,
        `write_json(path)`

Names are loaded on first use (`gnppdsl.lazy`), so `import gnppdsl` and `gnpp --help` do not
import casadi, clingo or pinocchio.
"""
import os as _os

from gnppdsl.lazy import lazy_getattr as _lazy_getattr

# OpenBLAS (numpy's, and casadi's under ipopt's linear solver) starts a thread per core when it
# is loaded. The dense blocks of these NLPs are small, so the extra threads mostly wait, and
# OpenBLAS waits by spinning (sched_yield): measured on a 2-core machine during a Lab 5 run,
# 146 s of system time in that thread, the process's CPU time 1.5x its wall time; lab2 one
# thread: 4 % less CPU, the same wall time. One thread unless the user set it: this must run
# before numpy or casadi are first imported (it has no effect after).
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"

__all__ = ["solve_problem", "load_and_compile", "SolveOptions", "Result", "__version__"]

_WHERE = {
    "solve_problem": "gnppdsl.solve.loop",
    "load_and_compile": "gnppdsl.solve.compiled",
    "SolveOptions": "gnppdsl.solve.options",
    "Result": "gnppdsl.solve.result",
}

__getattr__ = _lazy_getattr(__name__, _WHERE)
