"""A goal region for one link: MoveIt's position and orientation constraints.

A point fixed to the link (``offset`` in the link frame) must lie inside one of the regions
(boxes, spheres, cylinders placed in the constraints' frame), and the link's orientation must
lie within per-axis tolerances of a wanted one, as MoveIt's ``PositionConstraint`` and
``OrientationConstraint`` decide it: the rotation from the wanted orientation to the link's,
``R_wanted^T R_link``, as XYZ Euler angles (parameterization 0: ``Rx(a) Ry(b) Rz(c)``, b within
+-pi/2) or as a rotation vector (1), each component within its tolerance.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prehensile.model.geometry import Box, Cylinder, Sphere
from prehensile.spatial import make_pose, rotation_error

SLACK = 1e-9
"""m or rad added to every bound of :meth:`PoseGoal.satisfied` (rounding)."""


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class PoseGoal:
    """Position (and optionally orientation) constraints on one link.

    Attributes:
        link: the constrained link.
        frame: the frame the regions and the orientation are given in: "" (the world) or a link
            of the robot (placed where the request's start state puts it; the benchmark refuses
            a link the planned joints move, which MoveIt would place anew in each state).
        offset: (3,) the constrained point in the link frame (m).
        regions: ((Box | Sphere | Cylinder, T_frame_region (4, 4)), ...), at least one: the
            point must lie in one of them.
        orientation: (3, 3) wanted orientation of the link in ``frame``, or None (position only).
        tolerances: (3,) largest x, y, z angles (rad) of ``R_wanted^T R_link``.
        rotation_vector: the angles are a rotation vector's components (MoveIt's
            parameterization 1), else XYZ Euler angles (0).
    """

    link: str
    regions: tuple
    frame: str = ""
    offset: np.ndarray = field(default_factory=lambda: np.zeros(3))
    orientation: np.ndarray | None = None
    tolerances: np.ndarray = field(default_factory=lambda: np.zeros(3))
    rotation_vector: bool = False

    @property
    def T_link_point(self) -> np.ndarray:
        """(4, 4) the constrained point's frame: the link frame moved by ``offset``."""
        return make_pose(position=self.offset)

    def target(self, T_world_frame: np.ndarray) -> np.ndarray:
        """Where the point frame (:attr:`T_link_point`) should be, in the world: the pose (4, 4)
        at the first region's centre with the wanted orientation, or without one the
        position (3,) (m). It satisfies the constraints with room to spare."""
        centre = T_world_frame @ self.regions[0][1][:, 3]
        if self.orientation is None:
            return centre[:3]
        return make_pose(T_world_frame[:3, :3] @ self.orientation, centre[:3])

    def satisfied(self, T_world_frame: np.ndarray, T_world_link: np.ndarray) -> bool:
        """Whether the link at world pose T_world_link (4, 4) meets the constraints, the frame at
        T_world_frame (4, 4)."""
        point = np.linalg.solve(T_world_frame, T_world_link @ np.append(self.offset, 1.0))
        if not any(_inside(shape, np.linalg.solve(T_frame_region, point)[:3]) for shape, T_frame_region in self.regions):
            return False
        if self.orientation is None:
            return True
        return bool(np.all(np.abs(self.angles(T_world_frame, T_world_link)) <= self.tolerances + SLACK))

    def angles(self, T_world_frame: np.ndarray, T_world_link: np.ndarray) -> np.ndarray:
        """(3,) the angles (rad) of ``R_wanted^T R_link`` that the tolerances bound."""
        R = (T_world_frame[:3, :3] @ self.orientation).T @ T_world_link[:3, :3]
        if self.rotation_vector:
            return rotation_error(R, np.eye(3))
        # R = Rx(a) Ry(b) Rz(c) with b within +-pi/2: small rotations give small angles
        return np.array([np.arctan2(-R[1, 2], R[2, 2]), np.arcsin(np.clip(R[0, 2], -1.0, 1.0)),
                         np.arctan2(-R[0, 1], R[0, 0])])


def _inside(shape, p: np.ndarray) -> bool:
    """Whether the point p (3,) in the shape's frame lies in the Box, Sphere or Cylinder (z axis)."""
    if isinstance(shape, Box):
        return bool(np.all(np.abs(p) <= 0.5 * np.asarray(shape.size) + SLACK))
    if isinstance(shape, Sphere):
        return bool(np.linalg.norm(p) <= shape.radius + SLACK)
    if isinstance(shape, Cylinder):
        return bool(np.hypot(p[0], p[1]) <= shape.radius + SLACK and abs(p[2]) <= 0.5 * shape.length + SLACK)
    raise TypeError(f"a goal region is a Box, Sphere or Cylinder, got {type(shape).__name__}")
