"""C code of one derivative kernel, the step the solve (`jit.KernelCache`: compile now) and
the background compiler (`jit_worker`: compile the queue) share.

Why a module of its own: the solve imports the worker's cache-file handling (`install_library`,
`prune`, `try_lock`) and the worker needs the solve's code generation, so the shared piece sits
below both and neither imports the other back. casadi is imported when code is generated, not
with the module: a worker that finds no job exits without loading it.
"""
from __future__ import annotations

import os
from pathlib import Path


def kernel_symbol(key: str) -> str:
    """The kernel's C name (an identifier: the key may start with a digit)."""
    return f"gnpp_{key}"


def generate_c(f, key: str, directory: Path) -> Path:
    """The casadi Function f as `<symbol>.c` in `directory` (one exported function named
    after the key)."""
    import casadi as ca

    sym = kernel_symbol(key)
    named = ca.Function(sym, f.sx_in(), f.call(f.sx_in()), f.name_in(), f.name_out())
    cg = ca.CodeGenerator(sym + ".c", {"with_header": False})
    cg.add(named)
    cg.generate(str(directory) + os.sep)
    return directory / (sym + ".c")
