"""SE(3) poses as float64 (..., 4, 4) arrays and rotation helpers."""

from prehensile.spatial.transforms import (
    axis_angle_to_matrix,
    check_pose,
    invert,
    make_pose,
    matrix_to_rpy,
    quaternion_to_matrix,
    rpy_to_matrix,
    rotation_error,
    translation,
)

__all__ = [
    "axis_angle_to_matrix",
    "check_pose",
    "invert",
    "make_pose",
    "matrix_to_rpy",
    "quaternion_to_matrix",
    "rpy_to_matrix",
    "rotation_error",
    "translation",
]
