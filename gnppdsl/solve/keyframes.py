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


def render_solution(compiled: Any, result: Any, out_dir: str) -> list[str]:
    """Render the keyframes s_0 .. s_n of a solved result as PNG files; returns their paths."""
    from gnppdsl.geometry.render import render_keyframes

    plan = result.extras["plan"]
    states = world_states(compiled, plan.states, result.extras["values"])
    titles = [f"s{st.index}" + (f" <- {st.action}" if st.action else " (initial)") for st in result.steps]
    return render_keyframes(compiled.problem.scene, compiled.geometry, states, out_dir, titles=titles)
