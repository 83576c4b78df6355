"""gnppdsl.geometry: robots, forward kinematics, signed distances, verification, pictures.

Modules (import them directly; this package imports nothing heavy so the CLI stays fast):
- `robots`: `load_robot(SceneRobot) -> RobotModel` (pinocchio model, convex link shapes, SRDF pairs)
- `kinematics`: `fk_expression`, `fk_function` (casadi FK, checked against pinocchio)
- `shapes`: scene shapes -> convex coal shapes (planar scenes: extruded in z)
- `distance`: coal signed distance inside casadi (a stop-gradient callback around a local model)
- `features`: the local contact model (face/edge/vertex/sphere): exact gradients and Hessians
- `context`: `GeometryContext`, the nlp layer's geometry protocol for one scene
- `verify`: independent checks with pinocchio + coal (distances, limits, grasps, support)
- `render`: `render_keyframes` (PNG, top/front orthographic views)
- `ik`: `solve_ik` (ipopt with random restarts)
"""
