"""Settings of a reachability graph (paper 002, Sec. IV) in one dataclass.

Why separate from the IR's `Reachability` block: the graph is also built from Python (tests,
benchmarks, the solve loop with CLI overrides) without a `.pntc` file, and it needs a few knobs the
language does not expose (collision margin, enhancement budget). `from_block` maps the IR block;
everything else keeps its default.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, replace

from gnppdsl.errors import UserError


@dataclass(frozen=True)
class ReachSettings:
    """Parameters of `ReachabilityGraph`.

    robot          scene robot name (must be a URDF robot)
    frame          end-effector frame whose *position* the nodes describe (orientation is free,
                   as in the paper: the full trajectory optimisation adds orientation later)
    workspace      (lower xyz, upper xyz) box of the uniform node distribution U(p_min, p_max)
    samples        N_node: number of IK-validated nodes of the pre-built graph
    max_draws      give up after this many uniform draws (default 20 * samples): a fixed arm
                   cannot reach most of a large box
    neighbours     k of the k-nearest-neighbour edges (nearest in end-effector position)
    weights        (w_x, w_q, w_c) of the edge cost, Eq. 3
    interpolation  L: joint-space configurations checked for collision inside an edge; long
                   edges get more so that no two consecutive checks are more than
                   `max_joint_step` apart (any coordinate)
    ik_restarts    random restarts of the node-validating IK (Eq. 2) after the seeded attempts
    ik_tolerance   position error (m) accepted by the IK
    margin         clearance (m) demanded of nodes and edge configurations against obstacles
    self_collision check the robot's SRDF-filtered self-collision pairs too
    obstacles      scene objects the graph avoids; None: every static object of the scene
    enhance_rounds / enhance_samples / enhance_sigma / enhance_decay
                   Gaussian enhancement (Sec. IV-B2): rounds with `enhance_samples` draws each,
                   standard deviation `enhance_sigma` (m) shrinking by `enhance_decay` per round
    snap_radius    a query end within this distance (m) of an existing node uses that node
                   instead of a new IK-solved one (0: only exact matches)
    seed           all randomness (uniform draws, IK restarts, enhancement) comes from it
    """

    robot: str
    frame: str | None = None
    workspace: tuple[tuple[float, float, float], tuple[float, float, float]] = ((-1.0, -1.0, 0.0), (1.0, 1.0, 1.0))
    samples: int = 200
    max_draws: int | None = None
    neighbours: int = 8
    weights: tuple[float, float, float] = (1.0, 0.5, 0.1)
    interpolation: int = 10
    max_joint_step: float = 0.05
    ik_restarts: int = 5
    ik_tolerance: float = 1e-3
    margin: float = 0.005
    self_collision: bool = True
    obstacles: tuple[str, ...] | None = None
    enhance_rounds: int = 4
    enhance_samples: int = 6
    enhance_sigma: float = 0.15
    enhance_decay: float = 0.6
    snap_radius: float = 0.0
    seed: int = 0

    def __post_init__(self) -> None:
        lo, hi = self.workspace
        if len(lo) != 3 or len(hi) != 3:
            raise UserError(f"reachability for '{self.robot}': the workspace must be a 3-D box "
                            f"[[x, y, z], [x, y, z]], got {list(lo)}, {list(hi)}")
        if any(a > b for a, b in zip(lo, hi)):
            raise UserError(f"reachability for '{self.robot}': workspace lower bound {list(lo)} exceeds upper {list(hi)}")
        if self.samples < 1 or self.neighbours < 1 or self.interpolation < 1:
            raise UserError(f"reachability for '{self.robot}': samples, neighbours and interpolation must be >= 1")
        if len(self.weights) != 3 or any((not math.isfinite(w)) or w < 0 for w in self.weights):
            raise UserError(f"reachability for '{self.robot}': weights are three numbers >= 0 (w_x, w_q, w_c)")
        if self.ik_tolerance <= 0 or self.ik_restarts < 0:
            raise UserError(f"reachability for '{self.robot}': ik_tolerance > 0 and ik_restarts >= 0 needed")

    @property
    def draws(self) -> int:
        return self.max_draws if self.max_draws is not None else 20 * self.samples

    def merged(self, **overrides) -> "ReachSettings":
        """A copy with the given fields replaced (None values are ignored)."""
        return replace(self, **{k: v for k, v in overrides.items() if v is not None})

    @staticmethod
    def from_block(block, scene=None, **overrides) -> "ReachSettings":
        """Map an IR `gnppdsl.ir.model.Reachability` block to settings.

        `frame` defaults to the scene robot's `ee`, `workspace` to the scene's workspace."""
        frame = block.frame
        workspace = block.workspace
        if scene is not None:
            spec = scene.robots.get(block.robot)
            if frame is None and spec is not None:
                frame = spec.ee
            if workspace is None:
                workspace = scene.workspace
        if workspace is None:
            raise UserError(f"reachability '{block.name}': no workspace (set `workspace = [[...], [...]]` "
                            "in the block or `workspace:` in the scene)")
        kw = dict(robot=block.robot, frame=frame,
                  workspace=(tuple(float(v) for v in workspace[0]), tuple(float(v) for v in workspace[1])),
                  samples=int(block.samples), neighbours=int(block.neighbours),
                  weights=tuple(float(w) for w in block.weights), interpolation=int(block.interpolation),
                  ik_restarts=int(block.ik_restarts), ik_tolerance=float(block.ik_tolerance), seed=int(block.seed))
        kw.update({k: v for k, v in overrides.items() if v is not None})
        return ReachSettings(**kw)
