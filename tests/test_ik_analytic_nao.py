"""Closed-form NAO arm IK (prehensile.ik.analytic_nao) against the model's forward kinematics."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from prehensile import robots
from prehensile.errors import PrehensileError
from prehensile.ik.analytic_nao import MAX_SOLUTIONS, nao_arm_ik, nao_arm_ik_batch
from prehensile.ik.result import IKStatus
from prehensile.kinematics import link_pose
from prehensile.spatial.transforms import axis_angle_to_matrix

CHAINS = ["left_arm", "right_arm", "left_arm_wrist", "right_arm_wrist"]
MIRROR = np.diag([1.0, -1.0, 1.0, 1.0])  # y-mirror: the right arm is the mirror of the left


@pytest.fixture(scope="module")
def nao():
    return robots.load("nao")


def tip(model, chain: str) -> str:
    return model.chain(chain).tip_link


def configuration(model, chain: str, chain_q) -> np.ndarray:
    q = model.neutral_configuration()
    q[model.chain_q_indices(chain)] = chain_q
    return q


def pose_errors(T: np.ndarray, T_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Position (m) and rotation angle (rad, via the chord |R - R_ref|_F = √8 sin(angle / 2))."""
    pos = np.linalg.norm(T[..., :3, 3] - T_ref[..., :3, 3], axis=-1)
    chord = np.linalg.norm(T[..., :3, :3] - T_ref[..., :3, :3], axis=(-2, -1)) / np.sqrt(8.0)
    return pos, 2.0 * np.arcsin(np.minimum(chord, 1.0))


def mirrored(chain_q) -> np.ndarray:
    """Right-arm joint values of the y-mirrored left-arm configuration (pitch keeps its sign)."""
    return np.concatenate([[chain_q[0]], -np.asarray(chain_q[1:])])


def rotated(T: np.ndarray, axis, angle: float) -> np.ndarray:
    """T with its orientation turned by ``angle`` about the world ``axis``; position kept."""
    out = T.copy()
    out[:3, :3] = axis_angle_to_matrix(np.asarray(axis, float) / np.linalg.norm(axis), angle) @ T[:3, :3]
    return out


@pytest.mark.parametrize("chain", CHAINS)
def test_round_trip_recovers_every_configuration(nao, chain):
    rng = np.random.default_rng(CHAINS.index(chain))
    Q = nao.random_configurations(rng, 2000)
    idx = nao.chain_q_indices(chain)
    T = link_pose(nao, Q, tip(nao, chain))
    sols, counts = nao_arm_ik_batch(nao, chain, T)
    assert sols.shape == (2000, MAX_SOLUTIONS, len(idx)) and counts.shape == (2000,)
    assert np.all(counts >= 1)
    valid = np.arange(MAX_SOLUTIONS)[None] < counts[:, None]
    assert np.all(np.isnan(sols[~valid]))
    # the original chain configuration is among the solutions
    distance = np.where(valid, np.max(np.abs(sols - Q[:, None, idx]), axis=2), np.inf)
    assert np.all(distance.min(axis=1) < 1e-6)
    # every solution reproduces its target and lies within the limits
    full = np.repeat(Q[:, None], MAX_SOLUTIONS, axis=1)[valid]
    full[:, idx] = sols[valid]
    pos, rot = pose_errors(link_pose(nao, full, tip(nao, chain)), np.repeat(T[:, None], MAX_SOLUTIONS, axis=1)[valid])
    assert pos.max() < 1e-9 and rot.max() < 1e-9
    assert np.all(nao.within_limits(full, tol=0.0))


SPECIAL = {
    "elbow yaw +90, roll != 0": (0.4, 0.6, np.pi / 2, -0.7),
    "elbow yaw +90, roll = 0": (0.4, 0.0, np.pi / 2, -0.7),
    "elbow yaw -90, roll = 0": (-1.2, 0.0, -np.pi / 2, -1.2),
    "straight arm at the ElbowRoll limit": (0.3, 0.2, 1.0, -0.0349),
    "straight arm, elbow yaw 0": (0.0, 0.0, 0.0, -0.0349),
    "nearly straight, elbow yaw at its limit": (-1.0, 0.5, -2.0857, -0.035),
    "shoulder at its limits": (2.0857, 1.3265, 0.0, -1.5446),
    "shoulder roll at its lower limit": (-2.0857, -0.3142, 2.0857, -0.5),
    "digest general pose": (0.3, 0.2, -1.0, -0.8),
}


@pytest.mark.parametrize("wrist", [None, 0.0, 1.2])
@pytest.mark.parametrize("side", ["left", "right"])
@pytest.mark.parametrize("case", SPECIAL)
def test_special_configurations(nao, case, side, wrist):
    left_q = SPECIAL[case] if wrist is None else SPECIAL[case] + (wrist,)
    chain = f"{side}_arm" if wrist is None else f"{side}_arm_wrist"
    q = configuration(nao, chain, left_q if side == "left" else mirrored(left_q))
    target = link_pose(nao, q, tip(nao, chain))
    result = nao_arm_ik(nao, chain, target, q_seed=q)
    assert result.status is IKStatus.SUCCESS
    assert np.max(np.abs(result.q - q)) < 1e-6  # the seed itself is the closest solution
    assert result.position_error < 1e-9 and result.rotation_error < 1e-9
    pos, rot = pose_errors(link_pose(nao, result.solutions, tip(nao, chain)), target)
    assert pos.max() < 1e-9 and rot.max() < 1e-9


def test_digest_fixture(nao):
    """Digest §7.2 'general' pose (exact model): the left hand at (198.28, 95.96, 103.54) mm."""
    q = configuration(nao, "left_arm", (0.3, 0.2, -1.0, -0.8))
    target = link_pose(nao, q, "l_arm_tip")
    np.testing.assert_allclose(target[:3, 3] * 1e3, [198.28, 95.96, 103.54], atol=0.01)
    result = nao_arm_ik(nao, "left_arm", target)
    np.testing.assert_allclose(result.q[nao.chain_q_indices("left_arm")], (0.3, 0.2, -1.0, -0.8), atol=1e-9)


@pytest.mark.parametrize("wrist", [False, True])
def test_mirror_symmetry(nao, wrist):
    left, right = ("left_arm_wrist", "right_arm_wrist") if wrist else ("left_arm", "right_arm")
    Q = nao.random_configurations(np.random.default_rng(7), 300)
    T_left = link_pose(nao, Q, tip(nao, left))
    left_sols, left_counts = nao_arm_ik_batch(nao, left, T_left)
    right_sols, right_counts = nao_arm_ik_batch(nao, right, MIRROR @ T_left @ MIRROR)
    np.testing.assert_array_equal(left_counts, right_counts)
    expected = left_sols.copy()
    expected[..., 1:] *= -1.0
    np.testing.assert_allclose(right_sols, expected, atol=1e-9)


@pytest.mark.parametrize("chain", CHAINS)
def test_slightly_inconsistent_orientation_keeps_position_exact(nao, chain):
    """The position stays exact and the rotation error is at most the perturbation (module §2)."""
    rng = np.random.default_rng(11)
    for _ in range(20):
        q = nao.random_configurations(rng)
        target = rotated(link_pose(nao, q, tip(nao, chain)), rng.normal(size=3), 1e-3)
        assert nao_arm_ik(nao, chain, target).status is IKStatus.UNREACHABLE
        loose = nao_arm_ik(nao, chain, target, tolerance=(1e-6, 2e-3))
        assert loose.success and loose.position_error < 1e-12 and loose.rotation_error <= 1e-3 + 1e-9
        pos, rot = pose_errors(link_pose(nao, loose.solutions, tip(nao, chain)), target)
        assert pos.max() < 1e-12 and rot.max() <= 2e-3
        tiny = nao_arm_ik(nao, chain, rotated(link_pose(nao, q, tip(nao, chain)), rng.normal(size=3), 1e-9))
        assert tiny.success and tiny.position_error < 1e-12 and tiny.rotation_error <= 1e-9 + 1e-12


@pytest.mark.parametrize("chain", CHAINS)
def test_unreachable_orientation(nao, chain):
    q = configuration(nao, chain, (0.3, 0.2, -1.0, -0.8, 0.5)[: len(nao.chain_q_indices(chain))])
    target = rotated(link_pose(nao, q, tip(nao, chain)), (0.3, -1.0, 0.4), 0.5)
    seed = nao.neutral_configuration()
    result = nao_arm_ik(nao, chain, target)
    assert result.status is IKStatus.UNREACHABLE and not result.success
    assert result.solutions.shape == (0, nao.dof)
    np.testing.assert_array_equal(result.q, seed)
    pos, rot = pose_errors(link_pose(nao, seed, tip(nao, chain)), target)
    assert result.position_error == pytest.approx(pos) and result.rotation_error == pytest.approx(rot, abs=1e-9)


@pytest.mark.parametrize("chain", CHAINS)
def test_unreachable_positions(nao, chain):
    shoulder = np.array([0.0, 0.098 if chain.startswith("left") else -0.098, 0.1])
    far, at_shoulder = np.eye(4), np.eye(4)
    far[:3, 3] = shoulder + [0.3, 0.0, 0.0]
    at_shoulder[:3, 3] = shoulder
    sols, counts = nao_arm_ik_batch(nao, chain, np.stack([far, at_shoulder]))
    np.testing.assert_array_equal(counts, [0, 0])
    assert np.all(np.isnan(sols))
    assert nao_arm_ik(nao, chain, far).status is IKStatus.UNREACHABLE


def test_bad_input_raises(nao):
    target = link_pose(nao, nao.neutral_configuration(), "l_arm_tip")
    nan_target, scaled, reflected = target.copy(), target.copy(), target.copy()
    nan_target[0, 3] = np.nan
    scaled[:3, :3] *= 2.0
    reflected[:3, 1] *= -1.0
    for bad in (nan_target, scaled, reflected, np.eye(3)):
        with pytest.raises(PrehensileError):
            nao_arm_ik(nao, "left_arm", bad)
        with pytest.raises(PrehensileError):
            nao_arm_ik_batch(nao, "left_arm", bad[None] if bad.ndim == 2 else bad)
    with pytest.raises(PrehensileError, match="tolerance"):
        nao_arm_ik(nao, "left_arm", target, tolerance=(0.0, 1e-6))
    with pytest.raises(PrehensileError, match="q_seed"):
        nao_arm_ik(nao, "left_arm", target, q_seed=np.zeros(4))


@pytest.mark.parametrize("robot, chain", [("nao", "left_leg"), ("nao", "head"), ("panda", "arm")])
def test_other_chains_are_rejected(robot, chain):
    if robot not in robots.available():
        pytest.skip(f"{robot} is not installed")
    model = robots.load(robot)
    target = link_pose(model, model.neutral_configuration(), model.chain(chain).tip_link)
    with pytest.raises(PrehensileError, match="not a NAO-type arm"):
        nao_arm_ik(model, chain, target)


def test_batch_agrees_with_single_calls(nao):
    rng = np.random.default_rng(3)
    targets = link_pose(nao, nao.random_configurations(rng, 60), "r_gripper")
    targets[::4] = rotated(targets[0], (1.0, 0.0, 0.0), 0.7)  # some unreachable ones
    sols, counts = nao_arm_ik_batch(nao, "right_arm_wrist", targets)
    idx = nao.chain_q_indices("right_arm_wrist")
    for target, chain_sols, count in zip(targets, sols, counts):
        result = nao_arm_ik(nao, "right_arm_wrist", target)
        assert len(result.solutions) == count
        np.testing.assert_allclose(np.sort(result.solutions[:, idx], axis=0), np.sort(chain_sols[:count], axis=0))


def test_pose_set_returns_first_reachable_pose(nao):
    good = link_pose(nao, configuration(nao, "left_arm", (0.3, 0.2, -1.0, -0.8)), "l_arm_tip")
    bad = good.copy()
    bad[0, 3] += 0.5
    result = nao_arm_ik(nao, "left_arm", np.stack([bad, good, good]))
    assert result.success and result.target_index == 1
    result = nao_arm_ik(nao, "left_arm", np.stack([bad, bad]))
    assert result.status is IKStatus.UNREACHABLE and result.target_index == 0


def test_all_branches_sorted_by_seed_without_limits(nao):
    """With ±π limits the 5-DoF pose has 4 solutions (module docstring); the seed picks the closest."""
    wide = dataclasses.replace(nao, lower=np.full(nao.dof, -np.pi), upper=np.full(nao.dof, np.pi))
    q = configuration(wide, "left_arm_wrist", (0.3, 0.2, -1.0, -0.8, 0.5))
    target = link_pose(wide, q, "l_gripper")
    result = nao_arm_ik(wide, "left_arm_wrist", target)
    assert result.success and len(result.solutions) == 4
    pos, rot = pose_errors(link_pose(wide, result.solutions, "l_gripper"), target)
    assert pos.max() < 1e-9 and rot.max() < 1e-9
    seed_distance = np.linalg.norm(result.solutions - wide.neutral_configuration(), axis=1)
    assert np.all(np.diff(seed_distance) >= 0)
    for other in result.solutions:
        assert np.max(np.abs(nao_arm_ik(wide, "left_arm_wrist", target, q_seed=other).q - other)) < 1e-12


def test_solver_follows_the_model(nao):
    """A NAO V3.2-like upper arm (90 mm, no ElbowOffsetY) read from the model still round-trips."""
    origin = nao.joint_origin.copy()
    origin[nao.link_index("LElbow"), :3, 3] = (0.090, 0.0, 0.0)
    v32 = dataclasses.replace(nao, joint_origin=origin)
    Q = v32.random_configurations(np.random.default_rng(5), 200)
    T = link_pose(v32, Q, "l_gripper")
    sols, counts = nao_arm_ik_batch(v32, "left_arm_wrist", T)
    assert np.all(counts >= 1)
    idx = v32.chain_q_indices("left_arm_wrist")
    assert np.all(np.nanmin(np.max(np.abs(sols - Q[:, None, idx]), axis=2), axis=1) < 1e-6)


@pytest.mark.parametrize("change", ["flipped ElbowYaw axis", "ElbowRoll offset", "WristYaw off the elbow"])
def test_modified_structure_is_rejected(nao, change):
    axis, origin = nao.joint_axis.copy(), nao.joint_origin.copy()
    if change == "flipped ElbowYaw axis":
        axis[nao.link_index("LElbow")] *= -1.0
    elif change == "ElbowRoll offset":
        origin[nao.link_index("LForeArm"), 0, 3] = 0.01
    else:
        origin[nao.link_index("l_wrist"), 2, 3] = 0.01
    model = dataclasses.replace(nao, joint_axis=axis, joint_origin=origin)
    with pytest.raises(PrehensileError, match="not a NAO-type arm"):
        nao_arm_ik_batch(model, "left_arm_wrist", np.eye(4)[None])
