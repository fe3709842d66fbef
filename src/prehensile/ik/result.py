"""Result type and target validation shared by every IK solver.

A solver that finds no solution returns a status, never raises; only malformed input (a
target with NaN, a non-rotation, a wrong shape) raises :class:`~prehensile.errors.PrehensileError`.
"""

from __future__ import annotations

import enum
from dataclasses import dataclass

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.spatial.transforms import check_pose


class IKStatus(enum.Enum):
    """Outcome of an IK query."""

    SUCCESS = "success"              # a solution within the tolerances
    NOT_CONVERGED = "not_converged"  # an iterative solver stopped (iteration cap or no progress)
    TIMEOUT = "timeout"              # the time budget ran out before a valid solution was found
    UNREACHABLE = "unreachable"      # the target lies provably outside the chain's workspace


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class IKResult:
    """What an IK solver found.

    Attributes:
        status: see :class:`IKStatus`.
        q: (dof,) full-model configuration (rad or m): the solution, or the best configuration
            reached when there is none. Joints outside the chain keep the seed's values.
        solutions: (k, dof) every solution within tolerance (k = 0 when none; analytic
            solvers return all of them, iterative ones at most one).
        position_error: distance (m) between the target and the reached tip position of ``q``.
        rotation_error: angle (rad) of the rotation between target and reached tip orientation
            of ``q`` (0 for position-only targets). Both over the task rows a Jacobian solver
            keeps (``JacobianIKSettings.weights``).
        iterations: solver iterations summed over all restarts.
        time_s: wall time (s) without numba compilation (:func:`prehensile.clock.clock`).
        target_index: index of the pose reached when the target was a pose set (0 otherwise).
        restarts: random restarts used (0 when the first seed succeeded).
        target_indices: per tool, the pose reached, for solvers with several tools (dual-arm
            IK); empty otherwise.
    """

    status: IKStatus
    q: np.ndarray
    solutions: np.ndarray
    position_error: float
    rotation_error: float
    iterations: int
    time_s: float
    target_index: int = 0
    restarts: int = 0
    target_indices: tuple[int, ...] = ()

    @property
    def success(self) -> bool:
        return self.status is IKStatus.SUCCESS


def check_target_poses(target: np.ndarray, what: str = "target") -> np.ndarray:
    """Validate one pose (4, 4) or a pose set (k, 4, 4); returns a float64 (k, 4, 4) array.

    Raises:
        PrehensileError: wrong shape, NaN / infinite entries, or a non-rotation block.
    """
    poses = check_pose(np.asarray(target, dtype=float), what)
    if poses.ndim == 2:
        poses = poses[None]
    if poses.ndim != 3 or len(poses) == 0:
        raise PrehensileError(f"{what}: expected a pose (4, 4) or a non-empty pose set (k, 4, 4), got shape {poses.shape}")
    return np.ascontiguousarray(poses)


def check_target_positions(target: np.ndarray, what: str = "target") -> np.ndarray:
    """Validate one position (3,) or a set (k, 3) (m); returns a float64 (k, 3) array."""
    points = np.asarray(target, dtype=float)
    if points.ndim == 1:
        points = points[None]
    if points.ndim != 2 or points.shape[1] != 3 or len(points) == 0:
        raise PrehensileError(f"{what}: expected a position (3,) or a non-empty set (k, 3), got shape {np.shape(target)}")
    if not np.all(np.isfinite(points)):
        raise PrehensileError(f"{what}: contains NaN or infinite values")
    return np.ascontiguousarray(points)
