"""Scene: robots placed in the world, static obstacles and movable objects.

Every body is a :class:`Body`: a name, a world pose ``T_world_body`` (4, 4) and the geometry
attached to it (each :class:`~prehensile.model.geometry.Geometry` placed in the body frame).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prehensile.collision.world import Obstacle
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

    @property
    def configuration(self) -> np.ndarray:
        return self.model.neutral_configuration() if self.q is None else self.q


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
