"""Command-line options that `gnpp solve` and `gnpp bench` share, written once so that their
help and choices cannot drift apart. Light imports only (no casadi, no solver)."""
from __future__ import annotations

import argparse

from gnppdsl.ir.model import SOLVER_ORDERS, SOLVER_PLANNERS, setting_problem


def add_order_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--order", choices=SOLVER_ORDERS, default=None,
                        help="gnpp/rlgp: solve the full graph-NLP first and search for a conflict only "
                             "when it fails (full_first, default), relaxations first (relaxed_first), or the "
                             "small relaxations, then the full graph (staged)")


SOLVE_JIT_DEFAULT = ("the problem's solver setting `jit`, else kernels missing from the cache are "
                     "compiled in the background for later solves")


def add_jit_argument(parser: argparse.ArgumentParser, default: str = SOLVE_JIT_DEFAULT) -> None:
    parser.add_argument("--jit", action=argparse.BooleanOptionalAction, default=None,
                        help="--jit: compile the large derivative kernels to C during the solve "
                             f"(cached on disk); --no-jit: never. Default: {default}")


def add_curvature_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--distance-curvature", action=argparse.BooleanOptionalAction, default=None,
                        help="ipopt's Hessian includes the second derivatives of signed-distance rows "
                             "(--no-distance-curvature: they enter linearised, cheaper iterations on "
                             "robot domains). Default: the problem's solver setting "
                             "`distance_curvature`, else on")
    parser.add_argument("--kinematic-curvature", nargs="?", const=True, default=None,
                        type=kinematic_curvature_mode, metavar="auto|true|false",
                        help="ipopt's Hessian includes the second derivatives of forward-kinematics "
                             "rows (alone or `true`; --no-kinematic-curvature or `false`: they enter "
                             "linearised, Gauss-Newton-like steps; `auto`: linearised first, exact "
                             "again from the same start when that does not end feasible). Default: "
                             "the problem's solver setting `kinematic_curvature`, else auto")
    parser.add_argument("--no-kinematic-curvature", dest="kinematic_curvature", action="store_const",
                        const=False, help="= --kinematic-curvature false")


def kinematic_curvature_mode(text: str) -> bool | str:
    """`--kinematic-curvature MODE`: auto, true/on/yes, false/off/no."""
    t = text.strip().lower()
    if t == "auto":
        return "auto"
    if t in ("true", "on", "yes", "1"):
        return True
    if t in ("false", "off", "no", "0"):
        return False
    raise argparse.ArgumentTypeError(f"expected auto, true or false, got {text!r} (put the problem "
                                     "file before a bare --kinematic-curvature)")


def add_active_set_argument(parser: argparse.ArgumentParser, default: bool | None = None) -> None:
    """`--active-set / --no-active-set` (`SolveOptions.active_set`), as `gnpp solve` and
    benchmarks/bench_lab.py give it."""
    parser.add_argument("--active-set", action=argparse.BooleanOptionalAction, default=default,
                        help="every solution is verified independently (pinocchio + coal); with the "
                             "active set (default) the pairs it finds near join the plan's NLP until "
                             "the verification is clean; --no-active-set: a rejected solution ends the "
                             "solve as verification_failed (and counts as a failure in a benchmark)")


def add_planner_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--planner", choices=SOLVER_PLANNERS, default=None,
                        help="logic mode: auto (clingo's shortest plans while cheap, Fast Downward once "
                             "a call's proofs of shorter horizons cost more than 2 s, then both in turns of "
                             "doubling length), sequential (clingo, "
                             "shortest plans, exact N0), fd (Fast Downward, greedy search with FF on the task with the "
                             "conflicts compiled in: short plans, not proven shortest). Default: the "
                             "problem's solver setting `planner`, else auto")


def check_ranges(args: argparse.Namespace) -> None:
    """Range-check the numeric options `gnpp solve` and `gnpp bench` share, with the limits of
    the `solver { }` block (`gnppdsl.ir.model.SETTING_RANGES`): NaN, infinity, a negative
    time limit or a tolerance of 1e3 are errors naming the option, exit 2."""
    from gnppdsl.errors import UserError

    # an instance is a seed of the scene's draw (`gnppdsl.ir.instances`): the seed's range; in
    # `gnpp bench`, the last instance of --seed S --instances N is S + N - 1
    instance = getattr(args, "instance", None)
    if getattr(args, "instances", None):
        instance, option = args.seed + args.instances - 1, "--seed + --instances - 1"
    else:
        option = "--instance"
    if instance is not None and setting_problem("seed", instance) is not None:
        raise UserError(f"{option} {instance}: {setting_problem('seed', instance)}")
    for key in ("tolerance", "time_limit", "seed", "max_horizon", "max_iter", "anytime", "batch_conflicts"):
        value = getattr(args, key, None)
        if value is None:
            continue
        problem = setting_problem(key, value)
        if problem is not None:
            option = "--" + key.replace("_", "-")
            raise UserError(f"{option} {value}: {problem}")


def check_outputs(args: argparse.Namespace, files: tuple[str, ...] = ("json", "db"),
                  parents_created: bool = False) -> None:
    """Refuse the output paths before any work (`gnppdsl.outputs`): a missing directory
    (unless the command creates it), a symbolic link or a non-regular file at the options
    `files` (`--json`, `--db`, ...), a link or a file at `--render`."""
    import os
    import stat

    from gnppdsl.errors import UserError
    from gnppdsl.outputs import check_target

    for option in files:
        value = getattr(args, option, None)
        if value is not None:
            check_target(value, f"--{option}", parents_created)
    render = getattr(args, "render", None)
    if render is not None:
        try:
            mode = os.lstat(render).st_mode
        except FileNotFoundError:
            return
        except (OSError, ValueError) as exc:
            raise UserError(f"--render {render}: {getattr(exc, 'strerror', None) or exc}") from None
        if stat.S_ISLNK(mode) or not stat.S_ISDIR(mode):
            raise UserError(f"--render {render}: not a directory (symbolic links are not followed)")

