"""gnppdsl: a modelling language, compiler and conflict-driven solver for TAMP posed as PNTC.

Layers (data flows one way): lang -> ir -> compile -> solve (logic, nlp, conflicts) -> cli.
geometry sits under nlp; reach is R-LGP.
"""
import os as _os

# OpenBLAS (numpy's, and casadi's under ipopt's linear solver) starts a thread per core when it
# is loaded. The dense blocks of these NLPs are small, so the extra threads mostly wait, and
# OpenBLAS waits by spinning (sched_yield): measured on a 2-core machine during a Lab 5 run,
# 146 s of system time in that thread, the process's CPU time 1.5x its wall time; lab2 one
# thread: 4 % less CPU, the same wall time. One thread unless the user set it: this must run
# before numpy or casadi are first imported (it has no effect after).
_os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")

__version__ = "0.1.0"
