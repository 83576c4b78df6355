"""World poses of the scene's entities at every step of a solution (for `gnpp solve --render`).

Why here: the renderer (`gnppdsl.geometry.render.render_keyframes`) wants, per step, a dict
entity -> world pose (objects, planar robots) or joint coordinates (URDF robots). World poses
follow the kinematic chain of each symbolic state, which only the graph-NLP factory knows how
to expand (`world(o)` along `frame` declarations). We ask the factory to expand `world(o)` at
step i (`GraphNLPFactory.world_pose_expr`) into a resolved expression over continuous variables
and evaluate it with the independent numpy interpreter of the nlp layer.
"""
from __future__ import annotations

from typing import Any, Sequence

import numpy as np

from gnppdsl.ir.expr import CVar


def world_states(compiled: Any, states: Sequence[Sequence[int]], values: dict) -> list[dict[str, Any]]:
    """[{entity: world pose or joint coordinates}] for s_0 .. s_n."""
    from gnppdsl.solve.timing import world_poses

    problem = compiled.problem
    scene = problem.scene
    by_key_step = {(v.key, v.step): v for v in values}

    def value_of(key: str, step: int):
        v = by_key_step.get((key, step))
        return None if v is None else values[v]

    out: list[dict[str, Any]] = []
    for i in range(len(states)):
        st: dict[str, Any] = dict(world_poses(compiled, states, i, value_of))
        for robot, spec in (scene.robots.items() if scene is not None else ()):
            if spec.kind == "urdf" and robot in problem.objects:
                q = _robot_coords(problem.domain.frame_of(problem.objects[robot]), robot, i, by_key_step, values)
                if q is not None:
                    st[robot] = q
        out.append(st)
    return out


def _robot_coords(frame: Any, robot: str, step: int, by_key_step: dict, values: dict) -> np.ndarray | None:
    """The joint coordinates of a URDF robot: the continuous variable its `fk` frame reads."""
    if frame is None:
        return None
    stack = [frame.expr]
    while stack:
        e = stack.pop()
        if isinstance(e, CVar):
            key = f"{e.name}({robot})"
            v = by_key_step.get((key, step))
            if v is not None:
                return np.asarray(values[v], float).reshape(-1)
        for name in ("args", "items"):
            stack.extend(getattr(e, name, ()) or ())
    return None


def render_solution(compiled: Any, result: Any, out_dir: str, gif: bool = True) -> list[str]:
    """Render the keyframes s_0 .. s_n of a solved result as PNG files (each with the motion
    that led to it: waypoints of the trajectories, or the interpolated keyframe motion of
    planar domains) and, with `gif`, the whole plan as `plan.gif`; returns the paths."""
    from gnppdsl.geometry.render import render_animation, render_keyframes
    from gnppdsl.solve.timing import motion_samples, world_poses

    plan = result.extras["plan"]
    problem = compiled.problem
    states = world_states(compiled, plan.states, result.extras["values"])
    data = result.to_json()
    by = {(k, i): np.asarray(v, float) for i, st in enumerate(data["steps"]) for k, v in st["values"].items()}
    urdf = {info["configuration"]: r for r, info in data.get("robots", {}).items()
            if "configuration" in info and problem.scene.robots.get(r) is not None
            and problem.scene.robots[r].kind == "urdf"}
    motions: list[list[dict[str, Any]]] = [[] for _ in states]
    frames, durations, frame_titles = [], [], []
    samples = motion_samples(data["steps"], data.get("robots", {}))
    titles = [f"s{st.index}" + (f" <- {st.action}" if st.action else " (initial)") for st in result.steps]
    for k, (t, i, over) in enumerate(samples):
        if not over:
            st = states[i]
        else:
            def value_of(key: str, step: int, i=i, over=over):
                return over[key] if step == i and key in over else by.get((key, step))
            st = dict(world_poses(compiled, plan.states, i, value_of))
            st.update({r: value_of(key, i) for key, r in urdf.items() if value_of(key, i) is not None})
            motions[i + 1].append(st)
        frames.append(st)
        durations.append((samples[k + 1][0] - t) if k + 1 < len(samples) else 1.0)
        frame_titles.append(titles[min(i + (1 if over else 0), len(titles) - 1)] + f"   t = {t:.2f} s")
    entities = frozenset(problem.objects)
    paths = render_keyframes(problem.scene, compiled.geometry, states, out_dir, titles=titles,
                             entities=entities, motions=motions)
    if gif:
        import os
        paths.append(render_animation(problem.scene, compiled.geometry, frames, os.path.join(out_dir, "plan.gif"),
                                      durations=durations, titles=frame_titles, entities=entities))
    return paths
