"""gnpp's NLP engine side by side with rai's KOMO (issue 20, deliverable 5).

One Panda on the Lab table (examples/lab/lab.yaml: table, left arm's base, block size, pad)
picks a block and puts it on a pad: the two keyframes (grasp, placement) in one NLP, then the
two 20-step motions between them, each in its own NLP with the keyframes fixed. Per seed the
start configuration (home joints + U(-0.1, 0.1) rad) and the block's position on the table
(+ U(-0.03, 0.03) m in x and y) are perturbed, the same on both sides. CPU time
(`time.process_time`), alternating gnpp and KOMO seed by seed in one run:

- keyframe NLP: gnpp: the mode-switch graph-NLP of the plan `pick(b, arm, table),
  put(b, arm, pad)` (every factor at the keyframes, from the factory's start; assembly
  included); KOMO: `KOMO_ManipulationHelper.setup_pick_and_place_waypoints` + `grasp_box` +
  `place_box` (the rai tutorial's pick-and-place), problem set-up included;
- path NLP: each motion between the fixed keyframes (20 waypoints; gnpp: the phase NLP of the
  solve loop, always given to the solver, even when its straight-line start already holds (the
  first motion's does within 1e-8 on 11 of seeds 0-11: the solver then returns that start without
  running ipopt, `IterationMonitor.start_holds`; the second's misses by 2e-5 to 6e-4); KOMO: a 20-step
  `KOMO` with collisions, joint limits, acceleration costs and the keyframe as target, the
  block attached to the gripper for the second motion);
- end to end: a fresh process from start to solution (`gnpp solve` on the same problem, which
  also searches the plan; KOMO: a process that imports `robotic`, builds the configuration
  and solves keyframes and both motions), CPU of the child process (`RUSAGE_CHILDREN`).

Same geometry on both sides for the scene (table, block, pad, the arm's base pose and start
joints); each side uses its own Panda collision model (gnpp: the example-robot-data URDF's
convex link hulls, KOMO: rai's capsules) and its own feasibility test (gnpp: every row within
1e-6; KOMO: its solver's `feasible` flag, whose equality residual is printed: it accepts
sums up to ~1e-3). Warm process: one unmeasured solve of each kind first on both sides (gnpp
builds its template Functions there; the later seeds share them, as one process solving
several problems does).

KOMO is PyPI `robotic` (0.4.2; `pip install gnppdsl[bench-komo]`, and on Debian `apt-get
install liblapack3 libglut3.12`). Without it the script prints so and exits 0. rai writes
`z.log.global` into the working directory: KOMO runs in a scratch directory.
`KOMO.initWithWaypoints` (and so the helper's `sub_motion`) segfaults in 0.4.2; the motions are
initialised with `initWithPath` (the same straight line gnpp starts from).
`--against`: the worker-process side measured ~5 % faster than this process's in an A/A run
(the same tree on both sides, 12 seeds: keyframe ratio 1.05, path 1.04); read ratios near 1
with that in mind.

    python benchmarks/bench_komo.py [--seeds 20] [--no-e2e] [--only gnpp|komo] [--unshared]
        [--against DIR]   # DIR: another gnppdsl tree, e.g. `git archive main | tar -x -C DIR`
        [--kinematic-curvature auto|true|false]   # this tree's Hessian model of FK rows
        [--no-kinematic-curvature]   # = --kinematic-curvature false
"""
from __future__ import annotations

import argparse
import json
import os
import resource
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np
import yaml

ROOT = Path(__file__).resolve().parents[1]
LAB = ROOT / "examples" / "lab"
HOME = np.array([0, -0.5, 0, -2.0, 0, 1.6, 0.8])
BLOCK = (-0.2, 0.2, 0.645)            # examples/lab/lab.yaml: b1
PAD = (0.0, 0.2, 0.6005)              # pad_c
BASE = (-0.4, -0.3, 0.6)              # left_arm, rotated 90 deg about z
PROBLEM = """problem pick_place for lab
scene "scene.yaml"
objects { arm : arm  b : block  pad : pad }
init { parent(b) = table  holding(arm) = none }
goal { parent(b) = pad }
"""
PLAN = "pick(b, arm, table), put(b, arm, pad)"


def perturbation(seed: int) -> tuple[np.ndarray, tuple[float, float]]:
    """Start joints and block (x, y) of one seed (the same on both sides)."""
    rng = np.random.default_rng(seed)
    q0 = HOME + rng.uniform(-0.1, 0.1, 7)
    dx, dy = rng.uniform(-0.03, 0.03, 2)
    return q0, (BLOCK[0] + dx, BLOCK[1] + dy)


def write_problem(directory: Path, seed: int) -> Path:
    """The pick-and-place problem of one seed for gnpp: the Lab scene with one arm."""
    lab = yaml.safe_load((LAB / "lab.yaml").read_text())
    setting = yaml.safe_load((LAB / lab["include"]).read_text())    # robots, table, pads
    q0, (bx, by) = perturbation(seed)
    arm = dict(setting["robots"]["left_arm"], home=[float(x) for x in q0])
    objs = {**setting["objects"], **lab["objects"]}
    scene = {"name": "pick_place", "dimension": 3, "workspace": setting["workspace"],
             "robots": {"arm": arm},
             "objects": {"table": objs["table"], "pad": objs["pad_c"],
                         "b": dict(objs["b1"], pose={"xyz": [float(bx), float(by), BLOCK[2]]})},
             "ignore_collisions": [["pad", "table"]]}
    directory.mkdir(parents=True, exist_ok=True)
    (directory / "scene.yaml").write_text(yaml.safe_dump(scene))
    path = directory / "pick_place.pntc"
    path.write_text(PROBLEM)
    return path


# ---------------------------------------------------------------------------------------------
# gnpp
# ---------------------------------------------------------------------------------------------
class Gnpp:
    """The keyframe NLP and the two path NLPs of the plan, as the solve loop builds them."""

    def __init__(self, solver_options: dict | None = None, jit: str = "off") -> None:
        self.jit = jit                         # gnppdsl.nlp.jit mode of the template compiler
        self.compilers: dict | None = None     # template Functions shared across seeds
        self.solver_options = dict(solver_options or {})   # SolverOptions fields to override

    def solve(self, problem: Path, seed: int) -> dict:
        from gnppdsl.compile.semantics import parse_plan, plan_states
        from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions
        from gnppdsl import load_and_compile
        from gnppdsl.solve.interpolation import interpolate_trajectories
        from gnppdsl.solve.motions import GraphNLPView, _fixed
        from gnppdsl.solve.plan_graph import plan_graph

        c = load_and_compile([str(LAB / "domain.pntc"), str(problem)])
        if self.compilers is None:
            self.compilers = c.compilers
        else:
            # same templates, shapes and robot model: only poses (lifted parameters) differ
            c.compilers = self.compilers
        compiler = c.body_compiler(self.jit)
        s = c.problem.settings

        # the Hessian model of the domain's solver block, as `gnpp solve` runs it (a tree that
        # does not know a setting keeps its SolverOptions default)
        curvature = {k: getattr(s, k) for k in ("distance_curvature", "kinematic_curvature")
                     if s is not None and hasattr(s, k) and k in SolverOptions.__dataclass_fields__}

        def solver() -> FeasibilitySolver:
            kw = {"tolerance": s.tolerance if s and s.tolerance else 1e-6, "restarts": 0,
                  **curvature, **self.solver_options}
            opts = SolverOptions(**kw)
            return FeasibilitySolver(c.geometry, opts, compiler=compiler)

        g = plan_graph(c.factory, plan_states(c.task, parse_plan(c.task, PLAN)))
        modes = g.subgraph(variables=[v for v in g.variables if not v.waypoints], suffix="{modes}")
        t0 = time.process_time()
        r = solver().solve(modes, seed=seed)
        out = {"keyframe": time.process_time() - t0, "keyframe_ok": r.feasible,
               "keyframe_res": r.max_violation, "path": [], "path_ok": [], "path_res": []}
        if not r.feasible:
            return out
        keyframes = dict(r.values)
        trajs = [v for v in g.variables if v.waypoints]
        for i in sorted({v.step for v in trajs}):
            sl = g.time_slice(i, i + 1)
            sl = sl.subgraph(variables=[v for v in sl.variables if not (v.waypoints and v.step != i)],
                             suffix=f"{{motion {i}}}")
            frozen = {v: _fixed(v, keyframes[v]) for v in sl.variables if not v.waypoints}
            start = interpolate_trajectories([v for v in sl.variables if v.waypoints], keyframes)
            t0 = time.process_time()
            rp = solver().solve(GraphNLPView.with_variables(sl, frozen),
                                warm_start={**keyframes, **start}, seed=seed)
            out["path"].append(time.process_time() - t0)
            out["path_ok"].append(rp.feasible)
            out["path_res"].append(rp.max_violation)
        return out


class GnppWorker:
    """`Gnpp` in a child process whose gnppdsl is another source tree (`--against DIR`: e.g. main
    before a change, `git archive main | tar -x -C DIR`), so that two versions of the engine run
    side by side in one run, alternating seed by seed. The child measures its own CPU time per
    NLP exactly as `Gnpp` does here (it runs this file's `Gnpp`, importing gnppdsl from DIR)."""

    def __init__(self, tree: Path) -> None:
        env = dict(os.environ, PYTHONPATH=str(tree))
        self.proc = subprocess.Popen([sys.executable, str(Path(__file__).resolve()), "--worker"],
                                     stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, env=env)

    def solve(self, problem: Path, seed: int) -> dict:
        self.proc.stdin.write(json.dumps([str(problem), seed]) + "\n")
        self.proc.stdin.flush()
        line = self.proc.stdout.readline()
        if not line:
            raise RuntimeError("bench_komo: the --against worker died")
        return json.loads(line)

    def close(self) -> None:
        self.proc.stdin.close()
        self.proc.wait()


def worker_main() -> int:
    """The `--worker` loop: one [problem, seed] JSON line in, `Gnpp.solve`'s dict out."""
    import gnppdsl
    sys.stderr.write(f"bench_komo worker: gnppdsl from {Path(gnppdsl.__file__).parents[1]}\n")
    g = Gnpp()
    for line in sys.stdin:
        path, seed = json.loads(line)
        r = g.solve(Path(path), seed)
        print(json.dumps({k: (bool(v) if isinstance(v, np.bool_) else v) for k, v in r.items()},
                         default=lambda x: x.item() if hasattr(x, "item") else str(x)), flush=True)
    return 0


# ---------------------------------------------------------------------------------------------
# KOMO (rai)
# ---------------------------------------------------------------------------------------------
def komo_config(ry, seed: int):
    """The same scene in rai: table, Panda (base a child of the table, as in rai's
    pandaSingle.g, so that the base's capsule is not a collision with the table), pad, block.
    Boxes get a 1 mm corner radius (rai's FCL interface rejects radius 0)."""
    q0, (bx, by) = perturbation(seed)
    C = ry.Config()
    table = C.addFrame("table").setShape(ry.ST.ssBox, [2.3, 1.24, 0.05, 0.001]).setPosition([0, 0, 0.575])
    table.setContact(1)
    C.addFile(ry.raiPath("scenarios/panda_fixGripper.g"), "l_")
    base = C.getFrame("l_panda_base")
    base.setParent(table, False, False)
    base.setRelativePosition([BASE[0], BASE[1], BASE[2] - 0.575])
    base.setRelativeQuaternion([np.cos(np.pi / 4), 0, 0, np.sin(np.pi / 4)])
    C.addFrame("pad").setShape(ry.ST.ssBox, [0.08, 0.16, 0.001, 0.0]).setPosition(list(PAD))
    C.addFrame("b").setShape(ry.ST.ssBox, [0.06, 0.15, 0.09, 0.001]).setPosition([bx, by, BLOCK[2]]).setContact(1)
    C.setJointState(q0)
    return C


def _komo_solve(ry, nlp):
    sol = ry.NLP_Solver()
    sol.setProblem(nlp)
    # the options of KOMO_ManipulationHelper.solve
    sol.setOptions(damping=1e-1, verbose=0, stopTolerance=1e-3, lambdaMax=100., stopInners=20, stopEvals=200)
    return sol.solve()


def komo_motion(ry, C, qa, qb):
    """One 20-step motion qa -> qb (KOMO_ManipulationHelper.setup_motion's objectives)."""
    K = ry.KOMO(C, 1.0, 20, 2, True)
    K.addControlObjective([], 2, 1e-1)
    K.addObjective([], ry.FS.accumulatedCollisions, [], ry.OT.eq, [1e0])
    K.addObjective([], ry.FS.jointLimits, [], ry.OT.ineq, [1e0])
    K.addObjective([1.0], ry.FS.qItself, [], ry.OT.eq, [1e1], qb)
    K.addObjective([1.0], ry.FS.qItself, [], ry.OT.eq, [1e0], [], 1)
    K.initWithPath(np.linspace(qa, qb, 21)[1:])
    return _komo_solve(ry, K.nlp()), K


def komo_solve(ry, seed: int) -> dict:
    C = komo_config(ry, seed)
    t0 = time.process_time()
    M = ry.KOMO_ManipulationHelper()
    M.setup_pick_and_place_waypoints(C, "l_gripper", "b", homing_scale=1e-2, velocity_scale=1e-1,
                                     accumulated_collisions=True)
    M.grasp_box(1.0, "l_gripper", "b", "l_palm", "x")
    M.place_box(2.0, "b", "pad", "l_palm")
    ret = _komo_solve(ry, M.komo.nlp())
    out = {"keyframe": time.process_time() - t0, "keyframe_ok": bool(ret.feasible),
           "keyframe_res": float(ret.eq), "path": [], "path_ok": [], "path_res": []}
    if not ret.feasible:
        return out
    kf = M.komo.getPath()
    q0 = C.getJointState()
    for phase in range(2):
        t0 = time.process_time()
        if phase == 0:
            r, _ = komo_motion(ry, C, q0, kf[0])
        else:
            C2 = ry.Config()
            C2.addConfigurationCopy(C)
            C2.setJointState(kf[0])
            C2.attach("l_gripper", "b")
            r, _ = komo_motion(ry, C2, kf[0], kf[1])
        out["path"].append(time.process_time() - t0)
        out["path_ok"].append(bool(r.feasible))
        out["path_res"].append(float(r.eq))
    return out


def komo_main(seed: int) -> int:
    """The KOMO end-to-end process: import, build, keyframes, both motions; prints the verdict
    (run in the scratch directory, like the parent)."""
    import robotic as ry
    r = komo_solve(ry, seed)
    print(json.dumps({"solved": r["keyframe_ok"] and len(r["path_ok"]) == 2 and all(r["path_ok"])}))
    return 0


# ---------------------------------------------------------------------------------------------
# the run
# ---------------------------------------------------------------------------------------------
def child_cpu(cmd: list[str], cwd: Path, env: dict | None = None) -> tuple[float, str]:
    """CPU seconds (user + system) of one child process from start to exit, and its stdout."""
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    p = subprocess.run(cmd, cwd=cwd, capture_output=True, text=True, env=env)
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    cpu = (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime)
    return cpu, p.stdout


def _med(xs: list[float]) -> float:
    return statistics.median(xs) if xs else float("nan")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--no-e2e", action="store_true", help="skip the end-to-end subprocesses")
    ap.add_argument("--only", choices=["gnpp", "komo"], default=None)
    ap.add_argument("--unshared", action="store_true",
                    help="also gnpp with every NLP assembled anew (SolverOptions.shared_assembly "
                         "off: the engine before nlp/shape_cache.py), alternating with the others")
    ap.add_argument("--against", type=Path, default=None, metavar="DIR",
                    help="also gnpp from the gnppdsl source tree DIR (e.g. main before a change), "
                         "NLPs in a worker process and end to end, alternating with this tree")
    ap.add_argument("--kinematic-curvature", default=None, metavar="auto|true|false",
                    type=lambda t: {"auto": "auto", "true": True, "false": False}[t.lower()],
                    help="this tree's gnpp with SolverOptions.kinematic_curvature set so (false: the "
                         "forward-kinematics rows linearised in ipopt's Hessian; auto: linearised "
                         "first, exact where that fails; `gnpp solve --kinematic-curvature MODE`); "
                         "--against and --unshared keep the domain's")
    ap.add_argument("--no-kinematic-curvature", dest="kinematic_curvature", action="store_const",
                    const=False, help="= --kinematic-curvature false")
    ap.add_argument("--komo-process", type=int, default=None, help=argparse.SUPPRESS)
    ap.add_argument("--worker", action="store_true", help=argparse.SUPPRESS)
    args = ap.parse_args(argv)
    if args.komo_process is not None:
        return komo_main(args.komo_process)
    if args.worker:
        return worker_main()
    scratch = Path(tempfile.mkdtemp(prefix="bench_komo_"))
    cwd = os.getcwd()
    os.chdir(scratch)                      # rai writes z.log.global into the working directory
    try:
        import robotic as ry
    except ImportError as e:
        ry = None
        if args.only != "gnpp":
            os.chdir(cwd)
            print(f"bench_komo: rai/KOMO is not installed ({e}); `pip install robotic` "
                  "(and apt-get install liblapack3 libglut3.12). Nothing measured.")
            return 0
    sides = [s for s in ("gnpp", "komo") if args.only in (None, s)]
    if args.unshared and "gnpp" in sides:
        sides.insert(1, "gnpp-unshared")
    if args.against is not None and "gnpp" in sides:
        sides.insert(1, "gnpp-against")
    import importlib.util

    from gnppdsl.geometry import native
    src = ROOT / "gnppdsl" / "solve" / "loop.py"
    pyc = Path(importlib.util.cache_from_source(str(src)))
    fresh = pyc.is_file() and pyc.stat().st_mtime >= src.stat().st_mtime
    print(f"bench_komo: {args.seeds} seeds, CPU time, distances: {native.describe()}, template "
          f"Functions built in the unmeasured warm-up; gnppdsl bytecode "
          f"{'cached' if fresh else 'NOT cached (each gnpp process compiles its sources: make setup)'}")
    env = dict(os.environ, PYTHONPATH=str(ROOT) + os.pathsep + os.environ.get("PYTHONPATH", ""))
    mode = args.kinematic_curvature
    if mode is not None:
        print(f"gnpp (this tree): kinematic_curvature {str(mode).lower()}")
    try:
        mine = {} if mode is None else {"kinematic_curvature": mode}
        engines = {"gnpp": Gnpp(mine), "gnpp-unshared": Gnpp({"shared_assembly": False})}
        if "gnpp-against" in sides:
            engines["gnpp-against"] = GnppWorker(args.against.resolve())
            print(f"gnpp-against: gnppdsl from {args.against.resolve()}")
        rows: dict[str, list[dict]] = {s: [] for s in sides}
        warm = {"gnpp": lambda: engines["gnpp"].solve(write_problem(scratch / "warm", 1000), 1000),
                "gnpp-against": lambda: engines["gnpp-against"].solve(write_problem(scratch / "warm", 1000), 1000),
                "gnpp-unshared": lambda: engines["gnpp-unshared"].solve(write_problem(scratch / "warm", 1000), 1000),
                "komo": lambda: komo_solve(ry, 1000)}
        def end_to_end(s: str, problem: Path, seed: int, r: dict) -> None:
            if s.startswith("gnpp"):
                cmd = [sys.executable, "-m", "gnppdsl.cli.main", "solve", str(LAB / "domain.pntc"),
                       str(problem), "--quiet", "--no-jit", "--json", str(problem.parent / "out.json")]
                if s == "gnpp" and mode is not None:
                    cmd.append(f"--kinematic-curvature={str(mode).lower()}")
                tree = args.against.resolve() if s == "gnpp-against" else ROOT
                r["e2e"], _ = child_cpu(cmd, scratch, dict(env, PYTHONPATH=str(tree)))
                res = json.loads((problem.parent / "out.json").read_text())
                r["e2e_ok"] = bool(res.get("solved"))
                r["e2e_solve"] = float(res.get("stats", {}).get("cpu_time", float("nan")))
            else:
                cmd = [sys.executable, str(Path(__file__).resolve()), "--komo-process", str(seed)]
                r["e2e"], outp = child_cpu(cmd, scratch, env)
                r["e2e_ok"] = '"solved": true' in outp

        for s in sides:
            warm[s]()
            if not args.no_e2e and s != "gnpp-unshared":                # file system caches, as for every later process
                end_to_end(s, write_problem(scratch / "warm", 1000), 1000, {})
        for seed in range(args.seeds):
            problem = write_problem(scratch / f"s{seed}", seed)
            for s in sides:
                r = engines[s].solve(problem, seed) if s in engines else komo_solve(ry, seed)
                if not args.no_e2e and s != "gnpp-unshared":     # gnpp solve's own default
                    end_to_end(s, problem, seed, r)
                rows[s].append(r)
            line = "  ".join(f"{s}: kf {rows[s][-1]['keyframe'] * 1e3:6.1f} ms "
                             f"paths {sum(rows[s][-1]['path']) * 1e3:6.1f} ms"
                             + (f" e2e {rows[s][-1]['e2e']:.2f} s" if "e2e" in rows[s][-1] else "")
                             for s in sides)
            print(f"seed {seed:2d}  {line}", flush=True)
    finally:
        os.chdir(cwd)
    print()
    print(f"{'':14s}" + "".join(f"{s:>30s}" for s in sides))

    def row(name: str, get, fmt: str) -> None:
        cells = []
        for s in sides:
            xs = [x for r in rows[s] for x in get(r)]
            cells.append(fmt.format(_med(xs) * 1e3 if fmt.endswith("ms") else _med(xs)))
        print(f"{name:14s}" + "".join(f"{c:>30s}" for c in cells))

    row("keyframe NLP", lambda r: [r["keyframe"]], "median {:.1f} ms")
    row("path NLP", lambda r: r["path"], "median {:.1f} ms")
    row("both paths", lambda r: [sum(r["path"])] if len(r["path"]) == 2 else [], "median {:.1f} ms")
    if not args.no_e2e:
        row("end to end", lambda r: [r["e2e"]] if "e2e" in r else [], "median {:.2f} s CPU")
        for s in ("gnpp", "gnpp-against"):
            if s in sides:
                over = [r["e2e"] - r["e2e_solve"] for r in rows[s]]
                print(f"{s + ' overhead':14s}  process CPU beyond the solve's cpu_time: "
                      f"median {_med(over):.2f} s")
    for s in sides:
        rs = rows[s]
        kf = sum(r["keyframe_ok"] for r in rs)
        paths = sum(len(r["path_ok"]) == 2 and all(r["path_ok"]) for r in rs)
        e2e = sum(r.get("e2e_ok", False) for r in rs)
        res = [r["keyframe_res"] for r in rs] + [x for r in rs for x in r["path_res"]]
        print(f"{s}: feasible keyframes {kf}/{len(rs)}, both paths {paths}/{len(rs)}"
              + ("" if args.no_e2e or s == "gnpp-unshared" else f", end to end solved {e2e}/{len(rs)}")
              + f"; residual (gnpp: max violation, KOMO: eq sum) median {_med(res):.1e}, max {max(res):.1e}")
    if "gnpp-unshared" in sides:
        for name, get in (("keyframe", lambda r: [r["keyframe"]]), ("path", lambda r: r["path"])):
            a = _med([x for r in rows["gnpp"] for x in get(r)])
            b = _med([x for r in rows["gnpp-unshared"] for x in get(r)])
            print(f"ratio gnpp/gnpp-unshared {name} NLP: {a / b:.2f}")
    if "gnpp-against" in sides:
        engines["gnpp-against"].close()
        for name, get in (("keyframe", lambda r: [r["keyframe"]]), ("path", lambda r: r["path"]),
                          ("end to end", lambda r: [r["e2e"]] if "e2e" in r else [])):
            a = _med([x for r in rows["gnpp"] for x in get(r)])
            b = _med([x for r in rows["gnpp-against"] for x in get(r)])
            print(f"ratio gnpp/gnpp-against {name}: {a / b:.2f}")
    if "gnpp" in sides and "komo" in sides:
        for name, get in (("keyframe", lambda r: [r["keyframe"]]), ("path", lambda r: r["path"])):
            a = _med([x for r in rows["gnpp"] for x in get(r)])
            b = _med([x for r in rows["komo"] for x in get(r)])
            print(f"ratio gnpp/KOMO {name} NLP: {a / b:.2f}")
        if not args.no_e2e:
            a, b = _med([r["e2e"] for r in rows["gnpp"]]), _med([r["e2e"] for r in rows["komo"]])
            print(f"ratio gnpp/KOMO end to end: {a / b:.2f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
