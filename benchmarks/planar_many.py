"""A planar problem with many blocks and a short goal: the grounding-scale test of issue 19.

`python benchmarks/planar_many.py N DIR` writes DIR/many_N.pntc and DIR/many_N.yaml (domain:
examples/planar/domain.pntc, copied next to them): N discs on N spots in a grid on the left
half, two free regions on the right, one gripper; the goal moves b1 into region ra (two actions:
pick, place), so all but one block are irrelevant to the goal. The problem itself uses the
language's ranges and quantified facts; only the scene (N positions) is generated.
"""
from __future__ import annotations

import math
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def write_problem(n: int, directory: Path, goal_blocks: int = 1) -> Path:
    directory.mkdir(parents=True, exist_ok=True)
    shutil.copy(ROOT / "examples/planar/domain.pntc", directory / "domain.pntc")
    cols = max(1, math.ceil(math.sqrt(n)))
    step = 0.9 / cols
    radius = min(0.05, 0.4 * step)
    lines = [f"# {n} blocks on spots in a {cols}-column grid, two regions, one gripper",
             f"name: many_{n}", "dimension: 2", "workspace: [[-1, -1], [1, 1]]", "robots:",
             "  g: {kind: planar, home: [0, 0, 0], shape: {circle: 0.03}, reach_min: [-1, -1], reach_max: [1, 1]}",
             "objects:"]
    for i in range(n):
        x = -0.95 + step * (i % cols + 0.5)
        y = -0.45 + step * (i // cols + 0.5)
        lines.append(f"  s{i + 1}: {{pose: [{x:.4f}, {y:.4f}, 0.0]}}")
        lines.append(f"  b{i + 1}: {{shape: {{circle: {radius:.4f}}}, pose: [{x:.4f}, {y:.4f}, 0.0], "
                     f"radius: {radius:.4f}, color: red}}")
    for name, y in (("ra", 0.3), ("rb", -0.3)):
        lines.append(f"  {name}: {{shape: box, size: [0.3, 0.3, 0.01], pose: [0.5, {y}, 0.0], "
                     f"half_extent: [0.15, 0.15], static: true, color: yellow}}")
    (directory / f"many_{n}.yaml").write_text("\n".join(lines) + "\n")
    goal = "parent(b1) = ra" if goal_blocks == 1 else f"forall i in 1..{goal_blocks} . parent(b{{i}}) = ra"
    (directory / f"many_{n}.pntc").write_text(
        f"# {n} blocks, goal: {goal} (pick and place {goal_blocks} block(s))\n"
        f"problem many_{n} for planar_blocks\n"
        f'scene "many_{n}.yaml"\n'
        f"objects {{ b1..b{n} : block  s1..s{n} : spot  ra, rb : region  g : gripper }}\n"
        f"init {{ forall i in 1..{n} . parent(b{{i}}) = s{{i}}  holding(g) = none }}\n"
        f"goal {{ {goal} }}\n")
    return directory / f"many_{n}.pntc"


if __name__ == "__main__":
    print(write_problem(int(sys.argv[1]), Path(sys.argv[2])))
