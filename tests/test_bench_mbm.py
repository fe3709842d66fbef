"""``prehensile bench mbm`` and the benchmarking package on a few MotionBenchMaker problems."""

from __future__ import annotations

import importlib.util
import json
import tarfile
from pathlib import Path

import numpy as np
import pytest
from conftest import MBM, require_shared
from typer.testing import CliRunner

from prehensile.benchmarking import ratio, time_summary
from prehensile.benchmarking.mbm import (
    MBMSettings, PreparedProblem, _ends_as_asked, benchmark_spheres, load_problems, summarize,
)
from prehensile.cli.main import app
from prehensile.errors import PrehensileError

PROBLEMS = {"table_pick_panda": 1, "box_panda": 1}  # start and goal free on the padded spheres
runner = CliRunner()


@pytest.fixture(scope="module")
def problem_dir(tmp_path_factory) -> Path:
    """Two scene/request pairs extracted from the MBM archive, in their scenario folders."""
    panda = require_shared(MBM / "panda")
    out = tmp_path_factory.mktemp("mbm")
    with tarfile.open(panda / "problems.tar.bz2") as archive:
        for member in archive.getmembers():
            path = Path(member.name)
            if member.isfile() and PROBLEMS.get(path.parent.name) is not None and path.stem.endswith(
                    f"{PROBLEMS[path.parent.name]:04d}"):
                target = out / path.parent.name / path.name
                target.parent.mkdir(exist_ok=True)
                target.write_bytes(archive.extractfile(member).read())
    assert len(list(out.rglob("*.yaml"))) == 2 * len(PROBLEMS)
    return out


def _bench(problem_dir: Path, tmp_path: Path, *extra: str) -> dict:
    panda = MBM / "panda"
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(problem_dir), "--robot", str(panda / "panda.urdf"),
                                 "--srdf", str(panda / "panda.srdf"), "--spheres", str(panda / "panda_spherized.urdf"),
                                 "--budget", "2", "--seed", "3", "--json", str(out), *extra])
    assert result.exit_code == 0, result.output
    assert "overall" in result.output and "table_pick_panda" in result.output
    assert ("OMPL" in result.output) == ("--compare-ompl" in extra), result.output
    return json.loads(out.read_text())


def _check_summary(summary: dict, total: int) -> None:
    assert summary["total"] == total
    assert 0 <= summary["solved"] <= summary["total"]
    assert sum(summary["statuses"].values()) == total
    if summary["solved"]:
        assert 0 < summary["median_ms"] <= summary["p95_ms"]
        assert summary["path_length"] > 0
        assert 0 <= summary["colliding_paths"] <= summary["solved"]
        assert 0 <= summary["planned_again"] <= summary["total"]


def test_bench_mbm_ours(problem_dir, tmp_path):
    report = _bench(problem_dir, tmp_path)
    assert set(report) >= {"overall", "scenarios", "ompl", "ratios", "machine", "versions", "runs", "settings"}
    assert report["ompl"] is None and report["ratios"] is None
    assert set(report["scenarios"]) == set(PROBLEMS)
    _check_summary(report["overall"], len(PROBLEMS))
    for summary in report["scenarios"].values():
        _check_summary(summary, 1)
    overall = report["overall"]
    assert overall["solved"] == len(PROBLEMS)  # easy problems, 2 s each
    assert overall["colliding_paths"] == 0  # ours are certified on the exact meshes
    assert overall["ends_elsewhere"] == 0 and all(run["ours"]["ends_as_asked"] for run in report["runs"])
    assert overall["certify_median_ms"] > 0
    assert report["robot"]["joints"] == [f"panda_joint{i}" for i in range(1, 8)]
    assert report["robot"]["srdf"] == str(MBM / "panda" / "panda.srdf")
    assert report["versions"]["numpy"] == np.__version__
    assert report["command"].startswith("prehensile bench mbm")


def test_bench_mbm_with_ompl(problem_dir, tmp_path):
    pytest.importorskip("ompl")
    report = _bench(problem_dir, tmp_path, "--compare-ompl", "--limit", "1")
    ompl = report["ompl"]
    _check_summary(ompl["overall"], len(PROBLEMS))
    assert set(ompl["scenarios"]) == set(PROBLEMS)
    assert ompl["validity_call_us"] > 0 and 0 < ompl["segment_fraction"] < 1
    ratios = report["ratios"]
    assert ratios["paired_problems"] <= min(report["overall"]["solved"], ompl["overall"]["solved"])
    if ratios["paired_problems"]:
        assert ratios["median_speedup"] > 0 and ratios["paired_median_speedup"] > 0
    assert ompl["overall"]["certify_median_ms"] is None  # OMPL does not certify
    assert ompl["overall"]["ends_elsewhere"] == 0
    for run in report["runs"]:
        assert run["ompl"]["solved"] == (run["ompl"]["status"] == "success") and run["ompl"]["certify_s"] is None


ARMAR_PROBLEMS = [  # RightArm start and goal (rad) under a shelf board above a table, beside a post
    ((0.208, 0.625, 0.904), [-0.957, 0.992, 1.119, 0.381, -0.33, -0.274, 0.562],
     [0.582, 1.094, -1.298, 0.447, 1.271, -0.166, -0.054]),
    ((0.26, 0.668, 0.938), [0.602, 1.62, -0.042, 0.446, 0.83, 0.25, 0.739],
     [0.31, 1.568, -0.976, -0.077, 1.531, -0.167, -0.467]),
]


def _write_armar_problems(folder: Path) -> None:
    """MoveIt scene/request YAML pairs in MotionBenchMaker's layout for ARMAR-III's right arm."""
    import yaml

    from prehensile import robots

    model = robots.load("armar3")
    arm = [model.joint_names[i] for i in model.chain_q_indices("RightArm")]
    folder.mkdir(parents=True)
    neutral = {"name": list(model.joint_names), "position": model.neutral_configuration().tolist()}
    for k, (table, start, goal) in enumerate(ARMAR_PROBLEMS, 1):
        boxes = {"table": ((0, 0, 0), (0.6, 0.5, 0.04)), "board": ((0, 0.05, 0.5), (0.5, 0.3, 0.02)),
                 "post": ((0.3, 0, 0.25), (0.04, 0.04, 0.5))}
        scene = {"name": f"shelf{k}", "robot_model_name": model.name, "robot_state": {"joint_state": neutral},
                 "world": {"collision_objects": [
                     {"id": name, "primitives": [{"type": "box", "dimensions": list(size)}],
                      "primitive_poses": [{"position": np.add(table, offset).tolist(), "orientation": [0, 0, 0, 1]}]}
                     for name, (offset, size) in boxes.items()]}}
        start_state = dict(neutral, position=[dict(zip(arm, start)).get(n, v) for n, v in zip(*neutral.values())])
        request = {"group_name": "RightArm", "start_state": {"joint_state": start_state},
                   "goal_constraints": [{"joint_constraints": [{"joint_name": n, "position": v}
                                                               for n, v in zip(arm, goal)]}]}
        (folder / f"scene{k:04d}.yaml").write_text(yaml.safe_dump(scene))
        (folder / f"request{k:04d}.yaml").write_text(yaml.safe_dump(request))


def _bench_armar(tmp_path: Path, *options: str) -> tuple:
    """``bench mbm`` on the ARMAR-III problems in tmp_path / "problems" with ``options``; (CLI result, report)."""
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--json", str(out),
                                 *options])
    assert result.exit_code == 0, result.output
    return result, json.loads(out.read_text())


def test_bench_mbm_another_robot_with_generated_balls(tmp_path):
    """Any robot with an SRDF group: ARMAR-III's right arm, balls generated from its meshes."""
    _write_armar_problems(tmp_path / "problems" / "shelf_armar3")
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3",
                                 "--budget", "2", "--json", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    _check_summary(report["overall"], len(ARMAR_PROBLEMS))
    assert report["overall"]["solved"] == len(ARMAR_PROBLEMS)
    assert report["overall"]["colliding_paths"] == 0
    assert report["robot"]["joints"] == ["Shoulder_1_R", "Shoulder_2_R", "Upperarm_R", "Elbow_R", "Underarm_R",
                                         "Wrist_1_R", "Wrist_2_R"]
    assert report["robot"]["cover_spheres"] is None  # generated balls cover the meshes already
    assert all(run["ours"]["waypoints"] > 2 for run in report["runs"])  # the straight motion is blocked


@pytest.mark.parametrize("planner, position_tolerance, rotation_tolerance", [("ik_rrt", 1e-4, 1e-3),
                                                                             ("jplus_rrt", 1e-3, 1e-2)])
def test_pose_planners_reach_the_goal_pose(tmp_path, planner, position_tolerance, rotation_tolerance):
    """IK-RRT and J+-RRT plan to the pose the goal configuration gives the group's tip."""
    _write_armar_problems(tmp_path / "problems" / "shelf_armar3")
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--planner",
                                 planner, "--budget", "5", "--json", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    overall = report["overall"]
    _check_summary(overall, len(ARMAR_PROBLEMS))
    assert overall["solved"] == len(ARMAR_PROBLEMS) and overall["colliding_paths"] == 0
    assert overall["certify_median_ms"] > 0
    assert report["settings"]["planner"] == planner and f"{planner} on" in result.output
    for run in report["runs"]:
        assert run["ours"]["goal_error_m"] <= position_tolerance and run["ours"]["goal_error_rad"] <= rotation_tolerance
    assert overall["goal_error_m_max"] == max(run["ours"]["goal_error_m"] for run in report["runs"])


@pytest.mark.parametrize("planner", ["rrt_connect", "ik_rrt"])
def test_alternative_joint_goals_are_a_goal_set(tmp_path, planner):
    """MoveIt's goal_constraints are alternatives: the first goal here lies beyond a joint limit,
    so every planner must end at the second (rrt_connect and OMPL exactly; IK-RRT at a pose
    of one of them)."""
    import yaml

    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    for path in sorted(folder.glob("request*.yaml")):
        request = yaml.safe_load(path.read_text())
        (goal,) = request["goal_constraints"]
        beyond = {"joint_constraints": [dict(c, position=c["position"] + (9.0 if k == 0 else 0.0))
                                        for k, c in enumerate(goal["joint_constraints"])]}
        request["goal_constraints"] = [beyond, goal]
        path.write_text(yaml.safe_dump(request))
    ompl = ["--compare-ompl"] if planner == "rrt_connect" and importlib.util.find_spec("ompl") else []
    _, report = _bench_armar(tmp_path, "--planner", planner, "--budget", "5", *ompl)
    assert report["overall"]["solved"] == len(ARMAR_PROBLEMS) and report["overall"]["ends_elsewhere"] == 0
    if ompl:
        assert report["ompl"]["overall"]["solved"] == len(ARMAR_PROBLEMS)
        assert report["ompl"]["overall"]["ends_elsewhere"] == 0
    if planner == "ik_rrt":
        assert report["overall"]["goal_error_m_max"] <= 1e-4


def _pose_goal_requests(folder: Path) -> None:
    """Turn the ARMAR-III requests into pose goals where their goal configurations put TCP_R:
    request 1 a point 5 cm along TCP_R's z axis within a 1 mm sphere, the orientation within
    0.01 rad (XYZ Euler angles), in the frame of the arm's base link (written "/Right_Arm_Base");
    request 2 the TCP's position alone in a 2 cm box (world frame), given as a point of the hand
    base link, which is fixed to TCP_R."""
    import yaml
    from scipy.spatial.transform import Rotation

    from prehensile import robots
    from prehensile.kinematics import link_pose
    from prehensile.spatial import invert

    model = robots.load("armar3")
    arm = model.chain_q_indices("RightArm")
    offset = np.array([0.0, 0.0, 0.05])
    for k, (_, start, goal) in enumerate(ARMAR_PROBLEMS, 1):
        path = folder / f"request{k:04d}.yaml"
        request = yaml.safe_load(path.read_text())
        q_start, q_goal = model.neutral_configuration(), model.neutral_configuration()
        q_start[arm], q_goal[arm] = start, goal
        T_world_tcp = link_pose(model, q_goal, "TCP_R")
        T_world_base = link_pose(model, q_start, "Right_Arm_Base")
        if k == 1:
            T_base_tcp = invert(T_world_base) @ T_world_tcp
            point = T_base_tcp[:3, :3] @ offset + T_base_tcp[:3, 3]
            header = {"frame_id": "/Right_Arm_Base"}
            constraints = {
                "position_constraints": [{
                    "header": header, "link_name": "TCP_R", "target_point_offset": dict(zip("xyz", offset.tolist())),
                    "constraint_region": {"primitives": [{"type": 2, "dimensions": [0.001]}],
                                          "primitive_poses": [{"position": point.tolist(),
                                                               "orientation": [0, 0, 0, 1]}]}, "weight": 1.0}],
                "orientation_constraints": [{
                    "header": header, "link_name": "TCP_R",
                    "orientation": Rotation.from_matrix(T_base_tcp[:3, :3]).as_quat().tolist(),
                    "absolute_x_axis_tolerance": 0.01, "absolute_y_axis_tolerance": 0.01,
                    "absolute_z_axis_tolerance": 0.01, "parameterization": 0, "weight": 1.0}]}
        else:
            T_hand_tcp = invert(link_pose(model, q_goal, "Hand_R_Base")) @ T_world_tcp
            constraints = {"position_constraints": [{
                "link_name": "Hand_R_Base", "target_point_offset": T_hand_tcp[:3, 3].tolist(),
                "constraint_region": {"primitives": [{"type": "box", "dimensions": [0.02, 0.02, 0.02]}],
                                      "primitive_poses": [{"position": T_world_tcp[:3, 3].tolist()}]}}]}
        request["goal_constraints"] = [constraints]
        path.write_text(yaml.safe_dump(request))


def test_pose_goals_of_moveit_requests_are_met_by_the_pose_planners(tmp_path):
    """MoveIt requests with position and orientation constraints: ik_rrt reaches both (the
    constraints are checked at each path's end), jplus_rrt the one with an orientation;
    rrt_connect has no configuration to plan to and is refused before planning."""
    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    _pose_goal_requests(folder)
    for planner, limit in (("ik_rrt", "0"), ("jplus_rrt", "1")):
        result, report = _bench_armar(tmp_path, "--planner", planner, "--budget", "5", "--limit", limit)
        overall, runs = report["overall"], [run["ours"] for run in report["runs"]]
        assert overall["solved"] == len(runs) == (2 if limit == "0" else 1), (planner, overall)
        assert overall["colliding_paths"] == 0 and overall["goal_unsatisfied"] == 0
        assert all(run["goal_satisfied"] for run in runs)
        assert f"pose goals: {len(runs)} of {len(runs)} paths end within" in " ".join(result.output.split())
        # from the region's centre: within the 2 cm box and 0.01 rad per axis
        assert runs[0]["goal_error_m"] <= np.sqrt(3) * 1e-2 and runs[0]["goal_error_rad"] <= np.sqrt(3) * 1e-2
    assert runs[0]["goal_error_rad"] is not None
    # tolerances no planner meets: the path counts as unsolved, its status stays the planner's
    request = folder / "request0001.yaml"
    request.write_text(request.read_text().replace("_axis_tolerance: 0.01", "_axis_tolerance: 0.0"))
    result, report = _bench_armar(tmp_path, "--planner", "jplus_rrt", "--budget", "5", "--limit", "1")
    overall = report["overall"]
    assert overall["solved"] == 0 and overall["statuses"] == {"success": 1} and overall["goal_unsatisfied"] == 1
    assert "pose goals: 0 of 1 paths end within" in " ".join(result.output.split())
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3"])
    assert result.exit_code == 2
    assert ("request0001.yaml: goal_constraints[0]: a pose goal (position and orientation constraints) needs a pose "
            "planner: ik_rrt or jplus_rrt") in " ".join(result.output.split())
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--planner",
                                 "jplus_rrt"])
    assert result.exit_code == 2 and "request0002.yaml: goal_constraints[0]: jplus_rrt steps toward a full pose" in \
        " ".join(result.output.split())


def test_alternative_pose_goals_are_any_of_them(tmp_path):
    """Each request's pose goal behind an alternative 3 m away (no IK solution, and farther from
    the tool): both pose planners must end within the real one; alternatives on another point
    of the hand are refused, naming the request."""
    import yaml

    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    _pose_goal_requests(folder)
    for path in sorted(folder.glob("request*.yaml")):
        request = yaml.safe_load(path.read_text())
        (goal,) = request["goal_constraints"]
        far = yaml.safe_load(yaml.safe_dump(goal))
        pose = far["position_constraints"][0]["constraint_region"]["primitive_poses"][0]
        pose["position"] = (np.asarray(pose["position"]) + [3.0, 0.0, 0.0]).tolist()
        request["goal_constraints"] = [far, goal]
        path.write_text(yaml.safe_dump(request))
    for planner, limit in (("ik_rrt", "0"), ("jplus_rrt", "1")):
        _, report = _bench_armar(tmp_path, "--planner", planner, "--budget", "5", "--limit", limit)
        runs = [run["ours"] for run in report["runs"]]
        assert report["overall"]["solved"] == len(runs) and all(run["goal_satisfied"] for run in runs), planner
        assert all(run["goal_error_m"] <= np.sqrt(3) * 1e-2 for run in runs)  # from the near goal's centre
    path = folder / "request0002.yaml"
    request = yaml.safe_load(path.read_text())
    request["goal_constraints"][0]["position_constraints"][0]["target_point_offset"] = [0.0, 0.0, 0.0]
    path.write_text(yaml.safe_dump(request))
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--planner",
                                 "ik_rrt"])
    assert result.exit_code == 2
    assert ("request0002.yaml: goal_constraints[1]: constrains another point than goal_constraints[0]"
            in " ".join(result.output.split()))


def test_ik_rrt_aims_anywhere_in_a_pose_goal(tmp_path):
    """IK-RRT samples the whole goal region: request 1's sphere grown to 2 m and its tolerances
    to 3 rad hold the start, which is then the goal (the path stays there); request 2's box
    stretched to 2 m along x from the goal configuration's TCP has its centre out of reach."""
    import yaml

    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    _pose_goal_requests(folder)
    requests = [folder / f"request{k:04d}.yaml" for k in (1, 2)]
    first, second = (yaml.safe_load(path.read_text()) for path in requests)
    position = first["goal_constraints"][0]["position_constraints"][0]
    position["constraint_region"]["primitives"][0]["dimensions"] = [2.0]
    first["goal_constraints"][0]["orientation_constraints"][0].update(
        {f"absolute_{axis}_axis_tolerance": 3.0 for axis in "xyz"})
    region = second["goal_constraints"][0]["position_constraints"][0]["constraint_region"]
    region["primitives"][0]["dimensions"] = [2.0, 0.02, 0.02]
    region["primitive_poses"][0]["position"][0] += 0.99
    for path, request in zip(requests, (first, second)):
        path.write_text(yaml.safe_dump(request))
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--planner",
                                 "ik_rrt", "--budget", "5", "--json", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    runs = [run["ours"] for run in report["runs"]]
    assert report["overall"]["solved"] == 2 and report["overall"]["colliding_paths"] == 0
    assert all(run["goal_satisfied"] for run in runs)
    assert runs[0]["path_length"] == 0.0
    assert runs[1]["goal_error_m"] > 0.1  # far from the region's centre


@pytest.mark.parametrize("edit, message", [
    (("TCP_R", "Right_Arm_Base", 1), "link_name 'Right_Arm_Base' moves relative to the tip 'TCP_R' of group "
                                     "'RightArm'; constrain the tip or a link fixed to it"),
    (("Right_Arm_Base", "Nowhere", 1), "header.frame_id 'Nowhere' is not the world or a link of robot"),
    (("Right_Arm_Base", "Elbow_R", 1), "header.frame_id 'Elbow_R' is moved by group 'RightArm'"),
    (("Hand_R_Base", "Gripper", 2), "link_name 'Gripper' is not a link of robot 'armar3'"),
])
def test_pose_goals_on_links_that_cannot_serve_are_refused(tmp_path, edit, message):
    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    _pose_goal_requests(folder)
    old, new, k = edit
    request = folder / f"request{k:04d}.yaml"
    request.write_text(request.read_text().replace(old, new))
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--planner",
                                 "ik_rrt"])
    assert result.exit_code == 2 and message in " ".join(result.output.split()), result.output


def test_pose_planners_need_a_chain_and_no_ompl(tmp_path):
    _write_armar_problems(tmp_path / "problems" / "shelf_armar3")
    request = tmp_path / "problems" / "shelf_armar3" / "request0002.yaml"
    request.write_text(request.read_text().replace("group_name: RightArm", "group_name: right_hand"))
    base = ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--planner", "ik_rrt"]
    result = runner.invoke(app, base)
    assert result.exit_code == 2
    assert "request0002.yaml: group: ik_rrt plans to the pose of a chain's tip, and 'right_hand' is not a chain" \
        in result.output
    result = runner.invoke(app, [*base, "--compare-ompl"])
    assert result.exit_code == 2 and "compare OMPL with planner rrt_connect" in result.output
    import yaml  # a group of both arms has no one tip to plan to

    from prehensile import robots

    both = robots.load("armar3").chain("TorsoBothArms").joint_names
    data = yaml.safe_load(request.read_text())
    data["group_name"] = "TorsoBothArms"
    data["goal_constraints"][0]["joint_constraints"] += [{"joint_name": j, "position": 0.0} for j in both
                                                        if j.endswith("_L") or j.startswith("Hip")]
    request.write_text(yaml.safe_dump(data))
    result = runner.invoke(app, base)
    assert result.exit_code == 2
    assert ("request0002.yaml: group: ik_rrt plans the pose of one tip, and group 'TorsoBothArms' branches: "
            "Shoulder_1_") in " ".join(result.output.split())


def test_ball_radius_sizes_the_generated_balls(tmp_path):
    from prehensile import robots
    from prehensile.collision.spheres import generate_sphere_model

    _write_armar_problems(tmp_path / "problems" / "shelf_armar3")
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--limit", "1",
                                 "--ball-radius", "0.04", "--json", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    assert report["overall"]["solved"] == 1 and report["overall"]["colliding_paths"] == 0
    model = robots.load("armar3")
    assert report["robot"]["spheres"] == generate_sphere_model(model, max_radius=0.04).n_spheres
    assert report["robot"]["spheres"] > generate_sphere_model(model).n_spheres
    assert "--ball-radius 0.04" in report["command"]


@pytest.mark.parametrize("extra, message", [
    (["--budget", "inf"], "--budget: must be a positive, finite time (s), got inf"),
    (["--ball-radius", "-1"], "--ball-radius: must be positive and finite (m), got -1"),
    (["--ball-radius", "inf"], "--ball-radius: must be positive and finite (m), got inf"),
    (["--ball-radius", "0.04", "--spheres", __file__], "give it or --spheres, not both"),
    (["--pad"], "--pad pads the balls of --spheres"),
    (["--planner", "prm"], "--planner: 'prm' is not available; valid: rrt_connect"),
])
def test_bad_budget_and_ball_options_exit_2(tmp_path, extra, message):
    _write_armar_problems(tmp_path / "problems" / "shelf_armar3")
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", *extra])
    assert result.exit_code == 2
    assert message in " ".join(result.output.split())


def test_unusable_ends_are_reported_with_their_reason_and_unplanned_joints_clipped(tmp_path, caplog):
    import yaml

    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    # outside their limits: planned; not planned (free at -2.146), in the warm-up's problem too
    for k, joint, value in ((1, "Elbow_R", 5.0), (1, "Elbow_L", -2.5), (2, "Elbow_L", -2.5)):
        request = yaml.safe_load((folder / f"request{k:04d}.yaml").read_text())
        state = request["start_state"]["joint_state"]
        state["position"][state["name"].index(joint)] = value
        (folder / f"request{k:04d}.yaml").write_text(yaml.safe_dump(request))
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--budget", "1",
                                 "--limit", "2", "--json", str(out)])
    assert result.exit_code == 0, result.output
    first, second = (run["ours"] for run in json.loads(out.read_text())["runs"])
    assert first["status"] == "invalid_start" and first["reason"].startswith("start: joint Elbow_R = 5 outside")
    assert "invalid_start (first: shelf_armar3 #1): start: joint Elbow_R = 5" in " ".join(result.output.split())
    assert second["status"] == "success" and "reason" not in second
    for k in (1, 2):  # once each, not again for the warm-up
        warning = f"request{k:04d}.yaml: start_state: Elbow_L = -2.5 outside the joint limits and not planned"
        assert caplog.text.count(warning) == 1, caplog.text


def test_an_attached_collision_object_moves_with_the_hand(tmp_path):
    """A rod held in the Panda's hand (the scene's robot_state.attached_collision_objects) is
    planned with: a goal that puts it into the table is invalid although the bare hand stays
    3 cm above it; a goal above the table is reached without collision, the rod included."""
    import yaml

    from prehensile import robots
    from prehensile.collision import ExactChecker
    from prehensile.scene.moveit import load_moveit_scene

    model = robots.load("panda")
    arm = [f"panda_joint{i}" for i in range(1, 8)]
    rod = {"id": "rod", "primitives": [{"type": "box", "dimensions": [0.02, 0.02, 0.2]}],
           "primitive_poses": [{"position": [0, 0, 0.15], "orientation": [0, 0, 0, 1]}]}  # 10 cm past the fingertips
    start = [0, 0, 0, -1.5, 0, 1.5, 0.785]
    state = {"joint_state": {"name": arm + ["panda_finger_joint1"], "position": start + [0.01]},
             "attached_collision_objects": [{"link_name": "panda_hand", "object": rod,
                                             "touch_links": ["panda_leftfinger", "panda_rightfinger"]}]}
    table = {"id": "table", "primitives": [{"type": "box", "dimensions": [0.6, 1.0, 0.1]}],
             "primitive_poses": [{"position": [0.6, 0, 0.05], "orientation": [0, 0, 0, 1]}]}  # top at z = 0.1
    folder = tmp_path / "problems" / "held"
    folder.mkdir(parents=True)
    goals = ([0.6, 0, 0, -1.5, 0, 1.5, 0.785], [0.6, 0.5, 0, -1.9, 0, 2.4, 0.785])  # fingertips at 0.55 / 0.13 m
    for k, goal in enumerate(goals, 1):
        scene = {"name": f"held{k}", "robot_state": state, "world": {"collision_objects": [table]}}
        request = {"group_name": "panda_arm", "start_state": {"joint_state": state["joint_state"]},
                   "goal_constraints": [{"joint_constraints": [{"joint_name": n, "position": v}
                                                               for n, v in zip(arm, goal)]}]}
        (folder / f"scene{k:04d}.yaml").write_text(yaml.safe_dump(scene))
        (folder / f"request{k:04d}.yaml").write_text(yaml.safe_dump(request))
    out = tmp_path / "report.json"
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "panda", "--budget", "1",
                                 "--json", str(out)])
    assert result.exit_code == 0, result.output
    report = json.loads(out.read_text())
    above, into = (run["ours"] for run in report["runs"])
    assert above["status"] == "success" and report["overall"]["colliding_paths"] == 0
    assert into["status"] == "invalid_goal" and "attached/rod collides with table" in into["reason"]
    q = model.neutral_configuration()
    q[:7] = goals[1]
    world = load_moveit_scene(folder / "scene0002.yaml", model).collision_obstacles("panda")
    assert ExactChecker(model, world).is_free(q)  # the hand alone is free there


def test_a_timeout_names_the_end_only_the_balls_reject(tmp_path):
    """A start inside the conservative balls but free on the geometry, with no escape in the budget."""
    from prehensile.benchmarking.mbm import MBMSettings, PreparedProblem, _record, load_problems
    from prehensile.collision.spheres import generate_sphere_model
    from prehensile.planning import PlanResult, PlanStats, PlanStatus
    from prehensile import robots

    _write_armar_problems(tmp_path / "shelf")
    model = robots.load("armar3")
    coarse = generate_sphere_model(model, max_overshoot=np.inf)  # 8 balls per box: the torso's bulge 0.1 m
    prepared = PreparedProblem(model, (coarse, None), load_problems(tmp_path, model, 1)[0], MBMSettings())
    prepared.q_start = model.neutral_configuration()  # the hip's balls meet the arms' (exactly free)
    record = _record(prepared, PlanResult(PlanStatus.TIMEOUT, np.zeros((0, model.dof)), PlanStats()), 1.0,
                     MBMSettings(), certified=True)
    assert record["reason"].startswith("start: free on the exact geometry, but the sphere model's conservative balls")
    searched = PlanResult(PlanStatus.TIMEOUT, np.zeros((0, model.dof)), PlanStats(iterations=50))
    assert "reason" not in _record(prepared, searched, 1.0, MBMSettings(), True)  # the search ran: the start is fine


@pytest.mark.parametrize("goal, message", [
    ({}, "has no joint_constraints and no position_constraints"),
    ({"Elbow_X": 0.1}, "robot 'armar3' has no joint Elbow_X"),
    ({"Elbow_L": 0.1}, "Elbow_L not in the planned group 'RightArm'"),
    ({"Elbow_R": 0.1}, "no goal for planned joint"),
])
def test_bad_goal_exits_2_naming_the_request(tmp_path, goal, message):
    import yaml

    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    request = yaml.safe_load((folder / "request0001.yaml").read_text())
    request["goal_constraints"] = [{"joint_constraints": [{"joint_name": j, "position": v} for j, v in goal.items()]}]
    (folder / "request0001.yaml").write_text(yaml.safe_dump(request))
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--budget", "0.1"])
    assert result.exit_code == 2, result.output
    assert "request0001.yaml" in result.output and message in " ".join(result.output.split())

def test_a_start_without_a_planned_joint_exits_2_naming_the_joints(tmp_path):
    """A misspelt joint in the start state would leave the planned joint at its neutral value."""
    import yaml

    folder = tmp_path / "problems" / "shelf_armar3"
    _write_armar_problems(folder)
    request = yaml.safe_load((folder / "request0001.yaml").read_text())
    names = request["start_state"]["joint_state"]["name"]
    names[names.index("Elbow_R")] = "Elbow_RR"
    (folder / "request0001.yaml").write_text(yaml.safe_dump(request))
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "problems"), "--robot", "armar3", "--budget", "0.1"])
    assert result.exit_code == 2, result.output
    assert ("request0001.yaml: start_state.joint_state: no start for planned joint(s) Elbow_R; robot 'armar3' has "
            "no joint Elbow_RR (planned: ") in " ".join(result.output.split())


def test_every_request_is_checked_before_planning(tmp_path, monkeypatch):
    import yaml

    from prehensile import robots
    from prehensile.benchmarking import mbm

    folder = tmp_path / "shelf_armar3"
    _write_armar_problems(folder)
    last = sorted(folder.glob("request*.yaml"))[-1]
    request = yaml.safe_load(last.read_text())
    request["goal_constraints"][0]["joint_constraints"].pop()
    last.write_text(yaml.safe_dump(request))
    monkeypatch.setattr(mbm, "warm_up", lambda *args: pytest.fail("planning began before every request was checked"))
    with pytest.raises(PrehensileError, match=f"{last.name}: .*no goal for planned joint"):
        mbm.run_mbm(tmp_path, robots.load("armar3"), (None, None))


def test_a_problem_plans_the_same_in_any_set(tmp_path):
    import shutil

    from prehensile import robots
    from prehensile.benchmarking.mbm import load_problems, problem_seed

    model = robots.load("armar3")
    _write_armar_problems(tmp_path / "all" / "shelf")
    alone = tmp_path / "alone" / "shelf"
    alone.mkdir(parents=True)
    for name in ("scene0002.yaml", "request0002.yaml"):
        shutil.copy(tmp_path / "all" / "shelf" / name, alone / name)
    problems = load_problems(tmp_path / "all", model)
    settings = MBMSettings(seed=4)
    seeds = [problem_seed(settings, p) for p in problems]
    assert len({str(s) for s in seeds}) == len(problems) == 2  # one stream per problem
    assert problem_seed(settings, load_problems(tmp_path / "alone", model)[0]) == seeds[1]
    assert problem_seed(MBMSettings(seed=5), problems[0]) != seeds[0]


def test_bad_problems_path_exits_2(tmp_path):
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path / "missing"), "--robot", "panda"])
    assert result.exit_code == 2
    assert "missing" in result.output and "MoveIt problems" in result.output


def test_empty_problem_folder_exits_2(tmp_path):
    result = runner.invoke(app, ["bench", "mbm", str(tmp_path), "--robot", "panda"])
    assert result.exit_code == 2
    assert "no MoveIt problems found" in result.output


def test_settings_name_valid_choices():
    with pytest.raises(PrehensileError, match="valid: rrt_connect, ik_rrt, jplus_rrt"):
        MBMSettings(planner="prm")
    for budget in (0, float("inf"), float("nan")):
        with pytest.raises(PrehensileError, match="MBMSettings.time_budget_s must be > 0 and finite"):
            MBMSettings(time_budget_s=budget)
    with pytest.raises(PrehensileError, match="MBMSettings.limit must be an integer >= 0, got -1"):
        MBMSettings(limit=-1)


def test_summaries():
    assert time_summary([]) == {"median_ms": None, "p95_ms": None, "mean_ms": None}
    summary = time_summary([0.001, 0.002, 0.003])
    assert summary["median_ms"] == pytest.approx(2.0) and summary["mean_ms"] == pytest.approx(2.0)
    assert 2.0 < summary["p95_ms"] < 3.0
    assert ratio(4.0, 2.0) == 2.0 and ratio(None, 1.0) is None and ratio(1.0, 0.0) is None
    records = [
        {"status": "success", "solved": True, "time_s": 0.001, "search_s": 0.0008, "simplify_s": 0.0002,
         "certify_s": 0.01, "collision_checks": 100, "waypoints": 3, "path_length": 1.0, "exact_colliding": False,
         "goal_error_m": 2e-5, "goal_error_rad": None, "attempts": 2},
        {"status": "invalid_goal", "solved": False, "time_s": 0.0, "search_s": 0.0, "simplify_s": 0.0,
         "certify_s": 0.0, "collision_checks": 2, "waypoints": 0, "path_length": None, "exact_colliding": None,
         "goal_error_m": None, "goal_error_rad": None, "attempts": 1},
    ]
    summary = summarize(records)
    assert (summary["solved"], summary["total"], summary["colliding_paths"]) == (1, 2, 0)
    assert summary["median_ms"] == pytest.approx(1.0) and summary["path_length"] == 1.0
    assert summary["statuses"] == {"success": 1, "invalid_goal": 1}
    assert summary["planned_again"] == 1
    assert summary["goal_error_m_max"] == 2e-5 and summary["goal_error_rad_max"] is None


def test_ompl_takes_a_continuous_joint_starting_beyond_pi():
    """Ours and OMPL sample a continuous joint in one turn around the start; an end beyond pi is valid for both."""
    pytest.importorskip("ompl")
    from prehensile.benchmarking.ompl_peer import OMPLSettings, ompl_rrt_connect
    from prehensile.model.builder import JointSpec, LinkSpec, build_model
    from prehensile.model.geometry import Box, Geometry
    from prehensile.planning import PlanningContext
    from prehensile.spatial import make_pose

    bar = Geometry(Box((0.4, 0.05, 0.05)), make_pose(position=[0.2, 0, 0]))
    links = [LinkSpec("base"), LinkSpec("arm", collisions=[bar])]
    joints = [JointSpec("turn", "continuous", "base", "arm", np.eye(4), [0, 0, 1.0])]
    ctx = PlanningContext(build_model("turner", "test", links, joints), [])
    start, goal = np.array([4.0]), np.array([2.0])
    result = ompl_rrt_connect(ctx.space, ctx.spheres, start, goal, OMPLSettings(time_budget_s=1.0))
    assert result.success, result.status
    assert result.path[0] == pytest.approx(start) and result.path[-1] == pytest.approx(goal)


def test_ompl_solves_with_a_budget_beyond_its_clock():
    """OMPL's deadline (clock ns + budget, 64-bit) overflows for a 1e10 s budget and its search
    ends at once; the peer clips the budget. A block in front of the stretched two-link arm
    makes the search take more than one step."""
    pytest.importorskip("ompl")
    from prehensile.benchmarking.ompl_peer import OMPLSettings, ompl_rrt_connect
    from prehensile.collision import Obstacle
    from prehensile.model.builder import JointSpec, LinkSpec, build_model
    from prehensile.model.geometry import Box, Geometry
    from prehensile.planning import PlanningContext
    from prehensile.spatial import make_pose

    bar = Geometry(Box((0.4, 0.05, 0.05)), make_pose(position=[0.2, 0, 0]))
    links = [LinkSpec("base"), LinkSpec("l1", collisions=[bar]), LinkSpec("l2", collisions=[bar])]
    joints = [JointSpec("j1", "revolute", "base", "l1", np.eye(4), [0, 0, 1.0], -3.0, 3.0),
              JointSpec("j2", "revolute", "l1", "l2", make_pose(position=[0.45, 0, 0]), [0, 0, 1.0], -3.0, 3.0)]
    block = Obstacle("block", Box((0.1, 0.1, 0.1)), make_pose(position=[0.75, 0.0, 0]))
    ctx = PlanningContext(build_model("folder", "test", links, joints), [block])
    start, goal = np.array([-1.0, 0.0]), np.array([1.0, 0.0])
    assert not ctx.check_motion(start, goal)
    result = ompl_rrt_connect(ctx.space, ctx.spheres, start, goal, OMPLSettings(time_budget_s=1e10))
    assert result.success, result.status


def test_a_path_counts_only_from_the_start_to_the_goal(problem_dir):
    """The benchmark's own check of every path's ends (a planner could return a certified,
    collision-free path to somewhere else)."""
    from prehensile import robots

    panda = MBM / "panda"
    model = robots.load(str(panda / "panda.urdf"), str(panda / "panda.srdf"))
    problem = load_problems(problem_dir, model)[0]
    spheres = benchmark_spheres(model, panda / "panda_spherized.urdf")
    prepared = PreparedProblem(model, spheres, problem, MBMSettings())
    start, goal = prepared.q_start, prepared.q_goal
    assert _ends_as_asked(prepared, np.array([start, goal]))
    assert not _ends_as_asked(prepared, np.array([start, start]))
    assert not _ends_as_asked(prepared, np.array([goal, goal]))
    assert not _ends_as_asked(prepared, np.array([start, goal + 1e-6]))
