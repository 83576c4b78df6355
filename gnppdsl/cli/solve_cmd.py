"""`gnpp solve PROBLEM`: run the Graph-NLP Planner (or the One-way baseline) on one problem.

Exit codes: 0 solved; 1 not solved (no plan, time limit, solver failure), with the reason;
2 bad input (unknown file, syntax or type error, bad option).
Heavy imports (casadi, clingo, the solver) happen inside `run`, so `gnpp --help` stays fast.
"""
from __future__ import annotations

import argparse
import os
import sys
import time
from dataclasses import replace

from gnppdsl.cli.outputs import make_parent
from gnppdsl.cli.solver_args import (add_active_set_argument, add_curvature_argument,  # light imports
                                     add_jit_argument, add_order_argument, add_planner_argument,
                                     check_outputs, check_ranges)
from gnppdsl.solve.result import INTERRUPTED   # light (dataclasses only)


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("paths", nargs="+", metavar="PROBLEM",
                        help="the problem file (.pntc); a domain file may be given before it")
    parser.add_argument("--algorithm", choices=("gnpp", "oneway", "rlgp"), default=None,
                        help="Graph-NLP Planner (default), the One-way baseline (enumerate plans by "
                             "length, block only the failed plan), or rlgp: GNPP with the problem's "
                             "reachability graph (travel costs for the plan choice, trajectory warm starts)")
    parser.add_argument("--switches", default=None, metavar="SW",
                        help="subset of 'trng' for gnpp/rlgp: t = binary search on time, r = relaxations, "
                             "n = convergence heuristic, g = database of solved subgraphs "
                             "(default: the problem's solver settings, usually 'trn')")
    add_order_argument(parser)
    add_planner_argument(parser)
    add_jit_argument(parser)
    add_curvature_argument(parser)
    parser.add_argument("--time-limit", type=float, default=None, metavar="S", help="seconds for the whole solve")
    parser.add_argument("--seed", type=int, default=None, help="random seed of the NLP starts")
    parser.add_argument("--db", default=None, metavar="PATH",
                        help="persist the database of solved subgraphs in this SQLite file "
                             "(implies switch g); a later run on the same domain starts from it")
    add_active_set_argument(parser)
    parser.add_argument("--json", default=None, metavar="FILE", help="write the full result as JSON")
    parser.add_argument("--render", default=None, metavar="DIR", help="render the keyframes of the solution as images")
    parser.add_argument("--view", action="store_true",
                        help="open the solution in the browser 3-D viewer (as `gnpp view RESULT.json`)")
    parser.add_argument("--max-horizon", type=int, default=None, metavar="H", help="longest plan to try")
    parser.add_argument("--tolerance", type=float, default=None, help="constraint violation tolerance")
    parser.add_argument("--quiet", action="store_true",
                        help="print only the final status line (no progress on stderr)")
    parser.add_argument("--verbose", action="store_true", help="print each plan and conflict as found")
    parser.add_argument("--no-optimise", dest="optimise", action="store_false", default=None,
                        help="return the first feasible solution without minimising the domain's "
                             "`minimize` terms")
    parser.add_argument("--instance", type=int, default=None, metavar="K",
                        help="solve randomised instance K of the problem's family: the scene's "
                             "`random_xy` objects drawn with seed K (docs/scene.md)")
    parser.add_argument("--anytime", type=float, default=None, metavar="SECONDS",
                        help="after the first solution, look this long (within --time-limit) for "
                             "cheaper logical plans under a cost bound (action costs + a lower bound "
                             "of the objective); the result says whether the cost was proved optimal")
    parser.add_argument("--batch-conflicts", type=int, default=None, metavar="N",
                        help="gnpp/rlgp: NLPs per learned conflict spent deciding its renamings onto "
                             "other objects of the same type (and pairs, e.g. block and arm) that "
                             "lifting cannot accept; the infeasible ones are learned with it (0: off). "
                             "Default: the problem's solver setting `batch_conflicts`, else 64")
    parser.add_argument("--interleave-conflicts", action=argparse.BooleanOptionalAction, default=None,
                        help="gnpp/rlgp: a learned conflict also forbids its copies with steps inserted "
                             "or removed where its infeasible subgraph only passes values on (a parked "
                             "base, an object staying put), so one geometric failure is not learned "
                             "again per interleaving of other actions. Default: the problem's solver "
                             "setting `interleave_conflicts`, else on")
    parser.add_argument("--batch-lazy", action=argparse.BooleanOptionalAction, default=None,
                        help="gnpp/rlgp: a conflict's renamings beyond the first ones are decided only "
                             "when a proposed plan holds one (--no-batch-lazy: all when the conflict "
                             "is learned). Default: the problem's solver setting `batch_lazy`, else on")
    parser.add_argument("--stretch-conflicts", action=argparse.BooleanOptionalAction, default=None,
                        help="gnpp/rlgp, with interleaved conflicts: transitions of `preorder`-tagged "
                             "templates (a push held over several steps) count as pass-through steps "
                             "too. Default: the problem's solver setting `stretch_conflicts`, else off")


#: seconds the hard alarm (`gnppdsl.interrupt.arm_time_limit`) waits after the loop's own
#: deadline: the loop normally stops first and returns its partial result; the alarm is what
#: ends a run stuck where no deadline check reaches, so the limit holds within a second
ALARM_GRACE = 0.5


def run(args: argparse.Namespace) -> int:
    from gnppdsl import interrupt
    from gnppdsl.errors import UserError

    if args.switches is not None and set(args.switches) - set("trng"):
        raise UserError(f"--switches: '{args.switches}' is not a subset of 'trng'")
    check_ranges(args)
    for opt, value in (("--json", args.json), ("--db", args.db)):
        if value is not None:
            make_parent(opt, value)         # created on a fresh clone (`gnppdsl.cli.outputs`)
    check_outputs(args)
    with interrupt.handlers():
        return _run(args, time.monotonic())


def _run(args: argparse.Namespace, start: float) -> int:
    """Load, compile and solve under one time limit (loading and grounding count: the loop
    gets what is left); SIGINT / SIGTERM / the alarm end it with the partial result."""
    import gnppdsl                      # the public API: the command line solves through it
    from gnppdsl import interrupt
    from gnppdsl.errors import SolveFailure

    if args.time_limit is not None:
        interrupt.arm_time_limit(args.time_limit + ALARM_GRACE)
    compiled = None
    try:
        with interrupt.interruptible():
            compiled = gnppdsl.load_and_compile(args.paths, instance=args.instance)
            options = gnppdsl.SolveOptions.from_settings(
                compiled.problem.settings,
                algorithm=args.algorithm, switches=args.switches, time_limit=args.time_limit,
                seed=args.seed, max_horizon=args.max_horizon, tolerance=args.tolerance, database=args.db,
                order=args.order, jit=args.jit, distance_curvature=args.distance_curvature,
                kinematic_curvature=args.kinematic_curvature, planner=args.planner,
                active_set=args.active_set, optimise=args.optimise, anytime=args.anytime,
                batch_conflicts=args.batch_conflicts, interleave_conflicts=args.interleave_conflicts,
                stretch_conflicts=args.stretch_conflicts, batch_lazy=args.batch_lazy,
            )
            limit = options.time_limit
            left = limit - (time.monotonic() - start)
            if left <= 0:
                raise interrupt.Interrupted("time_limit")
            interrupt.arm_time_limit(left + ALARM_GRACE)
            options = replace(options, time_limit=left)
            if args.quiet:
                result = gnppdsl.solve_problem(compiled, options)
            else:   # a live status line on a terminal, a line per plan otherwise (gnppdsl.cli.status)
                from gnppdsl.cli.status import SolveStatus

                with SolveStatus(compiled.problem.name, limit, spent=time.monotonic() - start,
                                 echo=emit if args.verbose else None) as status:
                    result = gnppdsl.solve_problem(compiled, options, progress=status)
            result.time_limit = limit
    except interrupt.Interrupted as stop:
        result = _stopped(compiled, args, stop, time.monotonic() - start)
    except Exception:
        # a stop request that casadi turned into its own exception on the way out
        if interrupt.pending() is None:
            raise
        result = _stopped(compiled, args, interrupt.Interrupted(interrupt.pending()),
                          time.monotonic() - start)
    stop_reason = interrupt.pending()
    if stop_reason is not None and result.status not in (INTERRUPTED, "time_limit") and not result.solved:
        result.status = INTERRUPTED if stop_reason != "time_limit" else "time_limit"
    result = result.checked()
    if args.json:
        result.write_json(args.json)
    if args.quiet:
        emit(f"{result.problem}: {'solved' if result.solved else result.status}"
             + (f", N = {result.stats.N}" if result.solved else f": {result.message}"))
    else:
        emit(result.summary())
    if args.render and result.solved:
        _render(compiled, result, args.render)
    if args.view and result.solved:
        from gnppdsl.cli.view_cmd import show

        show(result.to_json(), compiled)
    if result.status == INTERRUPTED:
        reason = stop_reason or "SIGINT"
        print(f"gnpp: {result.problem} {interrupt.Interrupted(reason).describe()}"
              + (f"; partial result in {args.json}" if args.json else ""), file=sys.stderr)
        return interrupt.EXIT_CODES.get(reason, 130)
    if not result.solved:
        raise SolveFailure(f"gnpp: {result.problem} not solved: {result.message}")
    return 0


def _stopped(compiled, args: argparse.Namespace, stop, elapsed: float):
    """The result of a run stopped before the loop could return one (while loading, or
    before the loop catches `Interrupted` itself): status interrupted / time_limit, what
    is known so far."""
    from pathlib import Path

    from gnppdsl.solve.result import Result, Stats

    status = "time_limit" if stop.reason == "time_limit" else INTERRUPTED
    name = compiled.name if compiled is not None else Path(args.paths[-1]).stem
    domain = compiled.domain_name if compiled is not None else ""
    where = "while solving" if compiled is not None else "while loading"
    return Result(problem=name, domain=domain, algorithm=args.algorithm or "gnpp",
                  switches=args.switches or "", seed=args.seed or 0, status=status,
                  message=f"{stop.describe()} {where} after {elapsed:.1f} s",
                  stats=Stats(total_time=elapsed), time_limit=args.time_limit)


def _render(compiled, result, directory: str) -> None:
    from gnppdsl.solve.keyframes import render_solution

    files = render_solution(compiled, result, directory)
    emit(f"rendered {len(files) - 1} keyframes and the animation plan.gif to {directory}")


def emit(text: str) -> None:
    """Print to stdout; a closed pipe (`gnpp solve ... | head`) silences further output
    instead of ending in a traceback."""
    try:
        print(text, flush=True)
    except BrokenPipeError:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
