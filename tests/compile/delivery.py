"""A small domain whose action costs are scene distances (`cost step + norm(...)`), written to a
temporary directory by the tests of costs and disjunctive goals. A robot moves between places
of a planar scene; `visited(p)` records where it has been."""
from __future__ import annotations

from pathlib import Path

import yaml

DOMAIN = """\
domain delivery
type place
type robot
state at(r: robot) : place
state visited(p: place) : bool
continuous q(r: robot) : SE2
frame r: robot = q(r)
const step = 0.1
action move(r: robot, a: place, b: place) {
  pre at(r) = a, a != b
  eff at(r) := b, visited(b)
  cost step + norm(pos(pose0(a)) - pos(pose0(b)))
}
"""

PLACES = {"p0": (0.0, 0.0), "p1": (1.0, 0.2), "p2": (0.3, 1.1), "p3": (-0.7, 0.4), "p4": (0.9, -0.8)}
STEP = 0.1


def write(tmp: Path, goal: str, domain: str = DOMAIN, name: str = "tour") -> Path:
    """Domain, scene and a problem with the given goal body; returns the problem's path."""
    (tmp / "domain.pntc").write_text(domain)
    scene = {"name": name, "dimension": 2, "workspace": [[-2, -2], [2, 2]],
             "robots": {"r": {"kind": "planar", "home": [0, 0, 0], "shape": {"circle": 0.03}}},
             "objects": {p: {"pose": [x, y, 0.0]} for p, (x, y) in PLACES.items()}}
    (tmp / f"{name}.yaml").write_text(yaml.safe_dump(scene))
    (tmp / f"{name}.pntc").write_text(
        f'problem {name} for delivery\nscene "{name}.yaml"\n'
        f"objects {{ r : robot  p0..p4 : place }}\ninit {{ at(r) = p0 }}\ngoal {{ {goal} }}\n")
    return tmp / f"{name}.pntc"
