"""Batched forward kinematics and frame Jacobians (compiled with numba)."""

from prehensile.kinematics.forward import forward_kinematics, frame_jacobian, link_pose

__all__ = ["forward_kinematics", "frame_jacobian", "link_pose"]
