"""Rotations and transforms against scipy and algebraic identities."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from prehensile.errors import PrehensileError
from prehensile.spatial import (
    axis_angle_to_matrix, check_pose, invert, make_pose, matrix_to_rpy, quaternion_to_matrix,
    rotation_error, rpy_to_matrix,
)


def test_rpy_matches_scipy_fixed_axes_and_round_trips():
    rpy = np.random.default_rng(0).uniform([-np.pi, -1.5, -np.pi], [np.pi, 1.5, np.pi], (500, 3))
    R = rpy_to_matrix(rpy)
    assert np.allclose(R, Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
    assert np.allclose(matrix_to_rpy(R), rpy, atol=1e-9)


def test_rpy_round_trips_at_and_near_gimbal_lock():
    """At pitch +-pi/2 only roll -+ yaw is defined; the angles found must still give the
    rotation back (a scene file saved with them must load the same pose)."""
    rng = np.random.default_rng(1)
    rpy = rng.uniform(-np.pi, np.pi, (2000, 3))
    rpy[:, 1] = np.where(rng.uniform(size=2000) < 0.5, -0.5, 0.5) * np.pi + rng.normal(0.0, 1e-6, 2000)
    rpy[:10, 1] = 0.5 * np.pi  # exactly
    locked = quaternion_to_matrix(np.array([[0.5, 0.5, 0.5, -0.5], [0, 0.7071068, 0, -0.7071068]]))
    for R in (rpy_to_matrix(rpy), locked, Rotation.random(2000, random_state=2).as_matrix()):
        np.testing.assert_allclose(rpy_to_matrix(matrix_to_rpy(R)), R, atol=1e-12)


def test_make_pose_takes_rpy_instead_of_a_rotation():
    rpy = np.random.default_rng(5).uniform(-np.pi, np.pi, (4, 3))
    T = make_pose(rpy=rpy, position=[0.1, 0.2, 0.3])  # a batch of rotations, one position
    assert T.shape == (4, 4, 4)
    assert np.allclose(T[:, :3, :3], Rotation.from_euler("xyz", rpy).as_matrix(), atol=1e-12)
    assert np.array_equal(T[:, :3, 3], np.tile([0.1, 0.2, 0.3], (4, 1))) and np.array_equal(T[:, 3], [[0, 0, 0, 1]] * 4)
    assert np.array_equal(make_pose(rpy=[0.0, 0.0, 0.0]), np.eye(4))
    with pytest.raises(PrehensileError, match="make_pose: give rotation or rpy, not both"):
        make_pose(np.eye(3), rpy=[0.0, 0.0, 0.1])
    with pytest.raises(PrehensileError, match=r"make_pose: rpy must be \(\.\.\., 3\).*got shape \(2,\)"):
        make_pose(rpy=[0.1, 0.2])
    with pytest.raises(PrehensileError, match=r"position \(\.\.\., 3\) \(m\), got shapes \(3, 3\) and \(2,\)"):
        make_pose(position=[1.0, 2.0])
    with pytest.raises(PrehensileError, match=r"batch shapes of rotation \(2, 3, 3\) and position \(3, 3\)"):
        make_pose(np.stack([np.eye(3)] * 2), np.zeros((3, 3)))


def test_quaternion_and_axis_angle_match_scipy():
    rng = np.random.default_rng(1)
    quat = rng.normal(size=(200, 4))
    expected = Rotation.from_quat(quat[:, [1, 2, 3, 0]]).as_matrix()
    assert np.allclose(quaternion_to_matrix(quat), expected, atol=1e-12)
    rotvec = rng.normal(size=(200, 3))
    angle = np.linalg.norm(rotvec, axis=-1)
    assert np.allclose(axis_angle_to_matrix(rotvec / angle[:, None], angle), Rotation.from_rotvec(rotvec).as_matrix())
    with pytest.raises(PrehensileError, match="non-zero"):
        quaternion_to_matrix([0, 0, 0, 0])


def test_rotation_error_is_the_relative_rotation_vector_up_to_pi():
    rng = np.random.default_rng(2)
    R_current = Rotation.random(300, random_state=3).as_matrix()
    rotvec = rng.normal(size=(300, 3))
    rotvec *= (rng.uniform(0, np.pi, 300) / np.linalg.norm(rotvec, axis=-1))[:, None]
    rotvec[0] = [np.pi, 0, 0]
    rotvec[1] = [0, 0, 0]
    R_target = Rotation.from_rotvec(rotvec).as_matrix() @ R_current
    error = rotation_error(R_target, R_current)
    assert np.allclose(Rotation.from_rotvec(error).as_matrix() @ R_current, R_target, atol=1e-9)


def test_invert_and_check_pose():
    T = make_pose(Rotation.random(10, random_state=4).as_matrix(), np.arange(30.0).reshape(10, 3))
    assert np.allclose(T @ invert(T), np.eye(4))
    assert check_pose(T) is not None
    bad = T[0].copy()
    bad[0, 0] = np.nan
    with pytest.raises(PrehensileError, match="NaN"):
        check_pose(bad, "target")
    bad = T[0].copy()
    bad[:3, :3] *= 2
    with pytest.raises(PrehensileError, match="target: upper-left 3x3 block is not a rotation"):
        check_pose(bad, "target")
