"""Solved results shared by the view tests: `gnpp solve --json` run once per problem and session."""
from __future__ import annotations

import json
from pathlib import Path

import pytest

from gnppdsl.cli.main import main

EXAMPLES = Path(__file__).resolve().parents[2] / "examples"


@pytest.fixture(scope="session")
def solved_json(tmp_path_factory):
    """problem path (relative to examples/) -> the parsed JSON of `gnpp solve --json`."""
    cache: dict[str, dict] = {}
    out = tmp_path_factory.mktemp("results")

    def get(rel: str) -> dict:
        if rel not in cache:
            path = out / (rel.replace("/", "_") + ".json")
            main(["solve", str(EXAMPLES / rel), "--json", str(path), "--quiet", "--seed", "0"])
            cache[rel] = json.loads(path.read_text())
            cache[rel]["_path"] = str(path)
        return cache[rel]

    return get
