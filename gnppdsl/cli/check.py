"""`gnpp check FILES...`: parse, resolve and type-check domains, problems and modules.

Why its own light module: checking is the edit-compile loop of a modeller; it must start fast,
so nothing here (or below it) imports casadi, pinocchio or clingo.
"""
from __future__ import annotations

import argparse
import sys

EPILOG = """\
Each FILE is a domain, problem or module (.pntc), a scene (.yaml), or a directory (all its
*.pntc files).
A problem finds its domain among the given files, then as domain.pntc next to it, then as any
*.pntc in its directory declaring `domain NAME`. Problems load their scene YAML too.

Diagnostics are printed as `file:line:col: error: message` with the source line, a caret and a
hint. Exit status: 0 if everything is fine, 2 if there are errors.

examples:
  gnpp check examples/planar/domain.pntc
  gnpp check examples/planar            # domain and all problems of a directory
  gnpp check stdlib/planar.pntc         # a library module on its own
  gnpp check examples/lab/lab.yaml      # a scene file on its own

Language reference: docs/reference.md; scene schema: docs/scene.md.
"""


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.formatter_class = argparse.RawDescriptionHelpFormatter
    parser.epilog = EPILOG
    parser.add_argument("files", nargs="+", metavar="FILE", help=".pntc files (domains, problems, modules), scene .yaml files, or directories")
    parser.add_argument("-q", "--quiet", action="store_true", help="print diagnostics only, no summary line")


def run(args: argparse.Namespace) -> int:
    from gnppdsl.ir.resolve import check_files

    report = check_files(args.files)
    if report.ok:
        _check_costs(report)
    text = report.render()
    if text:
        print(text, file=sys.stderr)
        print(file=sys.stderr)
    if not args.quiet or not report.ok:
        print(report.summary(), file=sys.stderr if not report.ok else sys.stdout)
    return 0 if report.ok else 2


def _check_costs(report) -> None:
    """Cost expressions need the scene (an attribute a place lacks, a negative distance): for a
    problem whose domain has any, its ground costs are evaluated as the compiler will, and every
    error joins the report. Only then: grounding is the one step of `gnpp check` whose time
    grows with the problem, and other problems never need it."""
    from gnppdsl.compile.task import build_task
    from gnppdsl.errors import UserError
    from gnppdsl.lang.diagnostics import Diagnostic, DiagnosticError

    for problem in report.problems:
        if not any(a.cost_expr is not None for a in problem.domain.actions.values()):
            continue
        try:
            build_task(problem, prune=False)
        except DiagnosticError as exc:
            for d in exc.diagnostics:
                report.reporter.add(d)
        except UserError as exc:
            report.reporter.add(Diagnostic(str(exc), problem.span, "compile"))
