"""Output locations of the CLI: a file or directory a user names is created with its parents.

Why: `gnpp solve ... --json out/result.json` on a fresh clone used to stop with "directory out
does not exist"; the README's own commands must work there. A path that exists as the wrong
kind (a file where a directory is wanted) is a user error naming the option.
"""
from __future__ import annotations

from pathlib import Path

from gnppdsl.errors import UserError


def make_parent(option: str, path: str) -> Path:
    """Create the directory that will hold file `path` (given with `option`); return the path."""
    p = Path(path)
    make_dir(option, str(p.parent) if str(p.parent) else ".")
    if p.is_dir():
        raise UserError(f"{option} {path}: is a directory, expected a file name")
    return p


def make_dir(option: str, path: str) -> Path:
    """Create directory `path` (given with `option`) and its parents if missing."""
    p = Path(path)
    try:
        p.mkdir(parents=True, exist_ok=True)
    except FileExistsError:
        raise UserError(f"{option} {path}: exists and is not a directory") from None
    except OSError as exc:
        raise UserError(f"{option} {path}: cannot create directory: {exc.strerror or exc}") from None
    return p
