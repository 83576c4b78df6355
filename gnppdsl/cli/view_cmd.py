"""`gnpp view RESULT.json [--html FILE]`: the solved plan in a browser 3-D viewer.

Without `--html` the page goes to a temporary file that is opened in the default browser
(Python's `webbrowser`; where none is available the path is printed). `--html FILE` writes a
self-contained page (no network, the viewer's JavaScript and the robots' meshes inlined) to share
or attach to a paper and does not open it unless `--open` is given. The problem and domain files
are the ones recorded in the result (`inputs`); `--problem` names them when the result has moved.
"""
from __future__ import annotations

import argparse

from gnppdsl.cli.outputs import make_parent


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by `gnpp solve --json`")
    parser.add_argument("--html", metavar="FILE", default=None,
                        help="write the self-contained page to FILE (created with its directory)")
    parser.add_argument("--open", action="store_true", help="with --html: also open it in the browser")
    parser.add_argument("--force", action="store_true", help="overwrite an existing --html FILE")
    parser.add_argument("--problem", nargs="+", metavar="PATH", default=None,
                        help="the problem file (and domain) to take the scene from, instead of the "
                             "paths recorded in the result")


def run(args: argparse.Namespace) -> int:
    from pathlib import Path

    from gnppdsl.errors import UserError
    from gnppdsl.solve import load_and_compile
    from gnppdsl.view.result_file import load_result

    result = load_result(args.result)
    paths = args.problem or [result["inputs"].get("domain"), result["inputs"].get("problem")]
    paths = [p for p in paths if p]
    missing = [p for p in paths if not Path(p).is_file()]
    if missing:
        raise UserError(f"{args.result}: the problem file {missing[0]} recorded in the result is gone; "
                        "give it with --problem PATH")
    compiled = load_and_compile(paths)
    if args.html and Path(args.html).exists() and not args.force:
        raise UserError(f"--html {args.html}: exists (give --force to overwrite)")
    target = make_parent("--html", args.html) if args.html else None
    show(result, compiled, target, open_browser=args.open or target is None)
    return 0


def show(result: dict, compiled, target=None, open_browser: bool = True) -> None:
    """Write the viewer page (to `target`, else a temporary file) and open it."""
    import tempfile
    import webbrowser
    from pathlib import Path

    from gnppdsl.view.html import write_html

    if target is None:
        fd, name = tempfile.mkstemp(prefix=f"gnpp-{result['problem']}-", suffix=".html")
        import os
        os.close(fd)
        target = Path(name)
    path = write_html(result, compiled, target)
    print(f"wrote {path} ({path.stat().st_size / 1e6:.1f} MB)")
    if open_browser:
        try:
            opened = webbrowser.open(path.resolve().as_uri())
        except Exception:    # noqa: BLE001 - no browser: the path is printed
            opened = False
        print("opened it in the browser" if opened else f"open {path} in a browser")
