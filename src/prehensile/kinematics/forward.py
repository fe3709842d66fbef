"""Forward kinematics and frame Jacobians for batches of configurations.

``q`` has shape (*batch, dof); a single configuration is a batch of none. Poses are
``T_world_link`` (m), with the robot's root link at ``T_world_base`` (identity by default).
"""

from __future__ import annotations

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.kinematics import kernels
from prehensile.model.robot_model import RobotModel
from prehensile.spatial.transforms import check_one_pose

_EYE = np.eye(4)


def _base(T_world_base) -> np.ndarray:
    """The root pose (4, 4), checked rigid; identity for None."""
    return _EYE if T_world_base is None else check_one_pose(T_world_base, "T_world_base")


def _flat(model: RobotModel, q) -> tuple[np.ndarray, tuple[int, ...]]:
    q = np.asarray(q, dtype=float)
    if q.ndim == 0 or q.shape[-1] != model.dof:
        model.check_configuration(q)  # raises the descriptive error
    return np.ascontiguousarray(q.reshape(-1, model.dof)), q.shape[:-1]


def _non_finite(row: int, batch: tuple[int, ...]) -> PrehensileError:
    where = f" at batch index {tuple(int(i) for i in np.unravel_index(row, batch))}" if batch else ""
    return PrehensileError(f"q contains NaN or infinite values{where}")


def forward_kinematics(model: RobotModel, q: np.ndarray, T_world_base: np.ndarray | None = None) -> np.ndarray:
    """Poses of all links, shape (*batch, L, 4, 4), in the order of ``model.link_names``.

    The joint limits are not checked (as in pinocchio): a q outside them is posed as given,
    which the planners rely on. Test it with :meth:`~prehensile.model.RobotModel.within_limits`
    (:meth:`~prehensile.model.RobotModel.check_configuration` checks shape and finiteness only).

    Args:
        q: joint values (rad or m), shape (*batch, dof); not clipped to the limits.
        T_world_base: pose (4, 4) of the root link in the world; identity if None.

    Raises:
        PrehensileError: q has the wrong length or holds NaN / infinite values.
    """
    if isinstance(q, np.ndarray) and q.shape == (model.dof,) and q.dtype == np.float64:
        out = np.empty((model.n_links, 4, 4))  # fast path for one configuration
        if not kernels.fk_into(q, _base(T_world_base), model.joint_table, out):
            raise _non_finite(0, ())
        return out
    flat, batch = _flat(model, q)
    out = np.empty((flat.shape[0], model.n_links, 4, 4))
    bad = kernels.fk_batch_into(flat, _base(T_world_base), model.joint_table, out)
    if bad >= 0:
        raise _non_finite(bad, batch)
    return out.reshape(batch + (model.n_links, 4, 4))


def link_pose(model: RobotModel, q: np.ndarray, link: str, T_link_frame: np.ndarray | None = None,
              T_world_base: np.ndarray | None = None) -> np.ndarray:
    """Pose (*batch, 4, 4) of ``link``, times ``T_link_frame`` (4, 4) if given (e.g. a tool offset)."""
    pose = forward_kinematics(model, q, T_world_base)[..., model.link_index(link), :, :]
    return pose if T_link_frame is None else pose @ check_one_pose(T_link_frame, "T_link_frame")


def frame_jacobian(
    model: RobotModel,
    q: np.ndarray,
    link: str,
    T_link_frame: np.ndarray | None = None,
    frame: str = "world",
    T_world_base: np.ndarray | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Pose and Jacobian of a frame fixed to ``link`` (at ``T_link_frame``, default the link frame).

    The Jacobian maps joint velocities (dof,) to the frame's twist: rows 0-2 the velocity of
    the frame origin (m/s), rows 3-5 the angular velocity (rad/s). ``frame="world"`` expresses
    both in world axes (pinocchio's LOCAL_WORLD_ALIGNED); ``frame="local"`` in the frame's own
    axes (pinocchio's LOCAL).

    Returns:
        (pose (*batch, 4, 4), jacobian (*batch, 6, dof)).
    """
    if frame not in ("world", "local"):
        raise PrehensileError(f"frame must be 'world' or 'local', got '{frame}'")
    flat, batch = _flat(model, q)
    index = model.link_index(link)
    if T_link_frame is not None:
        T_link_frame = check_one_pose(T_link_frame, "T_link_frame")
    point = np.zeros(3) if T_link_frame is None else np.ascontiguousarray(T_link_frame[:3, 3])
    pose = np.empty((flat.shape[0], 4, 4))
    jac = np.empty((flat.shape[0], 6, model.dof))
    bad = kernels.fk_jacobian_batch_into(flat, _base(T_world_base), index, point, model.joint_table, pose, jac)
    if bad >= 0:
        raise _non_finite(bad, batch)
    if T_link_frame is not None:
        pose = pose @ T_link_frame
    if frame == "local":
        R_t = np.swapaxes(pose[:, :3, :3], -1, -2)
        jac = np.concatenate([R_t @ jac[:, :3], R_t @ jac[:, 3:]], axis=1)
    return pose.reshape(batch + (4, 4)), jac.reshape(batch + (6, model.dof))
