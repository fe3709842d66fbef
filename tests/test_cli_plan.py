"""``prehensile plan SCENE`` on the bundled plan demo scene, and scene goals."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from prehensile.cli.main import app
from prehensile.errors import SceneError
from prehensile.scene.files import bundled_scene_path, load_scene, robot_goals

ARM = [f"panda_joint{i}" for i in range(1, 8)]
IN_THE_WALL = ["0.0", "0.2", "0.0", "-2.0", "0.0", "2.2", "0.785"]  # hand straight into the wall
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
    np.testing.assert_allclose(trajectory["q"][0], waypoints[0], atol=1e-6)
    np.testing.assert_allclose(trajectory["q"][-1], waypoints[-1], atol=1e-6)
    assert (tmp_path / "plan.png").stat().st_size > 10_000


def test_goal_in_collision_exits_1(tmp_path):
    result = _plan("plan_demo", "--goal", *IN_THE_WALL, "--out", tmp_path)
    assert result.exit_code == 1, result.output
    assert "invalid_goal" in result.output
    path = json.loads((tmp_path / "path.json").read_text())
    assert path["status"] == "invalid_goal" and path["waypoints"] == []
    assert path["goal"] == pytest.approx([float(v) for v in IN_THE_WALL])
    assert not (tmp_path / "trajectory.json").exists() and (tmp_path / "plan.png").is_file()


@pytest.mark.parametrize("args, message", [
    (["plan_demo", "--goal", "0.1", "0.2"], "expected 7 values"),
    (["plan_demo", "--goal", "a", "b"], "expected numbers"),
    (["plan_demo", "--goal", "9", "0", "0", "-2", "0", "2", "0.7"], "outside its limits"),
    (["plan_demo", "--robot", "nao"], "no robot 'nao'; robots: panda"),
    (["plan_demo", "--chain", "leg"], "chain"),
    (["plan_demo", "--planner", "prm"], "valid: rrt_connect"),
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
