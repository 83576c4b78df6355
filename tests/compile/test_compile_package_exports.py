"""The lazy package exports (`gnppdsl.lazy.lazy_getattr`): every name a package lists in
`__all__` is the object of the submodule its table names, unknown names raise AttributeError,
and importing a package alone loads none of its heavy submodules."""
import importlib
import subprocess
import sys

import pytest

PACKAGES = ["compile", "logic", "reach", "solve", "conflicts"]


@pytest.mark.parametrize("pkg", PACKAGES)
def test_exports_resolve_to_their_submodule(pkg):
    m = importlib.import_module(f"gnppdsl.{pkg}")
    table = getattr(m, "_EXPORTS", None) or getattr(m, "_WHERE")
    assert sorted(m.__all__) == sorted(table)
    for name in m.__all__:
        sub = importlib.import_module(table[name])
        assert getattr(m, name) is sub.__dict__[name]
    with pytest.raises(AttributeError, match=f"gnppdsl.{pkg}.*no_such_name"):
        getattr(m, "no_such_name")


def test_importing_packages_loads_no_heavy_library():
    code = ("import sys\n"
            + "".join(f"import gnppdsl.{p}\n" for p in PACKAGES)
            + "print(','.join(m for m in ('casadi', 'clingo', 'pinocchio', 'coal') if m in sys.modules))")
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == ""
