"""Timings of the geometry layer (not a test: prints a table, asserts nothing about time).

    python benchmarks/bench_geometry.py

Moved here from the geometry tests (issue 25: timings live in benchmarks/, never in tests):
1. sdist box-mesh: build time of the casadi expression and its Jacobian, time per call of the
   casadi Function (value + Jacobian) and of the numeric coal query, on 300 new points.
2. Forward kinematics per robot model: build time of every frame's Function, time per call.
3. Panda IK (`solve_ik`, 5 restarts) on 20 reachable targets: median / max time, attempts.
Times are CPU time of this process (time.process_time).
"""
from __future__ import annotations

import sys
import tempfile
import time
from pathlib import Path

import casadi as ca
import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from gnppdsl.geometry.context import GeometryContext  # noqa: E402
from gnppdsl.geometry.ik import solve_ik  # noqa: E402
from gnppdsl.geometry.kinematics import fk_function, fk_rp_function  # noqa: E402
from gnppdsl.geometry.robots import load_robot  # noqa: E402
from gnppdsl.ir.scene_model import Scene, SceneObject, SceneRobot, SceneShape  # noqa: E402

I7 = (0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0)
clock = time.process_time


def bench_sdist(n: int = 300) -> None:
    import trimesh
    mesh = Path(tempfile.mkdtemp()) / "tetra.stl"
    trimesh.Trimesh(vertices=[[0, 0, 0], [0.2, 0, 0], [0, 0.15, 0], [0.02, 0.03, 0.1], [0.05, 0.05, 0.02]],
                    faces=[[0, 2, 1], [0, 1, 3], [1, 2, 3], [0, 3, 2]]).export(mesh)
    objs = [SceneObject("box", SceneShape("box", (0.3, 0.2, 0.1), None), I7),
            SceneObject("mesh", SceneShape("mesh", (1.0, 1.0, 1.0), str(mesh)), I7)]
    ctx = GeometryContext(Scene("t", 3, {}, {o.name: o for o in objs}))
    xa, xb = ca.SX.sym("a", 7), ca.SX.sym("b", 7)
    t0 = clock()
    d = ctx.sdist("box", xa, "mesh", xb)
    f = ca.Function("f", [xa, xb], [d, ca.jacobian(d, ca.vertcat(xa, xb))])
    t_build = clock() - t0
    pa, pb = np.r_[0, 0, 0, 0, 0, 0, 1], np.r_[0.3, 0.1, 0, 0, 0, 0, 1]
    shifts = [np.r_[0.001 * k, 0, 0, 0, 0, 0, 0] for k in range(n)]     # new points: no memo hits
    t0 = clock()
    for s in shifts:
        f(pa, pb + s)
    t_call = (clock() - t0) / n
    t0 = clock()
    for s in shifts:
        ctx.sdist_numeric("box", pa, "mesh", pb + s)
    t_num = (clock() - t0) / n
    print(f"sdist box-mesh: build {t_build * 1e3:.2f} ms, casadi value+jacobian {t_call * 1e6:.1f} us/call, "
          f"numeric coal {t_num * 1e6:.1f} us/call")


def bench_fk() -> None:
    specs = {"panda": SceneRobot("left", "urdf", model="panda", ee="panda_hand_tcp"),
             "ur5": SceneRobot("ur", "urdf", model="ur5", ee="ee_link"),
             "kinova": SceneRobot("kin", "urdf", model="kinova")}
    rng = np.random.default_rng(7)
    for key, spec in specs.items():
        robot = load_robot(spec)
        names = [f.name for f in robot.model.frames if f.name != "universe"]
        t0 = clock()
        funcs = [(fk_rp_function(robot, n), fk_function(robot, n)) for n in names]
        t_build = clock() - t0
        base = np.array(I7)
        coords = [robot.random_coords(rng) for _ in range(20)]
        t0 = clock()
        for c in coords:
            for f_rp, f_vec in funcs:
                f_rp(c, base)
                f_vec(c, base)
        t_eval = (clock() - t0) / (2 * len(coords) * len(funcs))
        print(f"fk {key}: frames {len(names)}, nc {robot.nc}, build {t_build * 1e3:.1f} ms, "
              f"eval {t_eval * 1e6:.1f} us/call")


def bench_ik(n: int = 20) -> None:
    import pinocchio as pin
    robot = load_robot(SceneRobot("ikpanda", "urdf", model="panda", ee="panda_hand_tcp",
                                  base=(0.1, 0.2, 0.0, 0.0, 0.0, 0.0, 1.0)))
    rng = np.random.default_rng(0)
    data = robot.model.createData()
    fid = robot.model.getFrameId("panda_hand_tcp")
    times, attempts, solved = [], [], 0
    for i in range(n):
        pin.framesForwardKinematics(robot.model, data, robot.to_pin_q(robot.random_coords(rng)))
        T = robot.base @ np.array(data.oMf[fid].homogeneous)
        t0 = clock()
        res = solve_ik(robot, T, restarts=5, seed=i)
        times.append(clock() - t0)
        if res is not None:
            solved += 1
            attempts.append(res.attempts)
    print(f"ik panda: solved {solved}/{n}, median {np.median(times) * 1e3:.1f} ms, max {max(times) * 1e3:.1f} ms, "
          f"mean attempts {np.mean(attempts):.2f}")


if __name__ == "__main__":
    bench_sdist()
    bench_fk()
    bench_ik()
