"""The pre-built reachability graph kept across processes, per scene (paper 002, Sec. IV-B1:
the graph is built once for a scene and reused by every query).

Why: building the graph IK-validates every sample (Eq. 2), 1.1 s of sort2's 5.5 s CPU with
R-LGP, and every `gnpp solve` of a scene rebuilt the same graph. What is kept is exactly what
`ReachabilityGraph.build` draws before any query: the accepted nodes (x, q, c) in order, the
random generator's state after the draws and the build statistics. A graph restored from it
equals the one built (same nodes, same edges, same random stream afterwards, so the same
queries, plans and results); the lazy edge checks and enhancements of a run stay in that run,
so a solve's result never depends on what ran before it. The outcomes of the lazy edge checks
are kept beside it (`load_checks` / `save_checks`, `<key>.checks.json`): each is a function of
the two configurations and of what the key covers, so a stored answer is the one the check
would give (`ReachabilityGraph.check_edge`); at most MAX_CHECKS, the latest.

Key: everything the build reads, as a digest: the code version (`nlp.function_store`: package
sources, casadi, pinocchio, Python), the settings, the robot's URDF and SRDF contents, its
reduced pinocchio model, coordinates, base and home configuration, the obstacles (scene shape and
pose) and the collision filter. Stored as JSON (numbers only: nothing executes at load) in
`GNPP_REACH_CACHE` (`0` / `off`: no store), else `$XDG_CACHE_HOME/gnppdsl/reach`
(`~/.cache/...`; `outputs.cache_directory`), a directory that must be this user's own with mode 0700
(`outputs.private_dir`), as the template store's. A missing, unreadable or foreign file is a
miss: the graph is built and the file written again (atomically).
"""
from __future__ import annotations

import hashlib
import json
from pathlib import Path
from typing import Any

FORMAT = 2     # 2: edges turn angles the short way round (a format-1 store predates that)
MAX_CHECKS = 50_000     # edge-check outcomes kept per graph (~2 MB of JSON)


def default_directory() -> Path | None:
    """The store's directory (module docstring), or None when switched off."""
    from gnppdsl.outputs import cache_directory
    return cache_directory("GNPP_REACH_CACHE", "reach")


def graph_key(settings: Any, spec: Any, robot: Any, home: Any, obstacles: list, scene: Any,
              ignore: frozenset, fixed_base: bool) -> str | None:
    """The digest of what `ReachabilityGraph.build` depends on (module docstring); None when
    something has no value representation (then nothing is stored)."""
    import numpy as np

    from gnppdsl.inputs import file_digest
    from gnppdsl.nlp.function_store import code_version

    parts = [f"format {FORMAT}", code_version(), repr(settings), file_digest(spec.urdf), file_digest(spec.srdf),
             hashlib.sha256(robot.model.saveToString().encode()).hexdigest(), repr(robot.coords),
             np.asarray(robot.base, float).tobytes().hex(), repr(robot.ee),
             np.asarray(home, float).tobytes().hex(),
             np.asarray(robot.lower, float).tobytes().hex(), np.asarray(robot.upper, float).tobytes().hex(),
             repr(sorted(sorted(p) for p in ignore)), f"fixed_base={fixed_base}"]
    for o in obstacles:
        obj = scene.objects.get(o.name)
        parts.append(f"{o.name} {obj.shape!r} {np.asarray(o.T, float).tobytes().hex()}")
    text = "\n".join(parts)
    if " at 0x" in text:
        return None
    return hashlib.sha256(text.encode()).hexdigest()


def _path(key: str) -> Path | None:
    d = default_directory()
    if d is None:
        return None
    from gnppdsl.outputs import private_dir

    return None if private_dir(d) is None else d / f"{key}.json"


def load(key: str) -> dict | None:
    """The stored build of `key`, or None (no store, no file, unreadable, another key)."""
    path = _path(key)
    if path is None:
        return None
    try:
        data = json.loads(path.read_text())
    except (OSError, ValueError):
        return None
    if not isinstance(data, dict) or data.get("key") != key or data.get("format") != FORMAT:
        return None
    return data


def save(key: str, payload: dict) -> bool:
    """Store `payload` under `key`, atomically (`outputs.write_atomic`: a reader never sees half
    a record); False when there is no usable directory or it cannot be written."""
    path = _path(key)
    if path is None:
        return False
    from gnppdsl.errors import UserError
    from gnppdsl.outputs import write_atomic

    try:
        write_atomic(path, json.dumps({**payload, "format": FORMAT, "key": key}), "reachability store", mode=0o600)
    except UserError:
        return False
    return True


def load_checks(key: str) -> dict[str, bool]:
    """The stored edge-check outcomes of `key`'s graph (segment key -> free), {} when none."""
    data = load(f"{key}.checks")
    if data is None or not isinstance(data.get("checks"), dict):
        return {}
    return {str(k): bool(v) for k, v in data["checks"].items()}


def save_checks(key: str, checks: dict[str, bool]) -> bool:
    """Store `checks` (merged with what another process stored meanwhile; the latest
    MAX_CHECKS)."""
    merged = {**load_checks(key), **checks}
    if len(merged) > MAX_CHECKS:
        merged = dict(list(merged.items())[-MAX_CHECKS:])
    return save(f"{key}.checks", {"checks": {k: int(v) for k, v in merged.items()}})
