"""example-robot-data model names -> their URDF and SRDF files, without importing pinocchio.

Why its own module below `geometry`: the scene loader checks a robot's `links:` against its
URDF's text when `gnpp check` runs, which must import no heavy library (not even numpy), and the
geometry layer loads the same files into pinocchio; both resolve a `model:` name here.
"""
from __future__ import annotations

import os
import sys
import sysconfig

from gnppdsl.errors import UserError

# example-robot-data names -> path below `<share>/example-robot-data/robots/` (URDF, SRDF).
_KNOWN = {
    "panda": ("panda_description/urdf/panda.urdf", "panda_description/srdf/panda.srdf"),
    "panda_collision": ("panda_description/urdf/panda_collision.urdf", "panda_description/srdf/panda.srdf"),
    "ur3": ("ur_description/urdf/ur3_robot.urdf", None),
    "ur5": ("ur_description/urdf/ur5_robot.urdf", "ur_description/srdf/ur5.srdf"),
    "ur10": ("ur_description/urdf/ur10_robot.urdf", None),
    "kinova": ("kinova_description/robots/kinova.urdf", "kinova_description/srdf/kinova.srdf"),
    "z1": ("z1_description/urdf/z1.urdf", "z1_description/srdf/z1.srdf"),
    "xarm7": ("xarm_description/urdf/xarm7.urdf", "xarm_description/srdf/xarm7.srdf"),
    "tiago": ("tiago_description/robots/tiago.urdf", None),
    "pr2": ("pr2_description/urdf/pr2.urdf", "pr2_description/srdf/pr2.srdf"),
    "double_pendulum": ("double_pendulum_description/urdf/double_pendulum.urdf", None),
    "double_pendulum_continuous": ("double_pendulum_description/urdf/double_pendulum_continuous.urdf", None),
}


def robot_data_share() -> str:
    """`<site-packages>/cmeel.prefix/share`, where example-robot-data installs its files.
    Looked up in the interpreter's paths first and only then next to pinocchio, so that
    `gnpp check` (scene `links:`, gnppdsl.ir.scene) finds a model's URDF without importing it."""
    candidates = []
    for key in ("purelib", "platlib"):
        candidates.append(os.path.join(sysconfig.get_paths()[key], "cmeel.prefix", "share"))
    for p in sys.path:
        candidates.append(os.path.join(p, "cmeel.prefix", "share"))
    for c in candidates:
        if os.path.isdir(os.path.join(c, "example-robot-data", "robots")):
            return c
    try:
        import pinocchio as pin
        # .../site-packages/cmeel.prefix/lib/python3.X/site-packages/pinocchio/__init__.py
        c = os.path.normpath(os.path.join(os.path.dirname(pin.__file__), "..", "..", "..", "..", "share"))
        if os.path.isdir(os.path.join(c, "example-robot-data", "robots")):
            return c
    except ImportError:  # pragma: no cover - pinocchio is a hard dependency
        pass
    raise UserError("example-robot-data is not installed (no cmeel.prefix/share/example-robot-data found); "
                    "install it with `pip install example-robot-data` or give the robot a `urdf:` path")


def resolve_model_files(name: str) -> tuple[str, str | None, str]:
    """An example-robot-data model name -> (urdf path, srdf path or None, package dir)."""
    share = robot_data_share()
    root = os.path.join(share, "example-robot-data", "robots")
    if name in _KNOWN:
        urdf_rel, srdf_rel = _KNOWN[name]
        urdf = os.path.join(root, urdf_rel)
        srdf = os.path.join(root, srdf_rel) if srdf_rel else None
    else:
        # Generic lookup: <x>_description/{urdf,robots}/<name>.urdf
        urdf = srdf = None
        for d in sorted(os.listdir(root)):
            for sub in ("urdf", "robots"):
                p = os.path.join(root, d, sub, name + ".urdf")
                if os.path.isfile(p):
                    urdf = p
                    s = os.path.join(root, d, "srdf", name + ".srdf")
                    srdf = s if os.path.isfile(s) else None
                    break
            if urdf:
                break
        if urdf is None:
            known = ", ".join(sorted(_KNOWN))
            raise UserError(f"unknown robot model '{name}' (example-robot-data has no {name}.urdf; known: {known})")
    if not os.path.isfile(urdf):
        raise UserError(f"robot model '{name}': URDF not found at {urdf}")
    if srdf is not None and not os.path.isfile(srdf):
        srdf = None
    return urdf, srdf, share


def default_locked(model_name: str | None) -> dict[str, float]:
    """The joints locked when a scene robot gives no `locked:`: a Panda's two finger joints,
    open (planning moves the arm; the gripper's width is fixed). One rule, read both by the
    geometry layer that builds the reduced model and by the scene check that counts the
    configuration's coordinates against `home`."""
    if model_name and model_name.startswith("panda"):
        return {"panda_finger_joint1": 0.04, "panda_finger_joint2": 0.04}
    return {}
