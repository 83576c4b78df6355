"""R-LGP's pair costs with the base's drive between consecutive picks and drops
(`reach.drives.pair_drives`, `solve.rlgp.ReachabilityCosts._drive_pair_costs`): the order of the
picks follows the drive, each pair's drive is a lower bound of the plan's chained drive, and the
footprint's quick far-away test keeps `Footprint.free`'s verdicts. No NLP is solved."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from gnppdsl.compile.placement import RADII, Footprint, _polygon_gap, base_footprint, base_radius
from gnppdsl.solve.compiled import load_and_compile

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"


@pytest.fixture(scope="module")
def sort18():
    return load_and_compile([str(MOBILE / "sort_random.pntc")], instance=18)


def test_rlgp_plans_sort_random_18_red_first(sort18):
    """Instance 18: red1 at (-0.10, 0.15), blue1 at (-0.42, 0.33), both north-west of the table's
    centre. The end-effector graph's Eq. 3 travel put blue1 first (2979 against 3107), a plan
    whose base drove 5.02 m (plain GNPP's red-first plan 3.58 m); with the drive red1 goes first."""
    from gnppdsl.solve.loop import Loop
    from gnppdsl.solve.options import SolveOptions

    run = Loop(sort18, SolveOptions(algorithm="rlgp", time_limit=120).validated(), None)
    res = run.next_plan(enumerate_=False)
    assert res.found
    names = [run.task.operators[o].name.replace(" ", "") for o in res.plan.operators]
    assert names[0] == "pick(red1,mm,center)", names


def test_pair_drives_bound_the_plan_chain_from_below(sort18):
    """Per pair the two ends are chosen independently, so along a plan the pairs' sum is at most
    the drive (plus ring penalties) of `plan_bases`' chain through the same targets, measured
    here from the chain's own points. Red-first also drives less than blue-first by the pairs."""
    from gnppdsl.reach.drives import RING_WEIGHT, TravelMap, pair_drives, plan_bases
    from gnppdsl.reach.integration import target_position

    p = sort18.problem
    spec = p.scene.robots["mm"]
    obstacles = [o for o in p.scene.static_obstacles(p.objects).values() if len(o.pose) >= 7]
    lo, hi = spec.attributes.get("base_min"), spec.attributes.get("base_max")
    r, fp = base_radius(spec), base_footprint(spec)
    names = ["red1", "red_tray", "blue1", "blue_tray"]
    targets = {i: target_position(p.scene, n) for i, n in enumerate(names)}
    drives = pair_drives(targets, spec.home, obstacles, lo, hi, radius=r, footprint=fp)

    def pairs(order):
        return sum(drives[(a, b)] for a, b in zip([None] + order[:-1], order))

    red_first, blue_first = pairs([0, 1, 2, 3]), pairs([2, 3, 0, 1])
    assert red_first < blue_first
    bases = plan_bases([targets[i] for i in range(4)], spec.home, obstacles, lo, hi, radius=r, footprint=fp)
    travel = TravelMap(obstacles, r, lo, hi)
    chain, prev = 0.0, np.asarray(spec.home[:2], float)
    for i, q in enumerate(bases):
        xy = np.asarray(q[:2], float)
        ring = float(np.linalg.norm(xy - np.asarray(targets[i][:2], float)))
        chain += float(travel.distances(prev[None], xy[None])[0, 0]) + RING_WEIGHT * (ring - r - RADII[0])
        prev = xy
    assert red_first <= chain + 1e-6
    for (a, b), d in drives.items():          # never shorter than the straight line between rings
        src = np.asarray(spec.home[:2], float) if a is None else np.asarray(targets[a][:2], float)
        reach = 0.0 if a is None else r + RADII[-1]
        straight = float(np.linalg.norm(np.asarray(targets[b][:2], float) - src)) - reach - r - RADII[-1]
        assert d >= straight - 1e-6


def test_footprint_far_test_keeps_the_verdicts():
    """`Footprint.free` skips an obstacle whose rectangle lies farther than the outline's reach
    plus the clearance; over random points and headings its verdicts equal the polygon gap's."""
    from types import SimpleNamespace

    hull = ((0.07, -0.1), (0.07, 0.1), (-0.15, 0.12), (-0.16, -0.12))
    fp = Footprint(hull, 0.15)
    box = SimpleNamespace(pose=(0.2, -0.1, 0.4, 0.0, 0.0, math.sin(0.3), math.cos(0.3)),
                          shape=SimpleNamespace(kind="box", size=(1.2, 0.8, 0.1)))
    ct, st = math.cos(0.6), math.sin(0.6)
    rect = [(0.2 + ct * u - st * v, -0.1 + st * u + ct * v) for u, v in ((0.6, 0.4), (-0.6, 0.4), (-0.6, -0.4), (0.6, -0.4))]
    rng = np.random.default_rng(0)
    seen = set()
    for x, y, yaw in zip(rng.uniform(-1.5, 1.5, 600), rng.uniform(-1.3, 1.3, 600), rng.uniform(-4, 4, 600)):
        c, s = math.cos(yaw), math.sin(yaw)
        outline = [(x + c * px - s * py, y + s * px + c * py) for px, py in hull]
        expected = _polygon_gap(outline, rect) >= fp.clearance
        assert fp.free(x, y, yaw, [box]) == expected
        seen.add(expected)
    assert seen == {True, False}
