"""Reference kinematics from pinocchio for cross-checking our FK and Jacobians."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from prehensile.model import RobotModel


class PinocchioReference:
    """Loads the same URDF in pinocchio and maps our q (dof,) to pinocchio's q."""

    def __init__(self, model: RobotModel, urdf_path: str):
        self.model = model
        self.pin_model = pin.buildModelFromUrdf(str(urdf_path))
        self.data = self.pin_model.createData()

    def pin_q(self, q: np.ndarray) -> np.ndarray:
        """Our configuration as pinocchio's q; mimic joints get multiplier * q + offset."""
        pm, m = self.pin_model, self.model
        result = pin.neutral(pm)
        for link, joint_name in enumerate(m.link_joint_names):
            if not joint_name or not pm.existJointName(joint_name) or m.joint_q_index[link] < 0:
                continue
            value = m.joint_multiplier[link] * q[m.joint_q_index[link]] + m.joint_offset[link]
            joint = pm.joints[pm.getJointId(joint_name)]
            if joint.nq == 2:  # continuous joints are stored as (cos, sin)
                result[joint.idx_q:joint.idx_q + 2] = np.cos(value), np.sin(value)
            else:
                result[joint.idx_q] = value
        return result

    def link_poses(self, q: np.ndarray) -> np.ndarray:
        """Poses (L, 4, 4) of our links (pinocchio body frames of the same name)."""
        pin.framesForwardKinematics(self.pin_model, self.data, self.pin_q(q))
        return np.array([self.data.oMf[self.pin_model.getFrameId(n)].homogeneous for n in self.model.link_names])
