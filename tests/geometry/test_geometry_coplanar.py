"""`features._first_of_coplanar` (which hull faces `_planes` keeps when coplanar triangles merge)
equals the face-by-face greedy it replaced (kept as the reference below): each face unless an
earlier kept face has its plane. Why a new implementation: one numpy call per face cost 2-3.5 ms
per Panda link hull, ~50 ms of every two-arm process; all pairs at once cost a fraction."""
from __future__ import annotations

import numpy as np

from gnppdsl.geometry.features import _first_of_coplanar


def _greedy(N: np.ndarray, O: np.ndarray) -> list[int]:
    keep: list[int] = []
    for i in range(len(N)):
        if any(N[j] @ N[i] > 1 - 1e-9 and abs(O[i] - O[j]) < 1e-9 for j in keep):
            continue
        keep.append(i)
    return keep


def _box_triangles() -> tuple[np.ndarray, np.ndarray]:
    """A box's hull as 12 triangles: each face's plane twice (the coplanar pairs to merge)."""
    N = np.repeat(np.vstack([np.eye(3), -np.eye(3)]), 2, axis=0)
    return N, np.repeat([0.1, 0.2, 0.3, 0.1, 0.2, 0.3], 2).astype(float)


def test_a_box_hulls_triangles_merge_to_its_six_planes():
    N, O = _box_triangles()
    keep = _first_of_coplanar(N, O)
    assert keep.tolist() == [0, 2, 4, 6, 8, 10] == _greedy(N, O)


def test_equal_to_the_greedy_on_shuffled_hulls_with_near_and_far_duplicates():
    rng = np.random.default_rng(3)
    for trial in range(20):
        N = rng.normal(size=(40, 3))
        N /= np.linalg.norm(N, axis=1, keepdims=True)
        O = rng.uniform(0.0, 1.0, 40)
        dup = rng.integers(0, 40, 25)                      # copies: same plane, within tolerance,
        noise = rng.choice([0.0, 1e-12, 1e-6], size=25)    # or just outside it
        N2 = N[dup] + noise[:, None] * rng.normal(size=(25, 3))
        N2 /= np.linalg.norm(N2, axis=1, keepdims=True)
        NN, OO = np.vstack([N, N2]), np.r_[O, O[dup] + noise]
        order = rng.permutation(len(OO))
        NN, OO = NN[order], OO[order]
        assert _first_of_coplanar(NN, OO).tolist() == _greedy(NN, OO), trial
