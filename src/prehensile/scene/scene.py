"""Scene: robots placed in the world, static obstacles and movable objects.

Every body is a :class:`Body`: a name, a world pose ``T_world_body`` (4, 4) and the geometry
attached to it (each :class:`~prehensile.model.geometry.Geometry` placed in the body frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prehensile.collision.world import Obstacle
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Geometry
from prehensile.model.robot_model import RobotModel


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body in the world: obstacle or graspable object."""

    name: str
    geometries: tuple[Geometry, ...]
    T_world_body: np.ndarray = field(default_factory=lambda: np.eye(4))

    def world_geometries(self) -> list[tuple[Geometry, np.ndarray]]:
        """Each geometry with its world pose ``T_world_geom`` (4, 4)."""
        return [(g, self.T_world_body @ g.T_link_geom) for g in self.geometries]


@dataclass(frozen=True, eq=False)
class PlacedRobot:
    """A robot model at ``T_world_base`` with a configuration q (dof,)."""

    name: str
    model: RobotModel
    T_world_base: np.ndarray = field(default_factory=lambda: np.eye(4))
    q: np.ndarray | None = None
    reference: str = ""
    """How a scene file names the robot: a bundled name ("panda") or a model file path."""

    @property
    def configuration(self) -> np.ndarray:
        return self.model.neutral_configuration() if self.q is None else self.q

    def link_poses(self) -> np.ndarray:
        """World poses ``T_world_link`` of all links at :attr:`configuration`, shape (L, 4, 4)."""
        return forward_kinematics(self.model, self.configuration, self.T_world_base)

    def world_geometries(self, kind: str = "collision") -> list[tuple[str, Geometry, np.ndarray]]:
        """(link name, geometry, ``T_world_geom`` (4, 4)) of every link shape at the configuration.

        Args:
            kind: "collision" or "visual" geometry; "visual" falls back to a link's collision
                shapes where it has no visual ones.
        """
        if kind not in ("collision", "visual"):
            raise ValueError(f"kind must be 'collision' or 'visual', got '{kind}'")
        poses = self.link_poses()
        out = []
        for index, link in enumerate(self.model.link_names):
            geometries = self.model.collisions[index]
            if kind == "visual" and self.model.visuals[index]:
                geometries = self.model.visuals[index]
            out += [(link, g, poses[index] @ g.T_link_geom) for g in geometries]
        return out


@dataclass(frozen=True, eq=False)
class Scene:
    """Robots, static obstacles and movable objects; ``source`` names the file it came from."""

    robots: tuple[PlacedRobot, ...] = ()
    obstacles: tuple[Body, ...] = ()
    objects: tuple[Body, ...] = ()
    source: str = ""

    @property
    def bodies(self) -> tuple[Body, ...]:
        """Obstacles and objects: everything a robot may collide with."""
        return self.obstacles + self.objects

    def collision_obstacles(self) -> list[Obstacle]:
        """Every shape of every obstacle and object, placed in the world."""
        return [
            Obstacle(body.name, geometry.shape, T_world_geom)
            for body in self.bodies
            for geometry, T_world_geom in body.world_geometries()
        ]
