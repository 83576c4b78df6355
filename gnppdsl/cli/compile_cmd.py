"""`gnpp compile PROBLEM --emit sas|pddl|asp|factors [-o DIR]`: show what the compiler makes.

Compile a problem and write one of:

- `sas`      the grounded SAS+ task as Fast Downward `.sas` text (`PROBLEM.sas`);
- `pddl`     the domain and problem as lifted PDDL (`domain.pddl` + `PROBLEM.pddl`: types,
             parameterised actions, derived predicates when the domain has them;
             `--inline-derived` substitutes them, for readers without derived predicates such
             as Unified Planning); with `--conflicts` the reformulated task, ground;
- `pddl-ground` the grounded SAS+ task as PDDL (one action per operator);
- `asp`      the clingo program of the logic planner (`PROBLEM.lp`, runs with `clingo FILE`);
- `factors`  the graph-NLP of a plan: variables and factor instances with their generating
             partial states (`PROBLEM.factors.txt`); `--plan` gives the actions (default: the
             initial state only, i.e. the factors of s_0).
`--conflicts FILE` first applies the Appendix-B reformulation for every conflict in FILE, so
the emitted task forbids them. Without `-o` a single output goes to stdout.
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

EPILOG = """examples:
  gnpp compile examples/planar/p1_one_block.pntc --emit sas
  gnpp compile examples/planar/p1_one_block.pntc --emit pddl -o out/
  gnpp compile examples/lab/lab3.pntc --emit pddl --inline-derived
  gnpp compile examples/planar/p3_occupied.pntc --emit factors --plan "pick(b1, g, s1); place(b1, g, target)"
  gnpp compile examples/planar/p3_occupied.pntc --emit sas --conflicts conflicts.txt
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.description = __doc__.split("\n", 1)[1].strip() if __doc__ else None
    parser.epilog = EPILOG
    parser.add_argument("paths", nargs="+", metavar="PROBLEM",
                        help="the problem file (.pntc); a domain file may be given before it")
    parser.add_argument("--emit", choices=("sas", "pddl", "pddl-ground", "asp", "factors"), default="sas",
                        help="what to write (default: sas)")
    parser.add_argument("--inline-derived", action="store_true",
                        help="--emit pddl: substitute derived predicates into the formulas that use them")
    parser.add_argument("-o", "--output", metavar="DIR", default=None,
                        help="write the file(s) into DIR (created if needed) instead of stdout")
    parser.add_argument("--plan", metavar="PLAN|FILE", default=None,
                        help="for --emit factors: actions applied from s_0, e.g. "
                             "\"pick(b1, g, s1); place(b1, g, right)\", or a file with one action "
                             "per line (Fast Downward plan files work too)")
    parser.add_argument("--conflicts", metavar="FILE", default=None,
                        help="forbid the conflicts in FILE (one <{..}, {..}> sequence of partial "
                             "states per line) before emitting sas, pddl or asp")


def run(args: argparse.Namespace) -> int:
    from gnppdsl.errors import UserError

    if args.inline_derived and args.emit != "pddl":
        raise UserError("--inline-derived only applies to --emit pddl")
    if args.plan is not None and args.emit != "factors":
        raise UserError("--plan only applies to --emit factors")
    if args.conflicts is not None and args.emit == "factors":
        raise UserError("--conflicts applies to --emit sas, pddl or asp, not factors")
    problem = _load(args.paths)
    from gnppdsl.compile.task import build_task

    task = build_task(problem)
    if args.conflicts is not None:
        task = _forbid(task, args.conflicts)
    stem = _safe(problem.name)
    files: list[tuple[str, str]]
    if args.emit == "sas":
        from gnppdsl.compile.sas_writer import write_sas

        files = [(f"{stem}.sas", write_sas(task))]
    elif args.emit == "pddl" and args.conflicts is None:
        from gnppdsl.compile.pddl_lifted import write_lifted_pddl

        out = write_lifted_pddl(problem, "inline" if args.inline_derived else "keep")
        files = [("domain.pddl", out.domain), (f"{stem}.pddl", out.problem)]
    elif args.emit in ("pddl", "pddl-ground"):
        from gnppdsl.compile.pddl import write_pddl

        out = write_pddl(task, problem.domain.name)
        files = [("domain.pddl", out.domain), (f"{stem}.pddl", out.problem)]
    elif args.emit == "asp":
        files = [(f"{stem}.lp", _asp(task))]
    else:
        files = [(f"{stem}.factors.txt", _factors(problem, task, args.plan))]
    _write(files, args.output)
    return 0


def _load(paths):
    from gnppdsl.errors import UserError

    for p in paths:
        if not Path(p).is_file():
            raise UserError(f"{p}: no such file")
    try:
        from gnppdsl.ir import load_problem
    except ImportError:
        raise UserError("the .pntc loader (gnppdsl.ir.load_problem) is not available in this build") from None
    if len(paths) > 2:
        raise UserError("give the problem file, optionally preceded by its domain file")
    if len(paths) == 2:
        return load_problem(paths[1], paths[0])     # `gnpp compile domain.pntc p1.pntc`
    return load_problem(paths[0])


def _safe(name: str) -> str:
    return "".join(c if c.isalnum() or c in "-_." else "_" for c in name) or "problem"


def _forbid(task, path):
    from gnppdsl.errors import UserError

    try:
        from gnppdsl.logic.conflict_io import read_conflicts
        from gnppdsl.logic.reformulation import forbid_sequences
    except ImportError:
        raise UserError("--conflicts needs gnppdsl.logic.reformulation and conflict_io, "
                        "which are not available in this build") from None
    conflicts = read_conflicts(path, task)
    return forbid_sequences(task, conflicts) if conflicts else task


def _asp(task) -> str:
    from gnppdsl.errors import UserError

    try:
        from gnppdsl.logic.encoding import encode_task
    except ImportError:
        raise UserError("--emit asp needs gnppdsl.logic.encoding, which is not available "
                        "in this build") from None
    return encode_task(task, standalone=True)


def _factors(problem, task, plan) -> str:
    from gnppdsl.compile.factory import GraphNLPFactory, format_factors
    from gnppdsl.compile.semantics import parse_plan, plan_states
    from gnppdsl.errors import UserError

    text = ""
    if plan is not None:
        from gnppdsl.inputs import InputError, is_regular_file, read_text

        path = Path(plan)
        if is_regular_file(path):
            try:
                text = read_text(path)
            except InputError as exc:
                raise UserError(f"--plan {plan}: {exc.message}") from None
        elif "(" not in plan and plan.strip() and (path.suffix or "/" in plan):
            raise UserError(f"--plan {plan}: no such file")
        else:
            text = plan
    states = plan_states(task, parse_plan(task, text))
    factory = GraphNLPFactory(problem, task, robot_dims=_robot_dims(problem))
    return format_factors(task, factory, states)


def _robot_dims(problem):
    """Joint dimensions and limits of URDF robots from their pinocchio models (as the solver
    does); planar robots and scenes without robot models use the factory's default."""
    scene = getattr(problem, "scene", None)
    if scene is None or not any(r.kind == "urdf" for r in scene.robots.values()):
        return None
    from gnppdsl.compile.factory import scene_robot_dims
    from gnppdsl.geometry.context import GeometryContext

    geometry = GeometryContext(scene)
    fallback = scene_robot_dims(problem)

    def dims(robot: str):
        if robot in geometry.models:
            lo_hi = geometry.robot_dims(robot)
            return lo_hi[0], tuple(map(float, lo_hi[1])), tuple(map(float, lo_hi[2]))
        return fallback(robot)

    return dims


def _write(files, out_dir) -> None:
    if out_dir is None:
        for k, (name, text) in enumerate(files):
            if len(files) > 1:
                sys.stdout.write(f"{';' if name.endswith('.pddl') else '#'} ---- {name} ----\n")
            sys.stdout.write(text)
        return
    from gnppdsl.outputs import output_dir, write_atomic

    d = output_dir(out_dir, "-o")
    for name, text in files:
        write_atomic(d / name, text, "-o")
    for name, _ in files:
        print(d / name)
