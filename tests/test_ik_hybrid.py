"""Hybrid IK (sampled free joints + per-arm solves), dual-arm and hand-over IK on ARMAR-III."""

from __future__ import annotations

import numpy as np
import pytest

from prehensile import robots
from prehensile.collision import ExactChecker
from prehensile.errors import PrehensileError
from prehensile.ik import ChainSolver, IKStatus, collision_filter
from prehensile.ik.hybrid import HybridIKSettings, ObjectRegion, solve_ik_hybrid, solve_regrasp_ik
from prehensile.spatial import invert, matrix_to_rpy, rotation_error


@pytest.fixture(scope="module")
def armar():
    model = robots.load("armar3")
    return model, ChainSolver(model, "LeftArm"), ChainSolver(model, "RightArm"), ExactChecker(model, [])


def free_two_arm_configurations(model, exact, n, seed):
    """n collision-free configurations with random arms and torso at rest."""
    rng, out = np.random.default_rng(seed), []
    arms = np.concatenate([model.chain_q_indices("LeftArm"), model.chain_q_indices("RightArm")])
    while len(out) < n:
        q = model.neutral_configuration()
        q[arms] = model.random_configurations(rng)[arms]
        if exact.is_free(q):
            out.append(q)
    return out


def test_dual_arm_ik_reaches_both_hands(armar):
    model, left, right, exact = armar
    valid = collision_filter(exact_checker=exact)
    solved = 0
    for i, q in enumerate(free_two_arm_configurations(model, exact, 20, seed=0)):
        targets = [left.tool_pose(q), right.tool_pose(q)]
        result = solve_ik_hybrid([left, right], targets, "Torso", rng=i, is_valid=valid,
                                 settings=HybridIKSettings(time_budget_s=0.2))
        if result.success:
            solved += 1
            assert exact.is_free(result.q) and model.within_limits(result.q)
            for solver, target in zip((left, right), targets):
                assert np.linalg.norm(solver.tool_pose(result.q)[:3, 3] - target[:3, 3]) <= 1e-4
            assert result.target_indices == (0, 0)
    assert solved >= 16


def test_same_seed_same_result_and_bad_arguments(armar):
    model, left, right, exact = armar
    q = free_two_arm_configurations(model, exact, 1, seed=3)[0]
    targets = [left.tool_pose(q), right.tool_pose(q)]
    a = solve_ik_hybrid([left, right], targets, "Torso", rng=5)
    b = solve_ik_hybrid([left, right], targets, "Torso", rng=5)
    assert a.status == b.status and np.array_equal(a.q, b.q)
    with pytest.raises(PrehensileError, match="targets"):
        solve_ik_hybrid([left, right], targets[:1])
    with pytest.raises(PrehensileError, match="overlap"):
        solve_ik_hybrid([left], targets[:1], free=["Shoulder_1_L"])
    torso_arms = [ChainSolver(model, "TorsoLeftArm"), ChainSolver(model, "TorsoRightArm")]  # solving one moves both
    with pytest.raises(PrehensileError, match="'TorsoLeftArm' and 'TorsoRightArm' share Hip_Pitch"):
        solve_ik_hybrid(torso_arms, targets)
    far = np.eye(4)
    far[:3, 3] = [0.0, 0.0, 9.0]
    timeout = solve_ik_hybrid([left], [far], "Torso", rng=0, settings=HybridIKSettings(time_budget_s=0.02))
    assert timeout.status is IKStatus.TIMEOUT and 0.02 <= timeout.time_s < 0.02 + 0.2
    capped = solve_ik_hybrid([left], [far], "Torso", rng=0, settings=HybridIKSettings(time_budget_s=60, max_samples=3))
    assert capped.status is IKStatus.NOT_CONVERGED and capped.restarts == 2  # samples before the last
    with pytest.raises(PrehensileError, match="HybridIKSettings.max_samples must be an integer >= 1 or None, got 0"):
        HybridIKSettings(max_samples=0)
    region = ObjectRegion((0.0, 0.0, 8.9), (0.1, 0.1, 9.0))  # out of reach
    result, _ = solve_regrasp_ik([left, right], [np.eye(4)[None]] * 2, region, "Torso", rng=0, time_budget_s=60,
                                 max_batches=2)
    assert result.status is IKStatus.NOT_CONVERGED and result.restarts == 32  # two batches of 16 attempts


def _tool_errors(solver, q, target):
    """Position (m) and rotation (rad) error of the solver's tool at q to ``target`` (4, 4)."""
    tool = solver.tool_pose(q)
    return np.linalg.norm(tool[:3, 3] - target[:3, 3]), np.linalg.norm(rotation_error(target[:3, :3], tool[:3, :3]))


def test_failed_hybrid_ik_reports_its_closest_attempt(armar):
    model, left, right, exact = armar
    q = free_two_arm_configurations(model, exact, 1, seed=3)[0]
    far = np.eye(4)
    far[:3, 3] = [0.0, 0.0, 9.0]
    for settings in (HybridIKSettings(time_budget_s=0.02), HybridIKSettings(time_budget_s=60, max_samples=3)):
        result = solve_ik_hybrid([left], [far], "Torso", rng=0, settings=settings)
        assert not result.success and result.target_indices == (0,)
        assert 6.0 < result.position_error < 9.0  # the errors of its q, not inf
        assert (result.position_error, result.rotation_error) == pytest.approx(_tool_errors(left, result.q, far))
    # the left arm solved, the right one failed: the larger errors, the right arm's
    result = solve_ik_hybrid([left, right], [left.tool_pose(q), far], "Torso", rng=0,
                             settings=HybridIKSettings(time_budget_s=60, max_samples=2))
    assert result.status is IKStatus.NOT_CONVERGED and result.target_indices == (0, 0)
    assert (result.position_error, result.rotation_error) == pytest.approx(_tool_errors(right, result.q, far))
    assert _tool_errors(left, result.q, left.tool_pose(q))[0] <= 1e-4
    # the left arm failed, the right one was not tried: the left arm's errors
    result = solve_ik_hybrid([left, right], [far, right.tool_pose(q)], "Torso", rng=0,
                             settings=HybridIKSettings(time_budget_s=60, max_samples=2))
    assert result.status is IKStatus.NOT_CONVERGED and result.target_indices == (0,)
    assert 6.0 < result.position_error < 9.0
    assert (result.position_error, result.rotation_error) == pytest.approx(_tool_errors(left, result.q, far))
    # solutions that is_valid rejects count: errors within the tolerances
    result = solve_ik_hybrid([left, right], [left.tool_pose(q), right.tool_pose(q)], "Torso", rng=0,
                             settings=HybridIKSettings(time_budget_s=60, max_samples=2), is_valid=lambda q: False)
    assert result.status is IKStatus.NOT_CONVERGED and result.solutions.shape == (0, model.dof)
    assert result.position_error <= 1e-4 and result.rotation_error <= 1e-3
    assert _tool_errors(right, result.q, right.tool_pose(q))[0] <= 1e-4
    # no attempt at all: inf, and the seed
    result = solve_ik_hybrid([left], [far], "Torso", q, rng=0, settings=HybridIKSettings(time_budget_s=1e-9))
    assert result.position_error == result.rotation_error == np.inf and np.array_equal(result.q, q)


def test_failed_regrasp_ik_reports_its_closest_attempt(armar):
    model, left, right, exact = armar
    q = free_two_arm_configurations(model, exact, 1, seed=7)[0]
    T_world_left, T_world_right = left.tool_pose(q), right.tool_pose(q)
    grasps = [np.eye(4)[None], (invert(T_world_left) @ T_world_right)[None]]
    p, rpy = T_world_left[:3, 3], matrix_to_rpy(T_world_left[:3, :3])
    region = ObjectRegion(tuple(p - 0.02), tuple(p + 0.02), tuple(rpy - 0.05), tuple(rpy + 0.05))
    result, T_world_object = solve_regrasp_ik([left, right], grasps, region, "Torso", rng=0, time_budget_s=60,
                                              max_batches=2, is_valid=lambda q: False)
    assert result.status is IKStatus.NOT_CONVERGED and T_world_object is None and result.target_indices == (0, 0)
    assert result.position_error <= 1e-4 and result.rotation_error <= 1e-3  # a solution is_valid rejected
    hands = invert(left.tool_pose(result.q)) @ right.tool_pose(result.q)  # holding the object by both grasps
    np.testing.assert_allclose(hands, grasps[1][0], atol=1e-3)
    far = ObjectRegion((0.0, 0.0, 8.9), (0.1, 0.1, 9.0))  # no attempt passes the reachability test
    result, _ = solve_regrasp_ik([left, right], [np.eye(4)[None]] * 2, far, "Torso", q, rng=0, time_budget_s=60,
                                 max_batches=1)
    assert result.position_error == result.rotation_error == np.inf and np.array_equal(result.q, q)


def test_regrasp_ik_finds_a_hand_over_pose(armar):
    model, left, right, exact = armar
    q = free_two_arm_configurations(model, exact, 1, seed=7)[0]
    T_world_left, T_world_right = left.tool_pose(q), right.tool_pose(q)
    grasps = [np.eye(4)[None], (invert(T_world_left) @ T_world_right)[None]]  # the object is at the left TCP
    p, rpy = T_world_left[:3, 3], matrix_to_rpy(T_world_left[:3, :3])
    region = ObjectRegion(tuple(p - 0.02), tuple(p + 0.02), tuple(rpy - 0.05), tuple(rpy + 0.05))
    result, T_world_object = solve_regrasp_ik([left, right], grasps, region, "Torso", rng=0, time_budget_s=30.0,
                                              is_valid=collision_filter(exact_checker=exact))
    assert result.success and T_world_object is not None
    np.testing.assert_allclose(left.tool_pose(result.q)[:3, 3], T_world_object[:3, 3], atol=1e-4)
    np.testing.assert_allclose(right.tool_pose(result.q)[:3, 3], (T_world_object @ grasps[1][0])[:3, 3], atol=1e-4)
    assert exact.is_free(result.q)
