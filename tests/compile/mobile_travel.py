"""A copy of the mobile sorting example (examples/mobile) whose action costs call the
reachability graph's travel, written to a temporary directory by the travel-cost tests of the
compile and solve layers; and the scene's numbers read from the YAML files themselves (not
through the scene loader), for the tests' oracles."""
from __future__ import annotations

import math
import shutil
from pathlib import Path

import yaml

MOBILE = Path(__file__).resolve().parents[2] / "examples" / "mobile"

PICK_COST = "cost 0.5 + travel_lb(r, from, o)"
DROP_COST = "cost 1 + travel(r, o, to)"
W_X = 2.0          # the block's w_x, changed from the example's 1.0 so that it shows in the costs

# each item in one of the two trays, whichever: the planner chooses by the costs
EITHER_TRAY = ("problem either for sorting\nscene \"sorting.yaml\"\n"
               "objects { mm : robot  center, red_table, blue_table : table  red_tray, blue_tray : tray"
               "  red1, blue1 : item }\n"
               "init { parent(red1) = center  parent(blue1) = center  holding(mm) = none }\n"
               "goal { (parent(red1) = red_tray or parent(red1) = blue_tray)\n"
               "       (parent(blue1) = red_tray or parent(blue1) = blue_tray) }\n")


def write(tmp: Path, pick: str = PICK_COST, drop: str = DROP_COST, block: bool = True) -> Path:
    """The example with the given `cost` lines of pick and drop (and w_x = W_X), or without its
    reachability block; returns the directory (domain.pntc, sort2.pntc, either.pntc)."""
    for f in ("domain.pntc", "sort2.pntc", "sorting.yaml", "sorting_setting.yaml"):
        shutil.copy(MOBILE / f, tmp / f)
    dom = (tmp / "domain.pntc").read_text()
    parts = dom.split("  cost 1\n")
    assert len(parts) == 3, "the example's pick and drop each end with `cost 1`"
    dom = parts[0] + f"  {pick}\n" + parts[1] + f"  {drop}\n" + parts[2]
    assert "weights = [1.0, 0.5, 0.1]" in dom
    dom = dom.replace("weights = [1.0, 0.5, 0.1]", f"weights = [{W_X}, 0.5, 0.1]")
    if not block:
        dom = dom[:dom.index("reachability reach {")]
    (tmp / "domain.pntc").write_text(dom)
    (tmp / "either.pntc").write_text(EITHER_TRAY)
    return tmp


def scene_xy(tmp: Path) -> dict[str, tuple[float, float]]:
    """Each scene object's (x, y), from the YAML files (the scene and the setting it includes)."""
    scene = yaml.safe_load((tmp / "sorting.yaml").read_text())
    setting = yaml.safe_load((tmp / scene["include"]).read_text())
    objects = {**setting["objects"], **scene["objects"]}
    return {name: tuple(float(v) for v in o["pose"]["xyz"][:2]) for name, o in objects.items()}


def lower_bound(xy: dict, a: str, b: str) -> float:
    """travel_lb by hand: w_x times the horizontal distance of the two scene positions."""
    return W_X * math.dist(xy[a], xy[b])


def arguments(op_name: str) -> list[str]:
    return [x.strip() for x in op_name[op_name.index("(") + 1:-1].split(",")]
