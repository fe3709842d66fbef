"""Scene: robots placed in the world, static obstacles and movable objects.

Every body is a :class:`Body`: a name, a world pose ``T_world_body`` (4, 4) and the geometry
attached to it (each :class:`~prehensile.model.geometry.Geometry` placed in the body frame).
An object may be held by a robot link (:class:`Hold`): it then moves with that link and is
part of the robot, not of its world (:meth:`Scene.attached_objects`).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from prehensile.collision.attached import AttachedObject
from prehensile.collision.world import Obstacle
from prehensile.errors import SceneError
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Geometry
from prehensile.model.robot_model import RobotModel
from prehensile.spatial.transforms import invert


@dataclass(frozen=True)
class Hold:
    """How a robot holds an object: ``link`` of robot ``robot`` carries it, and the object may
    touch ``touch_links`` (e.g. the fingers) besides the links rigidly fixed to ``link``."""

    robot: str
    link: str
    touch_links: tuple[str, ...] = ()


def check_hold(model: RobotModel, hold: Hold, where: str, link_key: str = "link") -> None:
    """Raise SceneError naming ``where`` (and ``link_key``, what the input calls the holding
    link) unless the holding link and the touch links of ``hold`` are links of ``model``."""
    for key, name in [(link_key, hold.link)] + [(f"touch_links[{k}]", n) for k, n in enumerate(hold.touch_links)]:
        if name not in model.link_names:
            raise SceneError(f"{where}.{key}: robot '{hold.robot}' has no link {name!r}; links: "
                             f"{', '.join(model.link_names)}")


@dataclass(frozen=True, eq=False)
class Body:
    """A rigid body in the world: obstacle or graspable object; ``held_by`` a robot or None."""

    name: str
    geometries: tuple[Geometry, ...]
    T_world_body: np.ndarray = field(default_factory=lambda: np.eye(4))
    held_by: Hold | None = None

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

    def __post_init__(self) -> None:
        """Raise SceneError unless every held body is an object held by a link of a robot of the scene."""
        models = {robot.name: robot.model for robot in self.robots}
        for body in self.obstacles:
            if body.held_by is not None:
                raise SceneError(f"{self.source}: obstacle '{body.name}' is held by '{body.held_by.robot}'; only "
                                 "objects can be held")
        for body in self.objects:
            if body.held_by is not None:
                where = f"{self.source}: object '{body.name}'.held_by"
                if body.held_by.robot not in models:
                    raise SceneError(f"{where}.robot: no robot {body.held_by.robot!r} in the scene; robots: "
                                     f"{', '.join(models) or '(none)'}")
                check_hold(models[body.held_by.robot], body.held_by, where)

    @property
    def bodies(self) -> tuple[Body, ...]:
        """Obstacles and objects: everything a robot may collide with, but for what it holds."""
        return self.obstacles + self.objects

    def robot(self, name: str) -> PlacedRobot:
        """The robot called ``name``; KeyError if there is none."""
        for robot in self.robots:
            if robot.name == name:
                return robot
        raise KeyError(name)

    def collision_obstacles(self, robot: str | None = None) -> list[Obstacle]:
        """Every shape of every obstacle and object, placed in the world; without the objects
        held by ``robot`` (a robot name), which move with it (:meth:`attached_objects`)."""
        return [
            Obstacle(body.name, geometry.shape, T_world_geom)
            for body in self.bodies
            if robot is None or body.held_by is None or body.held_by.robot != robot
            for geometry, T_world_geom in body.world_geometries()
        ]

    def attached_objects(self, robot: str | None) -> tuple[AttachedObject, ...]:
        """The objects held by robot ``robot``, fixed to their links where the scene places them:
        ``T_link_object`` from the link's pose at the robot's configuration and the object's
        world pose. () if it holds none."""
        held = [body for body in self.objects if body.held_by is not None and body.held_by.robot == robot]
        if not held:
            return ()
        placed = self.robot(robot)
        poses = placed.link_poses()
        return tuple(AttachedObject(body.name, body.held_by.link, body.geometries,
                                    invert(poses[placed.model.link_index(body.held_by.link)]) @ body.T_world_body,
                                    body.held_by.touch_links) for body in held)
