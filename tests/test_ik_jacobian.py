"""Jacobian IK and random-restart complete IK: round trips on every bundled chain, limits,
statuses, pose sets, collision rejection, determinism."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import erd_robot

from prehensile import robots
from prehensile.collision import ExactChecker, Obstacle
from prehensile.errors import PrehensileError
from prehensile.ik import (ChainSolver, CompleteIKSettings, IKStatus, JacobianIKSettings, collision_filter,
                           solve_ik, solve_ik_complete)
from prehensile.ik import kernels
from prehensile.kinematics import forward_kinematics, frame_jacobian
from prehensile.model.geometry import Sphere
from prehensile.spatial import make_pose, rotation_error

CHAINS = [("panda", "arm"), ("armar3", "TorsoRightArm"), ("armar3", "LeftArm"), ("nao", "left_arm"),
          ("nao", "right_arm"), ("nao", "left_arm_wrist")]


def chain_targets(model, chain, n, seed=0):
    """n configurations with random chain joints (others neutral) and their tool poses."""
    q = np.tile(model.neutral_configuration(), (n, 1))
    idx = model.chain_q_indices(chain)
    q[:, idx] = model.random_configurations(np.random.default_rng(seed), n)[:, idx]
    return q, ChainSolver(model, chain).tool_pose(q)


def assert_reaches(solver, result, target, pos_tol=1e-4, rot_tol=1e-3):
    pose = solver.tool_pose(result.q)
    assert np.linalg.norm(pose[:3, 3] - target[:3, 3]) <= pos_tol
    if not solver.settings.position_only:
        assert np.linalg.norm(rotation_error(target[:3, :3], pose[:3, :3])) <= rot_tol
    assert solver.model.within_limits(result.q)


@pytest.mark.parametrize("robot,chain", CHAINS)
def test_dls_round_trips(robot, chain):
    model = robots.load(robot)
    solver = ChainSolver(model, chain)
    _, targets = chain_targets(model, chain, 60)
    q0 = model.neutral_configuration()
    for i, target in enumerate(targets):
        result = solve_ik_complete(solver, target, q0, rng=i, settings=CompleteIKSettings(time_budget_s=0.2))
        assert result.status is IKStatus.SUCCESS, (i, result)
        assert_reaches(solver, result, target)
        assert result.position_error <= 1e-4 and result.rotation_error <= 1e-3
        untouched = np.setdiff1d(np.arange(model.dof), solver.var_q)
        assert np.array_equal(result.q[untouched], q0[untouched])


@pytest.mark.parametrize("method", ["pinv", "transpose"])
@pytest.mark.parametrize("robot,chain", [("panda", "arm"), ("nao", "left_arm")])
def test_other_methods_round_trip(robot, chain, method):
    model = robots.load(robot)
    position_only = method == "transpose"  # the transpose method is slow in 6-D (Buss 2004)
    settings = JacobianIKSettings(method=method, position_only=position_only)
    solver = ChainSolver(model, chain, settings=settings)
    _, targets = chain_targets(model, chain, 30, seed=1)
    q0 = model.neutral_configuration()
    for i, target in enumerate(targets):
        goal = target[:3, 3] if position_only else target
        result = solve_ik_complete(solver, goal, q0, rng=i, settings=CompleteIKSettings(time_budget_s=0.5))
        assert result.success, (method, i, result.status, result.position_error)
        assert_reaches(solver, result, target)


def test_chain_kernel_matches_frame_jacobian_and_finite_differences():
    model = robots.load("armar3")
    solver = ChainSolver(model, "TorsoRightArm", T_tip_tcp=np.array([[1, 0, 0, 0.01], [0, 1, 0, 0.02],
                                                                     [0, 0, 1, 0.03], [0, 0, 0, 1.0]]))
    q = model.random_configurations(np.random.default_rng(3))
    pose, jac = np.empty((4, 4)), np.empty((6, solver.n))
    frames = np.empty((len(solver.table), 3, 4))
    kernels.chain_pose_jacobian(q, solver.T_world_root, solver.table, solver.var_of_q, solver.T_tip_tcp, frames,
                                pose, jac)
    ref_pose, ref_jac = frame_jacobian(model, q, solver.chain.tip_link, solver.T_tip_tcp)
    np.testing.assert_allclose(pose, ref_pose, atol=1e-12)
    np.testing.assert_allclose(jac, ref_jac[:, solver.var_q], atol=1e-12)
    h = 1e-7
    for c, qi in enumerate(solver.var_q):
        dq = np.zeros(model.dof)
        dq[qi] = h
        p1, p0 = solver.tool_pose(q + dq), solver.tool_pose(q - dq)
        np.testing.assert_allclose((p1[:3, 3] - p0[:3, 3]) / (2 * h), jac[:3, c], atol=1e-6)
        np.testing.assert_allclose(rotation_error(p1[:3, :3], p0[:3, :3]) / (2 * h), jac[3:, c], atol=1e-6)


def test_unreachable_target_is_a_status_within_budget():
    model = robots.load("panda")
    solver = ChainSolver(model, "arm")
    target = np.eye(4)
    target[:3, 3] = [3.0, 0.0, 0.5]
    result = solve_ik_complete(solver, target, rng=0, settings=CompleteIKSettings(time_budget_s=0.02))
    assert result.status is IKStatus.TIMEOUT
    assert result.solutions.shape == (0, model.dof)
    assert 0.02 <= result.time_s < 0.02 + 0.2  # stops after the budget; the margin absorbs host noise
    assert result.restarts > 0 and model.within_limits(result.q)
    capped = solve_ik_complete(solver, target, rng=0, settings=CompleteIKSettings(time_budget_s=10, max_restarts=5))
    assert capped.status is IKStatus.NOT_CONVERGED and capped.restarts == 5
    local = solve_ik(model, "arm", target)
    assert local.status is IKStatus.NOT_CONVERGED and local.position_error > 1.0


def test_a_failed_solve_returns_the_closest_configuration_tried():
    """Not the last one tried: over restarts, the one nearest its target (in tolerances), with its own errors."""
    model = robots.load("panda")
    solver = ChainSolver(model, "arm", settings=JacobianIKSettings(position_only=True))
    target = np.array([1.5, 0.3, 0.4])  # 0.6 m beyond reach
    seeded = solver.solve(target)
    result = solve_ik_complete(solver, target, rng=0, settings=CompleteIKSettings(max_restarts=12))
    assert result.status is IKStatus.NOT_CONVERGED
    tcp = forward_kinematics(model, result.q)[model.link_index(model.chain("arm").tip_link)] @ solver.T_tip_tcp
    assert result.position_error == pytest.approx(np.linalg.norm(tcp[:3, 3] - target), abs=1e-9)
    assert result.position_error <= seeded.position_error + 1e-12
    single = [solver.solve(target, q).position_error for q in model.random_configurations(np.random.default_rng(1), 12)]
    assert result.position_error <= np.median(single)  # the last restart is often farther


def test_pose_set_any_one_will_do():
    model = robots.load("panda")
    solver = ChainSolver(model, "arm")
    _, targets = chain_targets(model, "arm", 2, seed=5)
    far = np.eye(4)
    far[:3, 3] = [0.0, 0.0, 5.0]
    result = solve_ik_complete(solver, np.stack([far, targets[1], far]), rng=0,
                               settings=CompleteIKSettings(time_budget_s=0.5))
    assert result.success and result.target_index == 1
    assert_reaches(solver, result, targets[1])


def test_pose_set_is_solved_first_for_the_pose_nearest_the_seed():
    """Of two reachable poses, the seed sits at the second: that one is the answer, unmoved."""
    model = robots.load("panda")
    solver = ChainSolver(model, "arm")
    seeds, targets = chain_targets(model, "arm", 2, seed=5)
    result = solve_ik_complete(solver, targets, seeds[1], rng=0)
    assert result.success and result.target_index == 1 and result.iterations <= 1
    assert np.abs(result.q - seeds[1]).max() < 1e-9


def test_same_seed_same_result_and_position_only():
    model = robots.load("panda")
    solver = ChainSolver(model, "arm", settings=JacobianIKSettings(position_only=True, position_tolerance=1e-5))
    point = np.array([0.4, 0.3, 0.5])
    start = np.array([0, -1.5, 0, -2.9, 0, 0.2, 0, 0.02, 0.02])[:model.dof]
    a = solve_ik_complete(solver, point, start, rng=7)
    b = solve_ik_complete(solver, point, start, rng=7)
    assert a.success and np.array_equal(a.q, b.q) and a.iterations == b.iterations
    assert np.linalg.norm(solver.tool_pose(a.q)[:3, 3] - point) <= 1e-5 and a.rotation_error == 0.0


def test_zero_weight_rows_are_free():
    """A free world yaw or a free height: targets that differ from the seed's pose only there are
    met at once, and targets that differ elsewhere are reached in the rows kept."""
    from prehensile.spatial import rpy_to_matrix

    model = robots.load("panda")
    q = model.neutral_configuration()
    q[:7] = [0.1, -0.3, 0.2, -2.0, 0.1, 1.8, 0.7]
    for weights, row in [((1, 1, 1, 1, 1, 0), 5), ((1, 1, 0, 1, 1, 1), 2)]:
        solver = ChainSolver(model, "arm", settings=JacobianIKSettings(weights=weights))
        T = solver.tool_pose(q)
        moved = T.copy()
        if row == 5:
            moved[:3, :3] = rpy_to_matrix([0, 0, 0.5]) @ T[:3, :3]
        else:
            moved[2, 3] += 0.05
        result = solver.solve(moved, q)
        assert result.success and result.iterations == 0
        moved[0, 3] += 0.03  # now a kept row differs too
        result = solve_ik_complete(solver, moved, q, rng=0, settings=CompleteIKSettings(time_budget_s=0.5))
        reached = solver.tool_pose(result.q)
        assert result.success and abs(reached[0, 3] - moved[0, 3]) <= 1e-4


def test_collision_filter_rejects_colliding_solutions():
    model = robots.load("panda")
    solver = ChainSolver(model, "arm", settings=JacobianIKSettings(position_only=True))
    point = np.array([0.45, 0.1, 0.3])
    first = solve_ik_complete(solver, point, rng=1)
    assert first.success
    # a ball where that solution's elbow is: the same query must now find another solution
    elbow = forward_kinematics(model, first.q)[model.link_index("panda_link4"), :3, 3]
    ball = Obstacle("ball", Sphere(0.08), make_pose(position=elbow))
    exact = ExactChecker(model, [ball])
    assert not exact.is_free(first.q)
    result = solve_ik_complete(solver, point, rng=1, settings=CompleteIKSettings(time_budget_s=2.0),
                               is_valid=collision_filter(exact_checker=exact))
    assert result.success and exact.is_free(result.q)
    assert np.linalg.norm(solver.tool_pose(result.q)[:3, 3] - point) <= 1e-4
    rejected = solve_ik_complete(solver, point, rng=1, is_valid=lambda q: False,
                                 settings=CompleteIKSettings(time_budget_s=0.01))
    assert rejected.status is IKStatus.TIMEOUT


def test_any_urdf_with_base_and_tip():
    model = robots.load(erd_robot("ur_description/urdf/ur5_robot.urdf"))
    solver = ChainSolver(model, base="base_link", tip="tool0")
    assert solver.n == 6
    q = model.random_configurations(np.random.default_rng(2))
    target = solver.tool_pose(q)
    result = solve_ik_complete(solver, target, rng=0, settings=CompleteIKSettings(time_budget_s=0.5))
    assert result.success
    assert_reaches(solver, result, target)


@pytest.mark.parametrize("bad", [np.full((4, 4), np.nan), np.diag([2.0, 1.0, 1.0, 1.0]), np.eye(3),
                                 np.diag([1.0, 1.0, -1.0, 1.0])])
def test_malformed_targets_raise(bad):
    solver = ChainSolver(robots.load("panda"), "arm")
    with pytest.raises(PrehensileError):
        solver.solve(bad)


def test_bad_settings_and_chains_raise():
    model = robots.load("panda")
    with pytest.raises(PrehensileError, match="dls"):
        JacobianIKSettings(method="newton")
    for bad, message in [({"damping": -1.0}, "damping must be >= 0 and finite"), ({"damping": np.nan}, "damping"),
                         ({"max_iterations": -5}, "max_iterations must be an integer >= 1 or None"),
                         ({"max_iterations": 2.5}, "max_iterations must be an integer >= 1 or None, got 2.5"),
                         ({"stall_iterations": 0}, "stall_iterations must be an integer >= 1"),
                         ({"position_tolerance": np.inf}, "position_tolerance must be > 0 and finite"),
                         ({"weights": (1.0, 1.0, 1.0)}, "weights must be 6 finite numbers >= 0"),
                         ({"weights": (1.0,) * 5 + (np.nan,)}, "weights must be 6")]:
        with pytest.raises(PrehensileError, match=message):
            JacobianIKSettings(**bad)
    with pytest.raises(PrehensileError,
                       match="CompleteIKSettings.max_restarts must be an integer >= 0 or None, got -1"):
        CompleteIKSettings(max_restarts=-1)
    with pytest.raises(PrehensileError, match=r"q_seed: expected one configuration \(8,\)"):
        ChainSolver(model, "arm").solve(ChainSolver(model, "arm").tool_pose(model.neutral_configuration()),
                                        np.zeros((2, 8)))
    with pytest.raises(PrehensileError, match="position_only"):
        ChainSolver(model, "arm").solve(np.zeros(3))
    with pytest.raises(KeyError):
        ChainSolver(model, "leg")
    with pytest.raises(PrehensileError):
        ChainSolver(model, base="panda_hand", tip="panda_link3")


def test_a_continuous_joint_is_solved_past_pi_and_a_seed_outside_the_limits_is_clipped():
    """Continuous joints have no limits (the solver used to clamp them to [-pi, pi]); a seed
    beyond a finite limit starts inside it, so no solution lies outside the limits."""
    from prehensile.model.builder import JointSpec, LinkSpec, build_model

    links = [LinkSpec("base"), LinkSpec("turn"), LinkSpec("arm"), LinkSpec("tip")]
    joints = [JointSpec("spin", "continuous", "base", "turn", np.eye(4), [0, 0, 1.0]),
              JointSpec("lift", "revolute", "turn", "arm", make_pose(position=[0.3, 0, 0]), [0, 1.0, 0], -1.0, 1.0),
              JointSpec("tool", "fixed", "arm", "tip", make_pose(position=[0.2, 0, 0]))]
    model = build_model("spinner", "test", links, joints)
    solver = ChainSolver(model, base="base", tip="tip")
    for seed, goal in (([3.0, 0.2], [3.3, 0.2]), ([5.0, 0.2], [5.05, 0.25])):
        result = solver.solve(solver.tool_pose(np.array(goal)), np.array(seed))
        assert result.success and abs(result.q[0] - goal[0]) < 1e-3, result
    beyond = np.array([0.0, 1.5])  # lift's limit is 1: only configurations outside the limits reach this pose
    result = solve_ik_complete(solver, solver.tool_pose(beyond), beyond, rng=0,
                               settings=CompleteIKSettings(max_restarts=8))
    assert not result.success and model.within_limits(result.q)


def test_a_large_unreachable_pose_set_keeps_the_budget():
    """The seed's round over 500 poses used to run in one compiled call: 180 ms on a 5 ms budget."""
    model = robots.load("panda")
    solver = ChainSolver(model, "arm", settings=JacobianIKSettings(method="pinv"))
    far = np.tile(np.eye(4), (500, 1, 1))
    far[:, :3, 3] = np.random.default_rng(0).uniform(2.0, 3.0, (500, 3))
    result = solve_ik_complete(solver, far, rng=0, settings=CompleteIKSettings(time_budget_s=0.02))
    assert result.status is IKStatus.TIMEOUT and result.time_s < 0.02 + 0.1
