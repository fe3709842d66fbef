"""Forward kinematics and frame Jacobians for batches of configurations.

``q`` has shape (*batch, dof); a single configuration is a batch of none. Poses are
``T_world_link`` (m), with the robot base at ``T_world_base`` (identity by default).
"""

from __future__ import annotations

import numpy as np

from prehensile.kinematics import kernels
from prehensile.model.robot_model import RobotModel

_EYE = np.eye(4)


def _arrays(model: RobotModel):
    return (model.link_parent, model.joint_type, model.joint_origin, model.joint_axis,
            model.joint_q_index, model.joint_multiplier, model.joint_offset)


def _base(T_world_base) -> np.ndarray:
    return _EYE if T_world_base is None else np.ascontiguousarray(T_world_base, dtype=float)


def forward_kinematics(model: RobotModel, q: np.ndarray, T_world_base: np.ndarray | None = None) -> np.ndarray:
    """Poses of all links, shape (*batch, L, 4, 4), in the order of ``model.link_names``.

    Args:
        q: joint values (rad or m), shape (*batch, dof).
        T_world_base: pose (4, 4) of the root link in the world; identity if None.
    """
    q = model.check_configuration(q)
    batch = q.shape[:-1]
    flat = np.ascontiguousarray(q.reshape(-1, model.dof))
    out = np.empty((flat.shape[0], model.n_links, 4, 4))
    if flat.shape[0] == 1:
        kernels.fk_single(flat[0], _base(T_world_base), *_arrays(model), out[0])
    else:
        kernels.fk_batch(flat, _base(T_world_base), *_arrays(model), out)
    return out.reshape(batch + (model.n_links, 4, 4))


def link_pose(model: RobotModel, q: np.ndarray, link: str, T_link_frame: np.ndarray | None = None,
              T_world_base: np.ndarray | None = None) -> np.ndarray:
    """Pose (*batch, 4, 4) of ``link`` (times ``T_link_frame`` if given, e.g. a TCP offset)."""
    pose = forward_kinematics(model, q, T_world_base)[..., model.link_index(link), :, :]
    return pose if T_link_frame is None else pose @ T_link_frame


def frame_jacobian(
    model: RobotModel,
    q: np.ndarray,
    link: str,
    T_link_frame: np.ndarray | None = None,
    frame: str = "world",
    T_world_base: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Pose and Jacobian of a frame fixed to ``link``.

    The Jacobian maps joint velocities (dof,) to the frame's (linear, angular) velocity:
    rows 0-2 the velocity of the frame origin (m/s), rows 3-5 the angular velocity (rad/s).
    ``frame="world"`` expresses both in world axes (pinocchio's LOCAL_WORLD_ALIGNED);
    ``frame="local"`` in the frame's own axes (pinocchio's LOCAL).

    Returns:
        (pose (*batch, 4, 4), jacobian (*batch, 6, dof)).
    """
    if frame not in ("world", "local"):
        raise ValueError(f"frame must be 'world' or 'local', got '{frame}'")
    q = model.check_configuration(q)
    batch = q.shape[:-1]
    flat = np.ascontiguousarray(q.reshape(-1, model.dof))
    point = np.zeros(3) if T_link_frame is None else np.ascontiguousarray(T_link_frame[:3, 3], dtype=float)
    poses = np.empty((flat.shape[0], model.n_links, 4, 4))
    jac = np.empty((flat.shape[0], 6, model.dof))
    index = model.link_index(link)
    local = frame == "local"
    kernels.fk_jacobian_batch(flat, _base(T_world_base), index, point, False, *_arrays(model), poses, jac)
    pose = poses[:, index]
    if T_link_frame is not None:
        pose = pose @ T_link_frame
    if local:
        R_t = np.swapaxes(pose[:, :3, :3], -1, -2)
        jac = np.concatenate([R_t @ jac[:, :3], R_t @ jac[:, 3:]], axis=1)
    return pose.reshape(batch + (4, 4)), jac.reshape(batch + (6, model.dof))
