"""A goal region for one link: MoveIt's position and orientation constraints.

A point fixed to the link (``offset`` in the link frame) must lie inside one of the regions
(boxes, spheres, cylinders placed in the constraints' frame), and the link's orientation must
lie within per-axis tolerances of a wanted one, as MoveIt's ``PositionConstraint`` and
``OrientationConstraint`` decide it: the rotation from the wanted orientation to the link's,
``R_wanted^T R_link``, as XYZ Euler angles (parameterization 0: ``Rx(a) Ry(b) Rz(c)``, b within
+-pi/2) or as a rotation vector (1), each component within its tolerance.

Planners that sample goals (IK-RRT) draw targets from the region (:meth:`PoseGoal.sample`) and
start from the one nearest to where the link is (:meth:`PoseGoal.closest`); J+-RRT steps toward
the one nearest to where the link is at each step. Both keep a margin from the region's bounds,
so that a planner that reaches a target within its own tolerance still meets them.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prehensile.model.geometry import Box, Cylinder, Sphere
from prehensile.errors import PrehensileError
from prehensile.spatial import axis_angle_to_matrix, make_pose, rotation_error, rpy_to_matrix
from prehensile.spatial.transforms import check_one_pose

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

    def __post_init__(self) -> None:
        where = f"PoseGoal of link '{self.link}'"
        if not self.regions:
            raise PrehensileError(f"{where}: no regions; give at least one (Box | Sphere | Cylinder, T_frame_region)")
        for k, region in enumerate(self.regions):
            if len(region) != 2 or not isinstance(region[0], (Box, Sphere, Cylinder)):
                raise PrehensileError(f"{where}: regions[{k}] must be (Box | Sphere | Cylinder, T_frame_region (4, 4))")
            check_one_pose(region[1], f"{where}: regions[{k}] pose")
        for name, value in (("offset", self.offset), ("tolerances", self.tolerances)):
            if np.shape(value) != (3,) or not np.all(np.isfinite(value)):
                raise PrehensileError(f"{where}: {name} must be 3 finite numbers, got {value!r}")
        if np.any(np.asarray(self.tolerances) < 0):
            raise PrehensileError(f"{where}: tolerances must be >= 0 (rad), got {self.tolerances!r}")
        if self.orientation is not None:
            check_one_pose(make_pose(self.orientation), f"{where}: orientation")

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

    def sample(self, rng: np.random.Generator, T_world_frame: np.ndarray, margin: tuple[float, float] = (0.0, 0.0)
               ) -> np.ndarray:
        """A random target of the point frame (:attr:`T_link_point`) that meets the constraints:
        a pose (4, 4), or without an orientation constraint a position (3,) (m), in the world.

        The point is uniform in one of the regions shrunk by ``margin[0]`` (m), each region as
        likely (a small reachable one beside a large unreachable one is drawn as often), each
        angle uniform within its tolerance less ``margin[1]`` (rad); a region or tolerance
        smaller than its margin gives its centre.
        """
        shape, T_frame_region = self.regions[rng.integers(len(self.regions))]
        point = T_frame_region @ np.append(_draw(*_shrunk(shape, margin[0]), rng), 1.0)
        bounds = self._angle_bounds(margin[1])
        return self._target(T_world_frame, point[:3], rng.uniform(-bounds, bounds))

    def closest(self, T_world_frame: np.ndarray, T_world_link: np.ndarray, margin: tuple[float, float] = (0.0, 0.0)
                ) -> np.ndarray:
        """The target (as :meth:`sample`) nearest to the point frame of the link at world pose
        T_world_link (4, 4): the point moved to the nearest point of the shrunk regions, each
        angle clipped into its tolerance less the margin: the point frame's own pose (up to
        rounding) if the link meets the constraints with the margin to spare."""
        point = self._point(T_world_frame, T_world_link)
        candidates = []
        for shape, T_frame_region in self.regions:
            local = _in_frame(T_frame_region, point)
            nearest = _project(*_shrunk(shape, margin[0]), local)
            candidates.append((np.linalg.norm(nearest - local), (T_frame_region @ np.append(nearest, 1.0))[:3]))
        position = min(candidates, key=lambda c: c[0])[1]
        if self.orientation is None:
            return self._target(T_world_frame, position, None)
        bounds = self._angle_bounds(margin[1])
        return self._target(T_world_frame, position, np.clip(self.angles(T_world_frame, T_world_link), -bounds, bounds))

    def _point(self, T_world_frame: np.ndarray, T_world_link: np.ndarray) -> np.ndarray:
        """(3,) the constrained point of the link at world pose T_world_link (4, 4), in the frame."""
        return _in_frame(T_world_frame, (T_world_link @ np.append(self.offset, 1.0))[:3])

    def _angle_bounds(self, margin: float) -> np.ndarray:
        """(3,) the angles (rad) targets may take: the tolerances less ``margin``, the second
        XYZ Euler angle within +-pi/2 (where it is decoded)."""
        bounds = np.maximum(self.tolerances - margin, 0.0)
        if not self.rotation_vector:
            bounds[1] = min(bounds[1], 0.5 * np.pi)
        return bounds

    def _target(self, T_world_frame: np.ndarray, point: np.ndarray, angles: np.ndarray | None) -> np.ndarray:
        """The world target of the point frame at ``point`` (3,) in the frame, rotated from the
        wanted orientation by ``angles`` (3,) as the tolerances measure them."""
        position = (T_world_frame @ np.append(point, 1.0))[:3]
        if self.orientation is None:
            return position
        if self.rotation_vector:
            angle = np.linalg.norm(angles)
            offset = axis_angle_to_matrix(angles / angle, angle) if angle > 0 else np.eye(3)
        else:  # Rx(a) Ry(b) Rz(c), the transpose of Rz(-c) Ry(-b) Rx(-a)
            offset = rpy_to_matrix(-np.asarray(angles)).T
        return make_pose(T_world_frame[:3, :3] @ self.orientation @ offset, position)

    def satisfied(self, T_world_frame: np.ndarray, T_world_link: np.ndarray) -> bool:
        """Whether the link at world pose T_world_link (4, 4) meets the constraints, the frame at
        T_world_frame (4, 4)."""
        point = self._point(T_world_frame, T_world_link)
        if not any(_inside(shape, _in_frame(T_frame_region, point)) for shape, T_frame_region in self.regions):
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


def _in_frame(T: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The point p (3,) in the frame of the rigid transform T (4, 4)."""
    return T[:3, :3].T @ (p - T[:3, 3])


def _shrunk(shape, margin: float) -> tuple[str, np.ndarray]:
    """(kind, half extents) of a region shrunk by ``margin`` (m) on every side, none below 0:
    ("box", (3,) half sides), ("sphere", (1,) radius) or ("cylinder", (radius, half length))."""
    if isinstance(shape, Box):
        kind, half = "box", 0.5 * np.asarray(shape.size, dtype=float)
    elif isinstance(shape, Sphere):
        kind, half = "sphere", np.array([shape.radius])
    else:  # a Cylinder (PoseGoal accepts no other region)
        kind, half = "cylinder", np.array([shape.radius, 0.5 * shape.length])
    return kind, np.maximum(half - margin, 0.0)


def _draw(kind: str, half: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """A point (3,) uniform in a shrunk region (:func:`_shrunk`), in its frame."""
    if kind == "box":
        return rng.uniform(-half, half)
    if kind == "sphere":
        direction = rng.normal(size=3)
        return direction / max(np.linalg.norm(direction), 1e-12) * half[0] * rng.uniform() ** (1.0 / 3.0)
    radius, angle = half[0] * np.sqrt(rng.uniform()), rng.uniform(0.0, 2.0 * np.pi)
    return np.array([radius * np.cos(angle), radius * np.sin(angle), rng.uniform(-half[1], half[1])])


def _project(kind: str, half: np.ndarray, p: np.ndarray) -> np.ndarray:
    """The point (3,) of a shrunk region (:func:`_shrunk`) nearest to p (3,), in its frame."""
    if kind == "box":
        return np.clip(p, -half, half)
    if kind == "sphere":
        norm = np.linalg.norm(p)
        return p if norm <= half[0] else p * (half[0] / norm)
    radial = np.hypot(p[0], p[1])
    scale = 1.0 if radial <= half[0] else half[0] / radial
    return np.array([p[0] * scale, p[1] * scale, np.clip(p[2], -half[1], half[1])])


def _inside(shape, p: np.ndarray) -> bool:
    """Whether the point p (3,) in the shape's frame lies in the Box, Sphere or Cylinder (z axis)."""
    return bool(np.array_equal(_project(*_shrunk(shape, -SLACK), p), p))
