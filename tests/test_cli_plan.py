"""``prehensile plan SCENE`` on the bundled plan demo scene, and scene goals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from prehensile.cli.main import app
from prehensile.collision.exact import ExactChecker
from prehensile.errors import SceneError
from prehensile.kinematics import link_pose
from prehensile.planning import PlanningContext
from prehensile.planning.trajectory import model_limits, time_parameterize
from prehensile.scene.files import bundled_scene_path, load_scene, robot_goals
from prehensile.spatial import rpy_to_matrix

ARM = [f"panda_joint{i}" for i in range(1, 8)]
IN_THE_WALL = ["0.0", "0.2", "0.0", "-2.0", "0.0", "2.2", "0.785"]  # hand straight into the wall
BEHIND_THE_WALL = ["0.3672", "0.4627", "0.2566", "3.1416", "0", "0.9004"]  # the scene goal's TCP pose (m, rad)
runner = CliRunner()


def _plan(*args: str):
    return runner.invoke(app, ["plan", *map(str, args)])


@pytest.fixture(scope="module")
def demo():
    path = bundled_scene_path("plan_demo")
    scene = load_scene(path)
    return path, scene, robot_goals(path, scene)


def test_scene_goal_is_read(demo):
    _, scene, goals = demo
    assert list(goals) == ["panda"] and list(goals["panda"]) == ARM
    assert goals["panda"]["panda_joint1"] == pytest.approx(0.9)
    assert scene.robots[0].q is not None  # the start


def test_plan_bundled_scene(demo, tmp_path):
    _, scene, goals = demo
    result = _plan("plan_demo", "--seed", "1", "--out", tmp_path)
    assert result.exit_code == 0, result.output
    assert "success" in result.output
    path = json.loads((tmp_path / "path.json").read_text())
    assert path["status"] == "success" and path["joint_names"] == ARM
    model, start = scene.robots[0].model, scene.robots[0].configuration
    waypoints = np.array(path["waypoints"])
    assert len(waypoints) >= 3  # the straight motion hits the wall
    np.testing.assert_allclose(waypoints[0], start[model.chain_q_indices("arm")], atol=1e-9)
    np.testing.assert_allclose(waypoints[-1], [goals["panda"][j] for j in ARM], atol=1e-9)
    assert path["fixed_joints"] == {"panda_finger_joint1": pytest.approx(0.02)}
    assert path["path_length_m"] > 0 and path["stats"]["certify_time_s"] >= 0
    trajectory = json.loads((tmp_path / "trajectory.json").read_text())
    assert trajectory["joint_names"] == ARM and trajectory["duration"] > 0
    assert trajectory["fixed_joints"] == path["fixed_joints"]
    np.testing.assert_allclose(trajectory["q"][0], waypoints[0], atol=1e-6)
    np.testing.assert_allclose(trajectory["q"][-1], waypoints[-1], atol=1e-6)
    arm = model.chain_q_indices("arm")  # corners blended where the exact geometry stays free: faster than stopping
    stopping = time_parameterize(waypoints, *model_limits(model, arm))
    assert trajectory["duration"] < 0.9 * stopping.duration
    samples = np.repeat(start[None], len(trajectory["q"]), axis=0)
    samples[:, arm] = trajectory["q"]
    assert ExactChecker(model, scene.collision_obstacles(), scene.robots[0].T_world_base).is_free(samples).all()
    assert (tmp_path / "plan.png").stat().st_size > 10_000


def _box_distance(obstacle, points: np.ndarray) -> np.ndarray:
    """Distance (m) of world points (N, 3) from a box obstacle (0 inside)."""
    T, half = obstacle.T_world_shape, 0.5 * np.array(obstacle.shape.size)
    local = (points - T[:3, 3]) @ T[:3, :3]
    return np.linalg.norm(np.maximum(np.abs(local) - half, 0.0), axis=1)


def test_plan_carries_a_held_object(tmp_path):
    """carry_demo: the bottle in the hand moves with it; along the path (waypoints joined by
    straight joint motions) and the trajectory neither the arm nor the bottle touches the
    bench or the wall, checked here without the planner's checkers."""
    result = _plan("carry_demo", "--out", tmp_path)
    assert result.exit_code == 0, result.output
    path = json.loads((tmp_path / "path.json").read_text())
    scene = load_scene(bundled_scene_path("carry_demo"))
    robot, (bottle,) = scene.robots[0], scene.attached_objects("panda")
    assert list(path["held_objects"]) == ["bottle"] and path["held_objects"]["bottle"]["link"] == "panda_hand"
    np.testing.assert_allclose(path["held_objects"]["bottle"]["T_link_object"], bottle.T_link_object, atol=1e-12)
    model, arm = robot.model, robot.model.chain_q_indices("arm")
    waypoints = np.array(path["waypoints"])
    steps = np.linspace(0.0, 1.0, 400)[:, None]
    along = np.concatenate([a + steps * (b - a) for a, b in zip(waypoints[:-1], waypoints[1:])])
    trajectory = np.array(json.loads((tmp_path / "trajectory.json").read_text())["q"])
    samples = np.repeat(robot.configuration[None], len(along) + len(trajectory), axis=0)
    samples[:, arm] = np.concatenate([along, trajectory])
    obstacles = scene.collision_obstacles("panda")
    assert [o.name for o in obstacles] == ["bench", "wall"]
    assert ExactChecker(model, obstacles, robot.T_world_base).is_free(samples).all()
    cylinder = bottle.geometries()[0].shape
    axis = np.linspace(-0.5, 0.5, 241)[:, None] * [0.0, 0.0, cylinder.length]  # 1 mm apart
    T_world_bottle = link_pose(model, samples, "panda_hand", bottle.T_link_object, robot.T_world_base)
    points = (np.einsum("nij,kj->nki", T_world_bottle[:, :3, :3], axis) + T_world_bottle[:, None, :3, 3]).reshape(-1, 3)
    for obstacle in obstacles:  # the balls of radius r + 0.5 mm around the axis points hold the bottle
        assert _box_distance(obstacle, points).min() > np.hypot(cylinder.radius, 0.0005), obstacle.name


def test_a_goal_where_the_held_object_collides_is_invalid(tmp_path):
    lowered = ["-0.796", "0.5", "0.075", "-1.592", "-0.01", "1.72", "0.965"]  # the bare hand stays above the bench
    result = _plan("carry_demo", "--goal", *lowered, "--out", tmp_path)
    assert result.exit_code == 1, result.output
    path = json.loads((tmp_path / "path.json").read_text())
    assert path["status"] == "invalid_goal" and "attached/bottle collides with bench" in path["reason"]
    scene = load_scene(bundled_scene_path("carry_demo"))
    robot = scene.robots[0]
    q = robot.configuration.copy()
    q[robot.model.chain_q_indices("arm")] = [float(v) for v in lowered]
    assert ExactChecker(robot.model, scene.collision_obstacles("panda"), robot.T_world_base).is_free(q)


def test_an_interrupted_plan_leaves_the_earlier_outputs_whole(tmp_path, monkeypatch):
    """The outputs are written together, after the picture is drawn: an interruption before
    then changes none of them."""
    import prehensile.viz

    assert _plan("plan_demo", "--out", tmp_path).exit_code == 0
    before = {f.name: f.read_bytes() for f in tmp_path.iterdir()}
    assert set(before) == {"path.json", "trajectory.json", "plan.png"}

    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    monkeypatch.setattr(prehensile.viz, "scene_image", interrupted)
    result = _plan("plan_demo", "--goal", *IN_THE_WALL[:1], *["0.3"] * 6, "--out", tmp_path)
    assert result.exit_code != 0
    assert {f.name: f.read_bytes() for f in tmp_path.iterdir()} == before  # no temp files either


@pytest.mark.parametrize("planner", ["ik_rrt", "jplus_rrt"])
def test_plan_to_a_target_pose(demo, planner, tmp_path):
    _, scene, _ = demo
    result = _plan("plan_demo", "--chain", "arm", "--target", *BEHIND_THE_WALL, "--planner", planner, "--out", tmp_path)
    assert result.exit_code == 0, result.output
    path = json.loads((tmp_path / "path.json").read_text())
    robot = scene.robots[0]
    values, target = np.array(BEHIND_THE_WALL, float), np.eye(4)
    target[:3, :3], target[:3, 3] = rpy_to_matrix(values[3:]), values[:3]
    assert path["status"] == "success" and path["planner"] == planner
    np.testing.assert_allclose(path["target"], target, atol=1e-12)
    waypoints = np.array(path["waypoints"])
    assert path["goal"] == pytest.approx(waypoints[-1].tolist())
    np.testing.assert_allclose(waypoints[0], robot.configuration[robot.model.chain_q_indices("arm")], atol=1e-9)
    reached = robot.configuration.copy()
    reached[robot.model.chain_q_indices("arm")] = waypoints[-1]
    tcp = link_pose(robot.model, reached, "panda_hand_tcp", T_world_base=robot.T_world_base)
    np.testing.assert_allclose(tcp[:3, 3], target[:3, 3], atol=1.5e-3)
    assert np.arccos(np.clip(0.5 * (np.trace(tcp[:3, :3].T @ target[:3, :3]) - 1.0), -1.0, 1.0)) < 1.5e-2
    trajectory = json.loads((tmp_path / "trajectory.json").read_text())
    assert len(trajectory["velocity_limits"]) == len(trajectory["acceleration_limits"]) == 7
    np.testing.assert_allclose(trajectory["q"][-1], waypoints[-1], atol=1e-6)


@pytest.mark.parametrize("planner", ["ik_rrt", "jplus_rrt"])
def test_plan_to_a_target_within_tolerances(demo, tmp_path, planner):
    """With tolerances the pose planners may end anywhere in the ball and orientation range
    around the target: IK-RRT's first goal is the nearest such pose to the start's, J+-RRT
    steps toward the one nearest to the tool; both end near the ball's surface here."""
    from scipy.spatial.transform import Rotation

    _, scene, _ = demo
    result = _plan("plan_demo", "--chain", "arm", "--target", *BEHIND_THE_WALL, "--position-tolerance", "0.05",
                   "--rotation-tolerance", "0.3", "--planner", planner, "--out", tmp_path)
    assert result.exit_code == 0, result.output
    path = json.loads((tmp_path / "path.json").read_text())
    assert path["status"] == "success" and path["goal_satisfied"] is True
    assert path["tolerance"] == {"position_m": 0.05, "rotation_rad": 0.3}
    robot = scene.robots[0]
    reached = robot.configuration.copy()
    reached[robot.model.chain_q_indices("arm")] = path["waypoints"][-1]
    tcp = link_pose(robot.model, reached, "panda_hand_tcp", T_world_base=robot.T_world_base)
    target = np.array(path["target"])
    assert 0.04 < np.linalg.norm(tcp[:3, 3] - target[:3, 3]) <= 0.05
    assert np.all(np.abs(Rotation.from_matrix(target[:3, :3].T @ tcp[:3, :3]).as_rotvec()) <= 0.3)


def test_goal_in_collision_exits_1(tmp_path):
    (tmp_path / "trajectory.json").write_text("{}")  # an earlier plan's
    result = _plan("plan_demo", "--goal", *IN_THE_WALL, "--out", tmp_path)
    assert result.exit_code == 1, result.output
    assert "invalid_goal" in result.output
    path = json.loads((tmp_path / "path.json").read_text())
    assert path["status"] == "invalid_goal" and path["waypoints"] == []
    assert "collides with wall" in path["reason"] and "goal: panda_" in result.output
    assert "--ball-radius" not in path["reason"]  # finer balls cannot help an end that collides
    assert path["goal"] == pytest.approx([float(v) for v in IN_THE_WALL])
    assert not (tmp_path / "trajectory.json").exists() and (tmp_path / "plan.png").is_file()


def test_a_target_out_of_reach_says_why(tmp_path):
    result = _plan("plan_demo", "--chain", "arm", "--target", "2.0", "0", "0.5", "3.14", "0", "0", "--budget", "0.3",
                   "--out", tmp_path)
    assert result.exit_code == 1, result.output
    path = json.loads((tmp_path / "path.json").read_text())
    assert path["status"] == "no_goal_configuration" and "out of reach" in path["reason"]


def test_an_end_only_coarse_balls_reject_is_explained_and_finer_balls_plan(tmp_path):
    """Coarse balls on ARMAR-III's torso box (8 per box, bulging 0.1 m out of it) overlap the
    arm at the demo's start: without an escape the start is invalid, and the reason says that
    finer balls may help. The default balls (at most 2 cm out of a box) plan from there."""
    from prehensile.cli.plan_cmd import _end_reason
    from prehensile.collision.spheres import generate_sphere_model
    from prehensile.planning import RRTConnectSettings, rrt_connect

    args = ["demo", "--robot", "armar3", "--chain", "LeftArm", "--goal", "0.3", "0.2", "0", "0.5", "0", "0", "0",
            "--out", tmp_path]
    result = _plan(*args, "--budget", "0.3")
    assert result.exit_code == 0, result.output
    assert json.loads((tmp_path / "path.json").read_text())["status"] == "success"
    scene = load_scene(bundled_scene_path("demo"))
    robot = next(r for r in scene.robots if r.name == "armar3")
    coarse = generate_sphere_model(robot.model, max_overshoot=np.inf)
    context = PlanningContext(robot.model, scene.collision_obstacles(), joints="LeftArm", q_ref=robot.configuration,
                              T_world_base=robot.T_world_base, spheres=coarse)
    goal = robot.configuration.copy()
    goal[robot.model.chain_q_indices("LeftArm")] = [0.3, 0.2, 0, 0.5, 0, 0, 0]
    planned = rrt_connect(context, robot.configuration, goal, RRTConnectSettings(time_budget_s=0.3, escape=False))
    assert planned.status.value == "invalid_start"
    reason = _end_reason(planned, context, robot.configuration, goal)
    assert reason.startswith("start: free on the exact geometry, but the sphere model's conservative balls collide")
    assert "--ball-radius" in reason


def test_a_search_that_ran_out_of_time_does_not_blame_its_start(tmp_path):
    """NAO's start is free on the meshes but its default balls touch (torso, LBicep): J+-RRT
    leaves it along a certified escape, then searches for a pose out of reach until the budget
    ends. The start, and finer balls, are not why it timed out."""
    scene = tmp_path / "nao.yaml"
    scene.write_text("robots:\n  - {robot: nao, joints: {LShoulderPitch: 1.0, LShoulderRoll: 0.1}}\n")
    robot = load_scene(scene).robots[0]
    context = PlanningContext(robot.model, [], joints="left_arm", q_ref=robot.configuration)
    assert "conservative balls collide" in context.why_invalid(robot.configuration)
    result = _plan(scene, "--chain", "left_arm", "--target", "1", "1", "1", "0", "0", "0", "--planner", "jplus_rrt",
                   "--budget", "0.3", "--out", tmp_path / "out")
    assert result.exit_code == 1, result.output
    path = json.loads((tmp_path / "out" / "path.json").read_text())
    assert path["status"] == "timeout" and path["stats"]["iterations"] > 0
    assert path["reason"].startswith("no goal reached: the tool came within ") and "start" not in path["reason"]
    assert "--ball-radius" not in result.output


def test_plan_to_a_position_of_a_short_arm(tmp_path):
    """NAO's 4-joint arm reaches a position (any orientation) taken from another configuration."""
    scene = tmp_path / "nao.yaml"
    scene.write_text("robots:\n  - {robot: nao}\n")
    robot = load_scene(scene).robots[0]
    arm = robot.model.chain_q_indices("left_arm")
    reached = robot.configuration.copy()
    reached[arm] = [0.5, 0.6, -0.8, -1.0]
    position = link_pose(robot.model, reached, "l_arm_tip", T_world_base=robot.T_world_base)[:3, 3]
    result = _plan(scene, "--chain", "left_arm", "--target", *map(str, position), "--out", tmp_path / "out")
    assert result.exit_code == 0, result.output
    path = json.loads((tmp_path / "out" / "path.json").read_text())
    assert path["planner"] == "ik_rrt" and path["target"] == pytest.approx(position.tolist())
    reached[arm] = path["waypoints"][-1]
    tip = link_pose(robot.model, reached, "l_arm_tip", T_world_base=robot.T_world_base)[:3, 3]
    assert np.linalg.norm(tip - position) < 1e-3
    result = _plan(scene, "--chain", "left_arm", "--target", *map(str, position), "--planner", "jplus_rrt")
    assert result.exit_code == 2 and "jplus_rrt steps toward a full pose" in " ".join(result.output.split())


@pytest.mark.parametrize("args, message", [
    (["plan_demo", "--goal", "0.1", "0.2"], "expected 7 values"),
    (["plan_demo", "--chain", "hand", "--goal", "0.01", "0.02"], "expected 1 value, one per planned joint"),
    (["plan_demo", "--goal", "a", "b"], "expected numbers"),
    (["plan_demo", "--goal", "9", "0", "0", "-2", "0", "2", "0.7"], "outside its limits"),
    (["plan_demo", "--goal", "inf", "0", "0", "-2", "0", "2", "0.7"], "panda_joint1 = inf is not a finite number"),
    (["plan_demo", "--robot", "nao"], "no robot 'nao'; robots: panda"),
    (["plan_demo", "--chain", "leg"], "--chain: robot 'panda' has no chain 'leg'; chains: arm, hand"),
    (["plan_demo", "--chain", "hand"], "the scene's goal sets panda_joint1"),
    (["plan_demo", "--planner", "prm"], "valid: rrt_connect, ik_rrt, jplus_rrt"),
    (["plan_demo", "--target", *BEHIND_THE_WALL], "give --chain"),
    (["plan_demo", "--chain", "arm", "--target", "0.3", "0.4", "0.2", "0"], "expected 3 values (x y z, m) or 6"),
    (["plan_demo", "--chain", "arm", "--target", *BEHIND_THE_WALL, "--planner", "rrt_connect"],
     "use ik_rrt or jplus_rrt"),
    (["plan_demo", "--chain", "arm", "--planner", "jplus_rrt"], "give --target"),
    (["plan_demo", "--goal", *IN_THE_WALL, "--target", *BEHIND_THE_WALL], "not both"),
    (["plan_demo", "--position-tolerance", "0.1"], "tolerances of a --target; give one"),
    (["plan_demo", "--chain", "arm", "--target", "0.3", "0.4", "0.5", "--rotation-tolerance", "0.1"],
     "--rotation-tolerance: the --target is a position (x y z)"),
    (["plan_demo", "--chain", "arm", "--target", *BEHIND_THE_WALL, "--position-tolerance", "-1"],
     "--position-tolerance: must be a finite number >= 0, got -1.0"),
    (["plan_demo", "--seed", "-1"], "--seed"),
    (["plan_demo", "--ball-radius", "0"], "--ball-radius: must be positive"),
    (["plan_demo", "--budget", "inf"], "--budget: must be a positive, finite time (s), got inf"),
    (["no_such_scene"], "bundled scenes:"),
])
def test_bad_input_exits_2(args, message, tmp_path):
    result = _plan(*args, "--out", tmp_path)
    assert result.exit_code == 2, result.output
    assert message in result.output


def test_bad_scene_goal_names_the_file(tmp_path):
    scene = tmp_path / "bad.yaml"
    scene.write_text("robots:\n  - {robot: panda, goal: {elbow: 1.0}}\n")
    with pytest.raises(SceneError, match=r"bad.yaml: robots\[0\].goal: robot 'panda' has no joint 'elbow'"):
        robot_goals(scene, load_scene(scene))
    scene.write_text("robots:\n  - {robot: panda, goal: {panda_finger_joint2: 0.01}}\n")
    with pytest.raises(SceneError, match=r"goal: mimic joint 'panda_finger_joint2' = 0.01 disagrees with the joint it "
                                         r"follows: 1 \* panda_finger_joint1 \+ 0 = 0$"):
        robot_goals(scene, load_scene(scene))
    scene.write_text("robots:\n  - {robot: panda, joints: {panda_finger_joint1: 0.01, panda_finger_joint2: 0.01},\n"
                     "      goal: {panda_joint1: 0.5, panda_finger_joint2: 0.01}}\n")  # agrees: accepted, not planned
    assert robot_goals(scene, load_scene(scene)) == {"panda": {"panda_joint1": 0.5}}
    scene.write_text("robots:\n  - {robot: panda, goal: {panda_finger_joint2: 0.0}}\n")
    with pytest.raises(SceneError, match=r"bad.yaml: robots\[0\].goal: empty; name the planned joints"):
        robot_goals(scene, load_scene(scene))
    scene.write_text("robots:\n  - {robot: panda, goal: {}}\n")
    with pytest.raises(SceneError, match=r"bad.yaml: robots\[0\].goal: empty; name the planned joints"):
        robot_goals(scene, load_scene(scene))


def test_a_scene_without_robots_says_so(tmp_path):
    scene = tmp_path / "empty.yaml"
    scene.write_text("obstacles: []\n")
    result = _plan(scene, "--out", tmp_path / "out")
    assert result.exit_code == 2 and "empty.yaml: the scene has no robots" in result.output
