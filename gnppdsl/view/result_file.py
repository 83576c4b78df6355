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
    bad = _misshapen(data)
    if bad:
        raise UserError(f"{path}: `{bad}` is not as docs/result.schema.json describes it "
                        "(an edited or truncated file?); solve again with `gnpp solve PROBLEM --json FILE`")
    return data


def _misshapen(data: dict[str, Any]) -> str | None:
    """The first field the viewer and the export read whose shape is not the schema's: the
    plan's actions and each learned conflict (text, source, named partial states, factors).
    Why by hand: jsonschema is a test dependency only, and these are the fields read below
    `load_result` without further checks."""
    plan = data.get("plan")
    if not isinstance(plan, list) or not all(isinstance(a, str) for a in plan):
        return "plan"
    conflicts = data.get("conflicts", [])
    if not isinstance(conflicts, list):
        return "conflicts"
    for k, c in enumerate(conflicts):
        where = f"conflicts[{k}]"
        if not isinstance(c, dict) or not isinstance(c.get("text"), str) or not isinstance(c.get("source"), str):
            return where
        named = c.get("named", [])
        if not isinstance(named, list) or not all(
                isinstance(st, list) and all(isinstance(f, list) and len(f) == 2 for f in st) for st in named):
            return f"{where}.named"
        factors = c.get("factors", [])
        if not isinstance(factors, list) or not all(isinstance(f, str) for f in factors):
            return f"{where}.factors"
    return None
