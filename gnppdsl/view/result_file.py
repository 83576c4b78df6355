"""Reading a result JSON written by `gnpp solve --json` (docs/result.schema.json).

Why a module: `gnpp export` and `gnpp view` (and the Python API) read the same file and must
report a bad one the same way: a located message (file:line:col for broken JSON, the field for
a missing one), never a traceback.
"""
from __future__ import annotations

import json
from pathlib import Path
from typing import Any

from gnppdsl.errors import UserError

def load_result(path: str | Path) -> dict[str, Any]:
    """The result JSON as a dict; UserError if it is missing, not JSON or not a solved result
    with time stamps (written by a gnpp that predates them)."""
    p = Path(path)
    try:
        text = p.read_text()
    except FileNotFoundError:
        raise UserError(f"{path}: no such file") from None
    except OSError as exc:
        raise UserError(f"{path}: {exc.strerror or exc}") from None
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        line = text.splitlines()[exc.lineno - 1] if 0 < exc.lineno <= len(text.splitlines()) else ""
        raise UserError(f"{path}:{exc.lineno}:{exc.colno}: not JSON: {exc.msg}\n  {line}\n  "
                        f"{' ' * (exc.colno - 1)}^") from None
    if not isinstance(data, dict) or "steps" not in data or "status" not in data:
        raise UserError(f"{path}: not a result of `gnpp solve --json` (no `status` / `steps`)")
    if not data.get("solved"):
        raise UserError(f"{path}: {data.get('problem', 'the problem')} was not solved "
                        f"({data.get('status')}): there is no motion in it")
    missing = [k for k in ("robots", "coordinates", "inputs") if k not in data]
    missing += [f"steps[{i}].time" for i, s in enumerate(data["steps"]) if s.get("time") is None][:1]
    if missing:
        raise UserError(f"{path}: no `{missing[0]}`: the file was written by an older gnpp; "
                        "solve again with `gnpp solve PROBLEM --json FILE`")
    return data
