"""`gnpp`: the command-line entry point.

Subcommands live in their own modules (`gnppdsl.cli.<name>`), each with
`add_arguments(parser)` and `run(args) -> int`, imported lazily so `gnpp check` does not pay
for casadi/pinocchio imports.
"""
from __future__ import annotations

import argparse
import importlib
import os
import sys

from gnppdsl import __version__
from gnppdsl.errors import UserError

# name -> (module, one-line help)
SUBCOMMANDS: dict[str, tuple[str, str]] = {
    "check": ("gnppdsl.cli.check", "parse, resolve and type-check .pntc files"),
    "compile": ("gnppdsl.cli.compile_cmd", "compile a problem to SAS+, PDDL, ASP or graph-NLP factors"),
    "solve": ("gnppdsl.cli.solve_cmd", "solve a problem with the Graph-NLP Planner"),
    "bench": ("gnppdsl.cli.bench", "run algorithms x problems x seeds and print a table"),
    "view": ("gnppdsl.cli.view_cmd", "show a solved result in a browser 3-D viewer (or write it as one HTML page)"),
    "export": ("gnppdsl.cli.export_cmd", "write a solved result's joint trajectories as CSV"),
}


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser of every sub-command; with `command` (`command_of`), only that one's
    module is imported and given its arguments (the others keep their name and help, all
    that `gnpp --help` or a misspelt command needs): `gnpp solve` does not import the modules
    of bench, view, export, compile and check."""
    parser = argparse.ArgumentParser(
        prog="gnpp",
        description="Compile and solve task and motion planning problems written in .pntc.",
    )
    parser.add_argument("--version", action="version", version=f"gnpp {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name, (module, help_) in SUBCOMMANDS.items():
        p = sub.add_parser(name, help=help_, description=help_)
        if command is not None and name != command:
            continue
        try:
            mod = importlib.import_module(module)
        except ModuleNotFoundError as exc:
            if exc.name != module:
                raise
            p.set_defaults(_unavailable=name)
            continue
        mod.add_arguments(p)
        p.set_defaults(_run=mod.run)
    return parser


def command_of(argv: list[str]) -> str:
    """The sub-command `argv` names (its first word that is not an option), or "" (none:
    `gnpp --help`, `gnpp --version`, a misspelt command)."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in SUBCOMMANDS else ""
    return ""


#: commands after which the `gnpp` program leaves without the interpreter's teardown
#: (`_leave_now`): what they write is on disk when they return
QUICK_EXIT = frozenset({"solve"})


def main(argv: list[str] | None = None) -> int:
    """Run one command; the exit status. Called without `argv` (as the `gnpp` program), a
    run ended by SIGINT/SIGTERM/the time limit, and any `gnpp solve`, leave at once
    (`_leave_now`)."""
    global _command
    _command = None
    if argv is None:
        # the `gnpp` program's own process: generated dataclass methods from the per-user code
        # cache (`gnppdsl.classcode`). Not for a library user's process: the patch reaches every
        # dataclass created after it, theirs too.
        from gnppdsl import classcode
        classcode.install()
    code = _main(argv)
    if argv is None:
        _leave_now(code, _command in QUICK_EXIT and not _observed())
    return code


def _observed() -> bool:
    """Whether a profiler or tracer runs (`python -m cProfile`, coverage.py): they write what
    they gathered at the interpreter's exit, so the process must end normally."""
    return sys.getprofile() is not None or sys.gettrace() is not None


_command: str | None = None     # the command `_main` ran (for `main`'s quick exit)


def _leave_now(code: int, finished: bool = False) -> None:
    """Skip the interpreter's teardown after a stop request, or after a command of
    QUICK_EXIT (`finished`). Finalising casadi, pinocchio and coal (and freeing every object
    one by one) took 1.2-1.4 s after a stopped Lab solve, beyond the 1 s a signal is to be
    honoured in, and ~0.2 s CPU after bench_komo's pick-and-place (of a ~1.9 s process).
    Everything a run writes is already on disk (atomic, fsync'ed files; committed SQLite
    transactions; the package registers no exit handlers), so this is as safe as the kill
    a stop answers; standard output and error are flushed first."""
    from gnppdsl import interrupt

    if interrupt.last_stop() is None and not finished:
        return
    for stream in (sys.stdout, sys.stderr):
        try:
            stream.flush()
        except (OSError, ValueError):
            pass
    os._exit(code)


def _main(argv: list[str] | None) -> int:
    from gnppdsl import interrupt

    interrupt.early()            # a signal while the parser's imports run: recorded, not fatal
    global _command
    args = None
    try:
        parser = build_parser(command_of(sys.argv[1:] if argv is None else argv))
        args = parser.parse_args(argv)
        _command = args.command
    finally:
        # `gnpp solve` acts on a recorded request inside its own handlers (status interrupted,
        # --json written); any other command ends here with the signal's exit status
        stopped = interrupt.release_early(keep=args is not None and args.command == "solve")
    if stopped is not None and args.command != "solve":
        print(f"gnpp: {interrupt.Interrupted(stopped).describe()}", file=sys.stderr)
        return interrupt.EXIT_CODES.get(stopped, 130)
    if args.command is None:
        parser.print_help()
        return 2
    if getattr(args, "_unavailable", None):
        print(f"gnpp: '{args._unavailable}' is not available in this build", file=sys.stderr)
        return 2
    try:
        return int(args._run(args) or 0)
    except UserError as err:
        print(str(err), file=sys.stderr)
        return err.exit_code
    except KeyboardInterrupt:
        print("gnpp: interrupted", file=sys.stderr)
        return 130
    except BrokenPipeError:
        # the reader went away (`gnpp ... | head`): stop quietly, as the Unix tools do
        _silence_stdout()
        return 0
    finally:
        interrupt.drop_carried()     # a request `solve` did not reach its handlers with


def _silence_stdout() -> None:
    """Point stdout at /dev/null so the interpreter's final flush does not raise again."""
    try:
        devnull = os.open(os.devnull, os.O_WRONLY)
        os.dup2(devnull, sys.stdout.fileno())
    except (OSError, ValueError):
        pass


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
