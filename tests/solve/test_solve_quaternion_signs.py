"""Warm starts along equality chains of rotations (`feasibility_check.align_quaternions`): q and
-q are one rotation, but the equality `a == b` of a kept pose (`manipulation.same`) sees them 2
apart. Values of one solve keep their differences along a chain (`FeasibilityCheck.warm_start`),
so a chain assembled from a relaxation's components, one of which came back as -q (clutter_6),
must get one sign before it starts an NLP with the equalities. Checked with the numpy evaluator
(the equality rows) and on the rotations themselves (unchanged)."""
from __future__ import annotations

from types import SimpleNamespace

import networkx as nx
import numpy as np

from gnppdsl.compile.factors import FactorInstance, VarInstance
from gnppdsl.ir.expr import Constraint, Slot
from gnppdsl.nlp.evaluate import max_violation
from gnppdsl.nlp.graph import GraphNLP
from gnppdsl.solve.check_memory import StampedValues
from gnppdsl.solve.feasibility_check import FeasibilityCheck, align_quaternions


def _pose(step: int, space: str = "SE3", dim: int = 7) -> VarInstance:
    return VarInstance("pose", ("o6",), step, space, dim)


def _same(a: VarInstance, b: VarInstance) -> FactorInstance:
    return FactorInstance("manipulation.same", "stay", (("o", "o6"),), frozenset({"time"}), a.step, 2, (),
                          (a, b), (Constraint(Slot(0), "==", Slot(1)),))


def _rotation(x: np.ndarray) -> np.ndarray:
    """Rotation matrix of an SE3 value [x, y, z, qx, qy, qz, qw]."""
    qx, qy, qz, qw = np.asarray(x, float)[3:7]
    return np.array([[1 - 2 * (qy * qy + qz * qz), 2 * (qx * qy - qz * qw), 2 * (qx * qz + qy * qw)],
                     [2 * (qx * qy + qz * qw), 1 - 2 * (qx * qx + qz * qz), 2 * (qy * qz - qx * qw)],
                     [2 * (qx * qz - qy * qw), 2 * (qy * qz + qx * qw), 1 - 2 * (qx * qx + qy * qy)]])


def _chain_graph(n: int = 4):
    poses = [_pose(i) for i in range(n)]
    factors = [_same(poses[i], poses[i + 1]) for i in range(n - 1)]
    return poses, GraphNLP(factors)


def test_one_solve_with_a_negated_quaternion_starts_with_one_sign():
    q = np.array([0.3, 0.1, 0.7, 0.0, 0.0, np.sin(0.4), np.cos(0.4)])
    flipped = q.copy()
    flipped[3:] *= -1
    poses, g = _chain_graph(4)
    values = StampedValues({poses[0]: q, poses[1]: q, poses[2]: flipped, poses[3]: q})   # one solve
    assert max_violation(g.factor_instances, values)[0] > 1.5          # 2|q| apart on the raw rows
    checker = SimpleNamespace(values=values)
    warm = FeasibilityCheck.warm_start(checker, g)
    assert max_violation(g.factor_instances, warm)[0] <= 1e-12
    for v in poses:                                                     # the same rotations
        assert np.allclose(_rotation(warm[v]), _rotation(values[v]))
        assert np.allclose(warm[v][:3], values[v][:3])
    assert values[poses[2]][3] == flipped[3]                            # the memory is not changed


def test_other_differences_and_other_spaces_are_left_as_they_are():
    """Only a negation is undone: a chain whose values differ otherwise (one solve of a
    relaxation without the equalities) keeps them, and vectors that hold no quaternion are
    never negated."""
    a = np.array([0.0, 0.0, 0.0, 0.0, 0.0, np.sin(0.2), np.cos(0.2)])
    b = np.array([0.5, 0.0, 0.0, 0.0, 0.0, -np.sin(1.0), -np.cos(1.0)])     # another rotation, -q form
    poses, g = _chain_graph(2)
    warm = {poses[0]: a, poses[1]: b}
    chains = nx.Graph([(poses[0], poses[1])])
    align_quaternions(chains, poses[0], warm)
    assert np.dot(warm[poses[1]][3:], a[3:]) >= 0 and np.allclose(warm[poses[1]][3:], -b[3:])
    assert np.allclose(_rotation(warm[poses[1]]), _rotation(b)) and np.allclose(warm[poses[1]][:3], b[:3])
    xs = [VarInstance("q", ("arm",), i, "joints", 7) for i in range(2)]
    warm = {xs[0]: np.ones(7), xs[1]: -np.ones(7)}
    align_quaternions(nx.Graph([(xs[0], xs[1])]), xs[0], warm)
    assert np.array_equal(warm[xs[1]], -np.ones(7))
