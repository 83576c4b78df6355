"""ipopt's `jac_g` carries only the Jacobian: its "g" output is a placeholder (zeros), so the
distance callbacks run once per Jacobian evaluation, not twice; ipopt takes g from `nlp_g`.

Checked independently: the Jacobian against central differences of `nlp_g`, the solve's
verdict against the numpy checker (coal directly), and the number of callback calls."""
from __future__ import annotations

import numpy as np
import pytest

import coal  # noqa: E402,F401  (a dependency of the package: never a skip)
from gnppdsl.geometry.context import GeometryContext  # noqa: E402
from gnppdsl.geometry.distance import WitnessCallback  # noqa: E402
from gnppdsl.nlp.evaluate import max_violation  # noqa: E402
from gnppdsl.nlp.feasibility import FeasibilitySolver, SolverOptions  # noqa: E402
from gnppdsl.nlp.graph import GraphNLP  # noqa: E402

from nlp_toys import coal_boxes  # noqa: E402



@pytest.fixture
def counted(monkeypatch):
    calls = {"n": 0}
    orig = WitnessCallback.eval_buffer

    def eval_buffer(self, arg, res):
        calls["n"] += 1
        return orig(self, arg, res)

    monkeypatch.setattr(WitnessCallback, "eval_buffer", eval_buffer)
    # the Python callback answers every query (not its native twin, whose calls are not seen)
    monkeypatch.setattr(GeometryContext, "witness_fast", lambda self, a, b, planar=False: self._callback(a, b, planar))
    return calls


def test_jac_g_is_the_jacobian_of_g_with_one_callback_pass(counted):
    geo, fs = coal_boxes(3, 0.4)
    a = FeasibilitySolver(geo, SolverOptions(restarts=0)).assemble(GraphNLP(fs))
    rng = np.random.default_rng(1)
    z = rng.uniform(-0.4, 0.4, a.lbx.size)
    p = np.concatenate([z[:a.n_x], a.params, [0.01]])
    g_fun, jac_fun = a.solver.get_function("nlp_g"), a.solver.get_function("nlp_jac_g")
    counted["n"] = 0
    J = np.array(jac_fun(z, p)[1])
    assert counted["n"] == 3                  # three box pairs, each queried once
    eps = 1e-6
    for j in range(a.n_x):                    # the pose columns (slacks are constants)
        dz = np.zeros_like(z)
        dz[j] = eps
        fd = (np.array(g_fun(z + dz, p)).ravel() - np.array(g_fun(z - dz, p)).ravel()) / (2 * eps)
        assert np.allclose(J[:, j], fd, atol=1e-5), j


def test_ipopt_solves_with_the_placeholder(counted):
    geo, fs = coal_boxes(3, 0.4)
    res = FeasibilitySolver(geo, SolverOptions(restarts=0)).solve(GraphNLP(fs), seed=0)
    assert res.feasible
    assert max_violation(fs, res.values, geo)[0] <= 1e-6      # coal directly, not the NLP
    assert counted["n"] > 0
