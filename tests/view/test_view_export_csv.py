"""`gnpp export RESULT --csv DIR`: per-robot joint trajectories round-trip (read back, compared
with the JSON's keyframes and waypoints), times are those of the JSON and increase, the speeds
they imply stay within the URDF velocity limits read from pinocchio; the JSON's world poses of
the lab agree with pinocchio forward kinematics composed along the state's parent chain (the
independent verifier's `_World`, which goes through neither casadi nor the factory)."""
from __future__ import annotations

import numpy as np
import pytest

from gnppdsl.cli.main import main
from gnppdsl.solve.timing import VELOCITY_SCALE
from gnppdsl.view.export import read_csv


@pytest.mark.parametrize("problem", ["lab/lab1.pntc", "planar/p3_occupied.pntc"])
def test_csv_round_trip(solved_json, problem, tmp_path):
    data = solved_json(problem)
    assert main(["export", data["_path"], "--csv", str(tmp_path / "csv")]) == 0
    for robot, info in data["robots"].items():
        t = read_csv(tmp_path / "csv" / f"{robot}.csv")
        assert t.joints == info["joints"] == data["coordinates"][info["configuration"]]
        assert all(b > a for a, b in zip(t.times, t.times[1:]))
        expected = [(data["steps"][0]["time"], data["steps"][0]["values"][info["configuration"]])]
        for prev, st in zip(data["steps"], data["steps"][1:]):
            traj = info.get("trajectory")
            if traj and traj in prev["trajectories"]:
                expected += list(zip(prev["trajectory_times"][traj][1:], prev["trajectories"][traj][1:]))
            else:
                expected.append((st["time"], st["values"][info["configuration"]]))
        assert len(t.times) == len(expected)
        for (te, qe), tr, qr in zip(expected, t.times, t.positions):
            assert tr == te and qr == qe          # exact: repr round-trips floats
        # every keyframe configuration is a row at its keyframe's time (a trajectory's last
        # waypoint is its keyframe within the solver's tolerance)
        rows = dict(zip(t.times, t.positions))
        for st in data["steps"]:
            assert np.allclose(rows[st["time"]], st["values"][info["configuration"]], atol=1e-6)


def test_export_refuses_to_overwrite_and_bad_input(solved_json, tmp_path, capsys):
    data = solved_json("lab/lab1.pntc")
    assert main(["export", data["_path"], "--csv", str(tmp_path)]) == 0
    assert main(["export", data["_path"], "--csv", str(tmp_path)]) == 2
    assert "--force" in capsys.readouterr().err
    assert main(["export", data["_path"], "--csv", str(tmp_path), "--force"]) == 0
    broken = tmp_path / "broken.json"
    broken.write_text('{"status": "solved",\n "steps": [}\n')
    assert main(["export", str(broken), "--csv", str(tmp_path)]) == 2
    assert f"{broken}:2:" in capsys.readouterr().err
    unsolved = solved_json("planar/t2_unreachable.pntc")
    assert main(["export", unsolved["_path"], "--csv", str(tmp_path)]) == 2
    assert "not solved" in capsys.readouterr().err


def test_times_respect_the_velocity_limits(solved_json, tmp_path):
    from gnppdsl.geometry.robots import load_robot
    from gnppdsl.ir import load_problem

    data = solved_json("lab/lab1.pntc")
    main(["export", data["_path"], "--csv", str(tmp_path)])
    scene = load_problem(data["inputs"]["problem"]).scene
    fastest = 0.0
    for robot in data["robots"]:
        model = load_robot(scene.robots[robot]).model
        vmax = np.array([model.velocityLimit[model.joints[model.getJointId(j)].idx_v]
                         for j in data["robots"][robot]["joints"]])
        t = read_csv(tmp_path / f"{robot}.csv")
        q = np.array(t.positions)
        speed = np.abs(np.diff(q, axis=0)) / np.diff(t.times)[:, None]
        assert np.all(speed <= vmax + 1e-9)
        fastest = max(fastest, float(np.max(speed / vmax)))
    # not needlessly slow: the limiting joint of some segment moves at the timing speed
    assert fastest == pytest.approx(VELOCITY_SCALE, rel=1e-6)


def test_lab_world_poses_match_pinocchio_chain(solved_json):
    from gnppdsl.geometry.context import GeometryContext
    from gnppdsl.geometry.robots import matrix_to_se3
    from gnppdsl.ir import load_problem
    from gnppdsl.solve.verify_solution import _FACT, _World

    data = solved_json("lab/lab1.pntc")
    scene = load_problem(data["inputs"]["problem"]).scene
    ctx = GeometryContext(scene)
    for st in data["steps"]:
        parents = {o: p for var, o, p in _FACT.findall(st["state"]) if var == "parent"}
        poses = {o: np.array(st["values"][f"pose({o})"]) for o in parents}
        configs = {r: np.array(st["values"][f"q({r})"]) for r in data["robots"]}
        w = _World(ctx, parents, poses, configs)
        assert set(st["world"]) == set(parents)
        for o, pose in st["world"].items():
            ref = matrix_to_se3(w.matrix(o))
            assert np.allclose(pose[:3], ref[:3], atol=1e-9)
            assert abs(abs(np.dot(pose[3:], ref[3:])) - 1) < 1e-9     # same rotation (q ~ -q)


@pytest.mark.parametrize("field, value", [
    ("plan", "pick(b1)"),
    ("conflicts", [{"text": "x", "source": "nlp", "named": [[["parent(b1)"]]], "factors": []}]),
    ("conflicts", [{"text": "x", "source": "nlp", "named": [], "factors": [3]}]),
    ("conflicts", ["not a conflict"]),
])
def test_view_and_export_refuse_a_misshapen_result(solved_json, tmp_path, capsys, field, value):
    """An edited result whose plan or conflicts are not of the schema's shape: a message naming
    the field and exit 2 (they were a ValueError / AttributeError / KeyError traceback)."""
    import json

    data = {k: v for k, v in solved_json("planar/p3_occupied.pntc").items() if k != "_path"}
    data[field] = value
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(data))
    assert main(["view", str(bad), "--html", str(tmp_path / "page.html")]) == 2
    assert f"`{field}" in capsys.readouterr().err
    assert main(["export", str(bad), "--csv", str(tmp_path / "csv")]) == 2
    assert not (tmp_path / "page.html").exists()
