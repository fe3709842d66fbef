"""Rotations and homogeneous transforms.

Conventions: ``T_a_b`` is the pose of frame b in frame a, a float64 array of shape
(..., 4, 4). Roll-pitch-yaw follows URDF: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``
(rotations about the fixed x, y, z axes). Quaternions are (w, x, y, z).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from prehensile.errors import PrehensileError


def rpy_to_matrix(rpy: np.ndarray) -> np.ndarray:
    """Rotation matrices from roll, pitch, yaw (rad), shape (..., 3) -> (..., 3, 3)."""
    rpy = np.asarray(rpy, dtype=float)
    cr, cp, cy = np.cos(rpy[..., 0]), np.cos(rpy[..., 1]), np.cos(rpy[..., 2])
    sr, sp, sy = np.sin(rpy[..., 0]), np.sin(rpy[..., 1]), np.sin(rpy[..., 2])
    R = np.empty(rpy.shape[:-1] + (3, 3))
    R[..., 0, 0] = cy * cp
    R[..., 0, 1] = cy * sp * sr - sy * cr
    R[..., 0, 2] = cy * sp * cr + sy * sr
    R[..., 1, 0] = sy * cp
    R[..., 1, 1] = sy * sp * sr + cy * cr
    R[..., 1, 2] = sy * sp * cr - cy * sr
    R[..., 2, 0] = -sp
    R[..., 2, 1] = cp * sr
    R[..., 2, 2] = cp * cr
    return R


def matrix_to_rpy(R: np.ndarray) -> np.ndarray:
    """Roll, pitch, yaw (rad) of rotation matrices, shape (..., 3, 3) -> (..., 3), such that
    :func:`rpy_to_matrix` gives R back to rounding everywhere, also at and near pitch +-pi/2
    (gimbal lock, where only roll - yaw or roll + yaw is defined): roll and pitch come from the
    last row, yaw from what is left of R once they are undone."""
    R = np.asarray(R, dtype=float)
    roll = np.arctan2(R[..., 2, 1], R[..., 2, 2])
    pitch = np.arctan2(-R[..., 2, 0], np.hypot(R[..., 2, 1], R[..., 2, 2]))
    Rz = R @ np.swapaxes(rpy_to_matrix(np.stack([roll, pitch, np.zeros_like(roll)], axis=-1)), -1, -2)
    yaw = np.arctan2(Rz[..., 1, 0], Rz[..., 0, 0])
    return np.stack([roll, pitch, yaw], axis=-1)


def axis_angle_to_matrix(axis: np.ndarray, angle: np.ndarray) -> np.ndarray:
    """Rodrigues' formula: unit axes (..., 3) and angles (...) in rad -> (..., 3, 3)."""
    axis = np.asarray(axis, dtype=float)
    angle = np.asarray(angle, dtype=float)[..., None, None]
    x, y, z = axis[..., 0], axis[..., 1], axis[..., 2]
    zero = np.zeros_like(x)
    K = np.stack([zero, -z, y, z, zero, -x, -y, x, zero], axis=-1).reshape(axis.shape[:-1] + (3, 3))
    eye = np.broadcast_to(np.eye(3), K.shape)
    return eye + np.sin(angle) * K + (1.0 - np.cos(angle)) * (K @ K)


def quaternion_to_matrix(quat: np.ndarray) -> np.ndarray:
    """Rotation matrices from quaternions (w, x, y, z), shape (..., 4) -> (..., 3, 3).

    The quaternion is normalised first; a zero quaternion is an error.
    """
    quat = np.asarray(quat, dtype=float)
    norm = np.linalg.norm(quat, axis=-1, keepdims=True)
    if np.any(norm < 1e-12) or not np.all(np.isfinite(quat)):
        raise PrehensileError(f"quaternion must be finite and non-zero, got {quat.tolist()}")
    w, x, y, z = np.moveaxis(quat / norm, -1, 0)
    R = np.stack(
        [
            1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y),
            2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x),
            2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y),
        ],
        axis=-1,
    )
    return R.reshape(quat.shape[:-1] + (3, 3))


def make_pose(rotation: np.ndarray | None = None, position: np.ndarray | None = None, *,
              rpy: np.ndarray | None = None) -> np.ndarray:
    """Homogeneous transform(s) (..., 4, 4) from a rotation and a position; the leading
    dimensions of the inputs broadcast.

    Args:
        rotation: rotation matrices (..., 3, 3); identity if None.
        position: positions (..., 3) in m; zero if None.
        rpy: roll, pitch, yaw (..., 3) in rad, instead of ``rotation``
            (:func:`rpy_to_matrix`: ``R = Rz(yaw) @ Ry(pitch) @ Rx(roll)``, as URDF).

    Raises:
        PrehensileError: both ``rotation`` and ``rpy`` given, or an input of another shape.
    """
    if rpy is not None:
        if rotation is not None:
            raise PrehensileError("make_pose: give rotation or rpy, not both")
        rpy = np.asarray(rpy, dtype=float)
        if rpy.shape[-1:] != (3,):
            raise PrehensileError(f"make_pose: rpy must be (..., 3) (roll, pitch, yaw in rad), got shape {rpy.shape}")
        rotation = rpy_to_matrix(rpy)
    rotation = np.eye(3) if rotation is None else np.asarray(rotation, dtype=float)
    position = np.zeros(3) if position is None else np.asarray(position, dtype=float)
    if rotation.shape[-2:] != (3, 3) or position.shape[-1:] != (3,):
        raise PrehensileError(f"make_pose: rotation must be (..., 3, 3) and position (..., 3) (m), got shapes "
                              f"{rotation.shape} and {position.shape}")
    try:
        batch = np.broadcast_shapes(rotation.shape[:-2], position.shape[:-1])
    except ValueError:
        raise PrehensileError(f"make_pose: the batch shapes of rotation {rotation.shape} and position "
                              f"{position.shape} do not broadcast") from None
    T = np.zeros(batch + (4, 4))
    T[..., :3, :3] = rotation
    T[..., :3, 3] = position
    T[..., 3, 3] = 1.0
    return T


def translation(x: float, y: float, z: float) -> np.ndarray:
    """A pure translation (m) as a 4x4 transform."""
    return make_pose(position=np.array([x, y, z], dtype=float))


def invert(T: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms, shape (..., 4, 4)."""
    T = np.asarray(T, dtype=float)
    R_t = np.swapaxes(T[..., :3, :3], -1, -2)
    return make_pose(R_t, -np.einsum("...ij,...j->...i", R_t, T[..., :3, 3]))


def rotation_error(R_target: np.ndarray, R_current: np.ndarray) -> np.ndarray:
    """Rotation vector (axis * angle, rad) taking R_current to R_target, in the world frame.

    Shapes (..., 3, 3) -> (..., 3); exact for angles up to pi.
    """
    R_err = np.asarray(R_target) @ np.swapaxes(np.asarray(R_current), -1, -2)
    cos_angle = np.clip((np.trace(R_err, axis1=-2, axis2=-1) - 1.0) / 2.0, -1.0, 1.0)
    angle = np.arccos(cos_angle)
    vee = np.stack(
        [R_err[..., 2, 1] - R_err[..., 1, 2], R_err[..., 0, 2] - R_err[..., 2, 0], R_err[..., 1, 0] - R_err[..., 0, 1]],
        axis=-1,
    )
    sin_angle = np.sin(angle)
    small = sin_angle < 1e-6
    scale = np.where(small, 0.5, angle / (2.0 * np.where(small, 1.0, sin_angle)))
    result = vee * scale[..., None]
    near_pi = small & (cos_angle < 0)
    if np.any(near_pi):
        # At pi the antisymmetric part vanishes: take the axis from the symmetric part.
        sym = (R_err[near_pi] + np.eye(3)) / 2.0
        col = np.argmax(np.diagonal(sym, axis1=-2, axis2=-1), axis=-1)
        axis = sym[np.arange(len(col)), :, col]
        axis /= np.linalg.norm(axis, axis=-1, keepdims=True)
        result[near_pi] = axis * angle[near_pi][..., None]
    return result


@njit(cache=True)
def _pose_defect(T, atol):
    """0 if every pose of T (N, 4, 4) is rigid; else 1 (not finite), 2 (not a rotation) or
    3 (bad last row)."""
    for k in range(T.shape[0]):
        for r in range(4):
            for c in range(4):
                if not np.isfinite(T[k, r, c]):
                    return 1
    for k in range(T.shape[0]):
        for i in range(3):
            for j in range(3):
                dot = T[k, i, 0] * T[k, j, 0] + T[k, i, 1] * T[k, j, 1] + T[k, i, 2] * T[k, j, 2]
                if abs(dot - (1.0 if i == j else 0.0)) > atol:
                    return 2
        det = (T[k, 0, 0] * (T[k, 1, 1] * T[k, 2, 2] - T[k, 1, 2] * T[k, 2, 1])
               - T[k, 0, 1] * (T[k, 1, 0] * T[k, 2, 2] - T[k, 1, 2] * T[k, 2, 0])
               + T[k, 0, 2] * (T[k, 1, 0] * T[k, 2, 1] - T[k, 1, 1] * T[k, 2, 0]))
        if det < 0.0:
            return 2
        if abs(T[k, 3, 0]) > atol or abs(T[k, 3, 1]) > atol or abs(T[k, 3, 2]) > atol or abs(T[k, 3, 3] - 1.0) > atol:
            return 3
    return 0


def check_pose(T: np.ndarray, what: str = "pose", atol: float = 1e-6) -> np.ndarray:
    """Validate rigid transform(s) (..., 4, 4); raise a clear error on NaN or a non-rotation."""
    T = np.asarray(T, dtype=float)
    if T.ndim < 2 or T.shape[-2:] != (4, 4):
        raise PrehensileError(f"{what}: expected shape (..., 4, 4), got {T.shape}")
    defect = _pose_defect(np.ascontiguousarray(T.reshape(-1, 4, 4)), atol)
    if defect == 1:
        raise PrehensileError(f"{what}: contains NaN or infinite values")
    if defect == 2:
        raise PrehensileError(f"{what}: upper-left 3x3 block is not a rotation matrix")
    if defect == 3:
        raise PrehensileError(f"{what}: last row must be [0, 0, 0, 1]")
    return T


def check_one_pose(T: np.ndarray, what: str = "pose") -> np.ndarray:
    """One rigid transform (4, 4) (:func:`check_pose`) as a contiguous float array."""
    T = check_pose(T, what)
    if T.shape != (4, 4):
        raise PrehensileError(f"{what}: expected one pose (4, 4), got {T.shape}")
    return np.ascontiguousarray(T)
