"""Assembled elastic NLPs shared by every graph-NLP of one structure.

Why: assembling a graph-NLP (the MX graph of its template calls, ipopt's `jac_g` and
`hess_lag`, `nlpsol`) depends only on its *structure*: which compiled template each factor
calls, on which variables (by position), and the variables' dimensions. The numbers of a
graph, its lifted constants (poses, radii, a start configuration), its variables' bounds and
the start point, are inputs of the solver at run time (`p`, `lbx`, `ubx`, `x0`). Measured on the
pick-and-place of `benchmarks/bench_komo.py`: assembly was 37 of ~75 ms per NLP (15 NLPs: 550 of
1180 ms) and rebuilt, identically, for every seed; Alg. 1 also solves the same structure again
for another plan, another time slice of the same actions, or another `gnpp bench` seed.

`FeasibilitySolver`'s own cache (by vertex set) stays for the same subgraph; this one is keyed
by the structure and kept per template compiler (`BodyCompiler`, shared by a solve loop), since
the compiled bodies' identities are part of the key. Nothing of the structure is guessed: the
key lists every factor's template and variable positions, so two graphs with one key build
the same expressions (`tests/nlp/test_nlp_shape_cache.py` checks equal numbers and results
against a fresh assembly).
"""
from __future__ import annotations

import weakref
from collections import OrderedDict
from typing import Any, Sequence

import numpy as np

MAX_SHAPES = 128
"""Assembled structures kept per compiler (LRU): each holds an nlpsol and its derivatives."""

_SHAPES: "weakref.WeakKeyDictionary[Any, OrderedDict]" = weakref.WeakKeyDictionary()


def shape_key(variables: Sequence[Any], compiled: Sequence[tuple], factor_vars: Sequence[Sequence[int]],
              quat_slices: Sequence[Sequence[slice]], options: tuple) -> tuple:
    """The structure of one graph-NLP: per variable its dimension and unit-quaternion slices,
    per factor (in the graph's order) its compiled body's identity and its variables'
    positions, and the solver options the assembly reads (`options`)."""
    return (tuple((v.dim, tuple((s.start, s.stop) for s in q)) for v, q in zip(variables, quat_slices)),
            tuple((id(cb), tuple(fv)) for (_, cb, _), fv in zip(compiled, factor_vars)),
            options)


def instance_numbers(compiled: Sequence[tuple], grouped: bool) -> tuple[np.ndarray, list]:
    """The parameter vector P and the factor rows [(ref, first row, end row)] of one graph in
    the assembly's layout: with `grouped` (MX assembly), instances of a template are the
    columns of one mapped call, templates in order of first appearance and each group's
    parameters column-major; else factors one after the other."""
    if not grouped:
        params = [p for _, _, p in compiled]
        rows, r0 = [], 0
        for r, cb, _ in compiled:
            rows.append((r, r0, r0 + cb.n_rows))
            r0 += cb.n_rows
        return (np.concatenate(params) if params else np.zeros(0)), rows
    groups: OrderedDict[int, list] = OrderedDict()
    for r, cb, p in compiled:
        groups.setdefault(id(cb), []).append((r, cb, p))
    params, rows, r0 = [], [], 0
    for members in groups.values():
        cb, k = members[0][1], len(members)
        if cb.n_params:
            params.append(np.stack([p for _, _, p in members], axis=1).reshape(-1, order="F"))
        for t, (r, _, _) in enumerate(members):
            rows.append((r, r0 + t * cb.n_rows, r0 + (t + 1) * cb.n_rows))
        r0 += k * cb.n_rows
    return (np.concatenate(params) if params else np.zeros(0)), rows


def lookup(compiler: Any, key: tuple) -> Any:
    """The assembled NLP stored for `key` under `compiler`, or None."""
    shapes = _SHAPES.get(compiler)
    if shapes is None:
        return None
    hit = shapes.get(key)
    if hit is not None:
        shapes.move_to_end(key)
        return hit[0]
    return None


def store(compiler: Any, key: tuple, assembled: Any, bodies: Sequence[Any]) -> None:
    """Remember `assembled` for `key` (with the compiled bodies whose ids the key holds, so the
    ids stay theirs)."""
    try:
        shapes = _SHAPES.setdefault(compiler, OrderedDict())
    except TypeError:                       # a compiler that cannot be weakly referenced
        return
    shapes[key] = (assembled, tuple(bodies))
    while len(shapes) > MAX_SHAPES:
        shapes.popitem(last=False)
