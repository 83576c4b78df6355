"""Every `gnpp solve --json` of the bundled examples validates against docs/result.schema.json
(checked with the `jsonschema` library, draft 2020-12), and the schema is exact for what exists:
a misspelt or mistyped field is refused."""
from __future__ import annotations

import copy
import json
from pathlib import Path

import jsonschema
import pytest

SCHEMA = json.loads((Path(__file__).resolve().parents[2] / "docs" / "result.schema.json").read_text())
VALIDATOR = jsonschema.Draft202012Validator(SCHEMA)

# what the suite solves quickly; a mobile problem (R-LGP, about a minute of CPU): the slow
# test_mobile_rlgp_json_output_validates below
PROBLEMS = [f"planar/{p}.pntc" for p in ("p1_one_block", "p2_two_blocks", "p3_occupied", "p4_pair",
                                          "p5_handover", "p6_clutter", "p7_relay", "t1_swap", "t2_unreachable")]
PROBLEMS += ["lab/lab1.pntc"]


def _clean(d: dict) -> dict:
    return {k: v for k, v in d.items() if not k.startswith("_")}


def test_schema_is_a_valid_draft_2020_12_schema():
    jsonschema.Draft202012Validator.check_schema(SCHEMA)


@pytest.mark.parametrize("problem", PROBLEMS)
def test_every_json_output_validates(solved_json, problem):
    data = _clean(solved_json(problem))
    errors = sorted(VALIDATOR.iter_errors(data), key=lambda e: list(e.path))
    assert not errors, "; ".join(f"{list(e.path)}: {e.message}" for e in errors[:5])
    if problem.startswith("planar/t2"):
        assert not data["solved"] and data["steps"] == []
    else:
        assert data["solved"]


@pytest.mark.slow
def test_mobile_rlgp_json_output_validates(pick_place_rlgp):
    """The `gnpp solve --algorithm rlgp --json` of mobile/pick_place (the session's one
    pick_place solve, tests/conftest.py, which the mobile test verifies): R-LGP's result and a
    robot on a base."""
    assert pick_place_rlgp.code == 0
    data = _clean(pick_place_rlgp.json)
    errors = sorted(VALIDATOR.iter_errors(data), key=lambda e: list(e.path))
    assert not errors, "; ".join(f"{list(e.path)}: {e.message}" for e in errors[:5])
    assert data["solved"] and data["algorithm"] == "rlgp"


def test_schema_refuses_what_gnpp_never_writes(solved_json):
    good = _clean(solved_json("lab/lab1.pntc"))
    assert VALIDATOR.is_valid(good)
    bad_cases = []
    d = copy.deepcopy(good); d["status"] = "done"; bad_cases.append(d)
    d = copy.deepcopy(good); del d["steps"][1]["time"]; bad_cases.append(d)
    d = copy.deepcopy(good); d["steps"][0]["values"]["q(left_arm)"][0] = "0.1"; bad_cases.append(d)
    d = copy.deepcopy(good); d["stats"]["nlp_solves"] = 1.5; bad_cases.append(d)
    d = copy.deepcopy(good); d["robots"]["left_arm"]["joints"] = "panda_joint1"; bad_cases.append(d)
    for d in bad_cases:
        assert not VALIDATOR.is_valid(d)
    # fields added by other parts of gnpp (verification, cost) are allowed
    d = copy.deepcopy(good); d["verification"] = {"ok": True}; d["cost"] = 3.0
    assert VALIDATOR.is_valid(d)
