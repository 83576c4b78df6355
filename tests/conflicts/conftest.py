"""Fixtures shared by the conflict tests: Field_4 compiled once per module (the interleaving
and stutter tests build their conflicts from its factory's own factors)."""
from __future__ import annotations

from pathlib import Path

import pytest

from gnppdsl.solve.compiled import load_and_compile

FIELD = Path(__file__).resolve().parents[2] / "examples" / "field"


@pytest.fixture(scope="module")
def field4():
    return load_and_compile(str(FIELD / "field4.pntc"))
