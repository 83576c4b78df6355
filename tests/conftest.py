"""Shared pytest switches.

`@pytest.mark.slow` tests (long end-to-end solves) are skipped unless GNPP_SLOW=1, so the
default suite stays fast."""
import os

import pytest


def pytest_collection_modifyitems(config, items):
    if os.environ.get("GNPP_SLOW") == "1":
        return
    skip = pytest.mark.skip(reason="slow test: set GNPP_SLOW=1 to run it")
    for item in items:
        if "slow" in item.keywords:
            item.add_marker(skip)


# Solves in the tests never start background kernel compilers (gnppdsl.nlp.jit's default mode):
# they would write to the user's cache and compete with the tests for the CPU. The jit tests
# build their KernelCaches explicitly, in temporary directories.
os.environ.setdefault("GNPP_JIT", "0")
# Nor do they start the background build of the native distance library (gnppdsl.geometry.native):
# `make setup` builds it, and tests/geometry/test_geometry_native.py builds it when it is missing.
os.environ.setdefault("GNPP_NATIVE_BUILD", "0")
