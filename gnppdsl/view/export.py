"""Joint trajectories of a solved result as CSV files a controller can read.

One file per robot, `<robot>.csv`: a header `time,<joint 1>,...,<joint n>` (the names of the
robot's planner coordinates: pinocchio joint names, `root_x`-style suffixes for multi-coordinate
joints, `x,y,theta` for planar grippers), then one row per sample, times strictly increasing,
in seconds from the start. Samples: the initial keyframe, then per phase s_i -> s_{i+1} every
trajectory waypoint after the first (its time from the result's `trajectory_times`) or, for a
phase without a trajectory, the next keyframe. A robot whose values a step lacks keeps its
last configuration. Numbers are written with `repr` so that reading them back gives the same
floats (the round trip is tested).
"""
from __future__ import annotations

import csv
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from gnppdsl.errors import UserError


@dataclass
class JointTrajectory:
    robot: str
    joints: list[str]
    times: list[float]
    positions: list[list[float]]      # one row per time, one column per joint


def joint_trajectories(result: dict[str, Any]) -> list[JointTrajectory]:
    """Per robot of a result JSON (annotated: `robots`, step `time`), its timed samples."""
    out = []
    steps = result["steps"]
    for robot, info in result.get("robots", {}).items():
        cfg, traj = info.get("configuration"), info.get("trajectory")
        times: list[float] = []
        rows: list[list[float]] = []

        def add(t: float, q: Any) -> None:
            if q is None:
                q = rows[-1] if rows else None
            if q is None:
                return
            if times and t <= times[-1]:
                return                   # a repeated sample (a zero-length phase)
            times.append(float(t))
            rows.append([float(x) for x in q])

        for i, st in enumerate(steps):
            if i == 0:
                add(st["time"], st["values"].get(cfg))
                continue
            prev = steps[i - 1]
            pts = prev["trajectories"].get(traj) if traj else None
            if pts:
                ts = prev["trajectory_times"][traj]
                for t, q in zip(ts[1:], pts[1:]):
                    add(t, q)
            else:
                add(st["time"], st["values"].get(cfg))
        if rows:
            out.append(JointTrajectory(robot, list(info["joints"]), times, rows))
    return out


def export_csv(result: dict[str, Any], directory: str | Path, overwrite: bool = False) -> list[Path]:
    """Write `<robot>.csv` for every robot of `result` into `directory` (created if missing);
    an existing file is kept unless `overwrite`. Returns the paths written."""
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    trajs = joint_trajectories(result)
    if not trajs:
        raise UserError(f"{result.get('problem', 'the result')}: no robot configurations to export")
    paths = [d / f"{t.robot}.csv" for t in trajs]
    existing = [p for p in paths if p.exists()]
    if existing and not overwrite:
        raise UserError(f"--csv {directory}: {existing[0]} exists (give --force to overwrite)")
    for t, p in zip(trajs, paths):
        tmp = p.with_name(p.name + ".tmp")
        with tmp.open("w", newline="") as f:
            w = csv.writer(f)
            w.writerow(["time", *t.joints])
            for time, q in zip(t.times, t.positions):
                w.writerow([repr(time), *map(repr, q)])
        tmp.replace(p)
    return paths


def read_csv(path: str | Path) -> JointTrajectory:
    """Read a file written by `export_csv` back (what a controller would do)."""
    p = Path(path)
    with p.open(newline="") as f:
        rows = list(csv.reader(f))
    header, body = rows[0], rows[1:]
    if not header or header[0] != "time":
        raise UserError(f"{path}:1: expected a header starting with `time`")
    return JointTrajectory(p.stem, header[1:], [float(r[0]) for r in body], [[float(x) for x in r[1:]] for r in body])
