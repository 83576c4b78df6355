"""`gnpp export RESULT.json --csv DIR`: per-robot joint trajectories (time + one column per
joint) of a solved result, for a controller or a plotting script (gnppdsl.view.export)."""
from __future__ import annotations

import argparse

from gnppdsl.cli.outputs import make_dir


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("result", metavar="RESULT.json", help="a result written by `gnpp solve --json`")
    parser.add_argument("--csv", required=True, metavar="DIR",
                        help="write DIR/<robot>.csv for every robot (created if missing)")
    parser.add_argument("--force", action="store_true", help="overwrite existing CSV files")


def run(args: argparse.Namespace) -> int:
    from gnppdsl.view.export import export_csv
    from gnppdsl.view.result_file import load_result

    result = load_result(args.result)
    make_dir("--csv", args.csv)
    paths = export_csv(result, args.csv, overwrite=args.force)
    for p in paths:
        print(f"wrote {p}")
    return 0
