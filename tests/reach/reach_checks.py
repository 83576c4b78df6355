"""Independent checks for the reach tests: pinocchio's own geometry placements and direct coal
calls on the robot's *individual* collision shapes (the graph uses one merged hull per link),
so a bug in gnppdsl.reach.collision cannot hide itself."""
from __future__ import annotations

import dataclasses

import numpy as np
import pinocchio as pin

from gnppdsl.geometry.robots import se3_to_matrix
from gnppdsl.geometry.shapes import coal_shape
from gnppdsl.ir.scene import load_scene_file
from gnppdsl.ir.scene_model import SceneObject, SceneShape

LAB = "examples/lab/lab.yaml"
# in front of the left arm of the Lab scene (base at x = -0.4, y = -0.3 on the table top z = 0.6)
LEFT_BOX = ((-0.85, -0.05, 0.66), (0.05, 0.5, 1.0))


def lab_scene_with_wall(root):
    """The Lab scene plus a static wall between the left and the right half of the left arm's
    reach: paths from x = -0.75 to x = -0.15 must go over it, so some k-NN edges collide."""
    sc = load_scene_file(root / LAB)
    wall = SceneObject("wall", SceneShape("box", (0.04, 0.4, 0.25)), (-0.45, 0.35, 0.725, 0.0, 0.0, 0.0, 1.0),
                       static=True)
    return dataclasses.replace(sc, objects={**sc.objects, "wall": wall})


def fk_position(robot, q, frame):
    data = robot.model.createData()
    pin.framesForwardKinematics(robot.model, data, robot.to_pin_q(q))
    return (robot.base @ np.array(data.oMf[robot.model.getFrameId(frame)].homogeneous))[:3, 3]


class IndependentChecker:
    """Minimum signed distance of a robot configuration to the static scene objects and to itself."""

    def __init__(self, robot, scene):
        import coal
        self.coal = coal
        self.robot = robot
        ign = {frozenset(p) for p in scene.ignore_collisions}
        self.obstacles = [(n, coal_shape(o.shape), se3_to_matrix(o.pose)) for n, o in scene.objects.items()
                          if o.static and o.shape.kind != "none" and frozenset((robot.name, n)) not in ign]
        self.req = coal.DistanceRequest()
        self.req.enable_signed_distance = True

    def _tf(self, T):
        return self.coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))

    def min_distance(self, q) -> float:
        r = self.robot
        data = r.model.createData()
        gdata = pin.GeometryData(r.geom)
        pin.framesForwardKinematics(r.model, data, r.to_pin_q(q))
        pin.updateGeometryPlacements(r.model, data, r.geom, gdata)
        best = np.inf
        for k, go in enumerate(r.geom.geometryObjects):
            if r.model.frames[go.parentFrame].name in r.fixed_links:
                continue      # the Panda's link0 stands on the table
            W = r.base @ np.array(gdata.oMg[k].homogeneous)
            for _, s, T in self.obstacles:
                res = self.coal.DistanceResult()
                best = min(best, self.coal.distance(go.geometry, self._tf(W), s, self._tf(T), self.req, res))
        pin.computeDistances(r.model, data, r.geom, gdata, r.to_pin_q(q))
        for dr in gdata.distanceResults:
            best = min(best, dr.min_distance)
        return float(best)

    def segment_min_distance(self, q1, q2, n: int) -> float:
        return min(self.min_distance(q1 + t * (q2 - q1)) for t in np.linspace(0.0, 1.0, n))
