"""`prehensile ik`: position-only and 6-D queries, exit codes, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from prehensile import robots
from prehensile.cli.main import app
from prehensile.kinematics import link_pose
from prehensile.spatial import matrix_to_rpy
from prehensile.spatial.transforms import rotation_error

runner = CliRunner()


def _run(*args):
    return runner.invoke(app, [str(a) for a in args])


def _reachable(robot: str, chain: str, seed: int = 3) -> tuple[np.ndarray, list[float]]:
    """Tip pose (4, 4) of a random configuration of the chain, and its x y z roll pitch yaw."""
    model = robots.load(robot)
    q = model.neutral_configuration()
    index = model.chain_q_indices(chain)
    q[index] = np.random.default_rng(seed).uniform(model.lower[index], model.upper[index])
    pose = link_pose(model, q, model.chain(chain).tip_link)
    return pose, [*pose[:3, 3], *matrix_to_rpy(pose[:3, :3])]


def _reached(robot: str, chain: str, joints: dict) -> np.ndarray:
    model = robots.load(robot)
    q = model.configuration_from_dict(joints)
    return link_pose(model, q, model.chain(chain).tip_link)


@pytest.mark.parametrize("robot, chain, method", [("panda", "arm", "dls"), ("nao", "left_arm", "dls"),
                                                  ("nao", "left_arm_wrist", "analytic")])
def test_pose_target_is_reached(robot, chain, method):
    pose, values = _reachable(robot, chain)
    result = _run("ik", robot, "--chain", chain, "--target", *values, "--method", method, "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["status"] == "success" and data["solutions"]
    for joints in data["solutions"]:  # analytic: every solution reaches the target
        reached = _reached(robot, chain, joints)
        assert np.linalg.norm(reached[:3, 3] - pose[:3, 3]) <= 1e-4
        assert np.linalg.norm(rotation_error(pose[:3, :3], reached[:3, :3])) <= 1e-3


@pytest.mark.parametrize("robot, chain, method", [("panda", "arm", "dls"), ("nao", "left_arm", "dls"),
                                                  ("nao", "left_arm", "fabrik")])
def test_position_target_is_reached(robot, chain, method):
    pose, values = _reachable(robot, chain, seed=5)
    result = _run("ik", robot, "--chain", chain, "--target", *values[:3], "--method", method, "--json")
    assert result.exit_code == 0, result.output
    data = json.loads(result.stdout)
    assert data["rotation_error_rad"] is None and data["target"]["rpy"] is None
    assert np.linalg.norm(_reached(robot, chain, data["joints"])[:3, 3] - pose[:3, 3]) <= 1e-4


def test_table_output_names_the_joints_and_status():
    _, values = _reachable("panda", "arm")
    result = _run("ik", "panda", "--chain", "arm", "--target", *values)
    assert result.exit_code == 0, result.output
    for text in ("panda_joint1", "panda_joint7", "status success", "iterations", "ms"):
        assert text in result.stdout


def test_unreachable_target_exits_1_with_status_and_says_it_is_out_of_reach():
    result = _run("ik", "panda", "--chain", "arm", "--target", 3, 0, 0, "--budget", 0.02)
    assert result.exit_code == 1, result.output
    assert "status timeout" in result.stdout
    assert "out of reach: the target is 3.000 m from panda_link0, the base of chain 'arm'" in result.stdout
    model = robots.load("panda")  # the bound: the tip's offsets from the base add up to it
    reach = float(result.stdout.split("reaches at most")[1].split()[0])
    tip = max(np.linalg.norm(link_pose(model, q, "panda_hand_tcp")[:3, 3])
              for q in model.random_configurations(np.random.default_rng(0), 500))
    assert 0.8 < tip <= reach < 1.5
    near = _run("ik", "panda", "--chain", "arm", "--target", 0.1, 0, 1.35, "--budget", 0.02, "--json")
    assert near.exit_code == 1 and json.loads(near.stdout)["reason"] is None  # unsolved, not provably out of reach


def test_an_infinite_budget_is_refused():
    """It would never end the restarts for an unreachable target."""
    _, values = _reachable("panda", "arm")
    result = _run("ik", "panda", "--chain", "arm", "--target", *values, "--budget", "inf")
    assert result.exit_code == 2 and "--budget: must be a positive, finite time (s), got inf" in result.stderr


def test_unknown_chain_exits_2_listing_chains():
    result = _run("ik", "nao", "--chain", "tentacle", "--target", 0.1, 0.1, 0.1)
    assert result.exit_code == 2
    assert "tentacle" in result.stderr and "left_arm" in result.stderr and "right_arm_wrist" in result.stderr


@pytest.mark.parametrize("extra, message", [
    (["--target", 0.1, 0.2], "expected 3 values"),
    ([], "or 6 (x y z roll pitch yaw; m, rad), got none"),
    (["--target", 0.1, 0.2, "nan"], "NaN"),
    (["--target", 0.1, 0.2, "x"], "expected numbers"),
    (["--target", 0.1, 0.2, 0.3, "--method", "magic"], "pinv, dls, fabrik, analytic"),
    (["--target", 0.1, 0.2, 0.3, "--method", "analytic"], "solves poses"),
])
def test_bad_input_exits_2(extra, message):
    result = _run("ik", "nao", "--chain", "left_arm", *extra)
    assert result.exit_code == 2
    assert message in result.stderr
