"""Command-line options that `gnpp solve` and `gnpp bench` share, written once so that their
help and choices cannot drift apart. Light imports only (no casadi, no solver)."""
from __future__ import annotations

import argparse

from gnppdsl.ir.model import SOLVER_ORDERS, SOLVER_PLANNERS


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


def add_planner_argument(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--planner", choices=SOLVER_PLANNERS, default=None,
                        help="logic mode: auto (clingo's shortest plans while cheap, Fast Downward once "
                             "a call's proofs of shorter horizons cost more than 2 s), sequential (clingo, "
                             "shortest plans, exact N0), fd (Fast Downward, greedy search with FF on the task with the "
                             "conflicts compiled in: short plans, not proven shortest). Default: the "
                             "problem's solver setting `planner`, else auto")
