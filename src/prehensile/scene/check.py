"""Collision check of a whole scene: every robot at its configuration.

Each robot is checked for self-collisions (minus the model's disabled pairs) and against the
world: the scene's obstacles and objects plus the collision shapes of every *other* robot,
placed by forward kinematics. Another robot's shapes appear as obstacles called
``"<robot>/<link>"``, so a robot-robot contact is reported by both robots. An object a robot
holds (:class:`~prehensile.scene.scene.Hold`) is part of that robot, a link called
``"attached/<object>"`` (its contacts with the robot's other links are self contacts), and an
obstacle for the other robots.
"""

from __future__ import annotations

from dataclasses import dataclass

from prehensile.collision.attached import AttachedObject
from prehensile.collision.world import Obstacle
from prehensile.errors import SceneError
from prehensile.scene.scene import PlacedRobot, Scene

METHODS = ("exact", "spheres")


@dataclass(frozen=True)
class Contact:
    """A colliding pair: ``link`` of ``robot`` touches ``other`` (a link of the same robot, a
    body of the scene or ``"<robot>/<link>"``); ``depth`` is the penetration depth in m (0 where
    the checker does not measure it)."""

    robot: str
    link: str
    other: str
    depth: float
    kind: str  # "self" or "world"


@dataclass(frozen=True)
class RobotCheck:
    """The result for one robot: ``free`` and the contacts (empty when free)."""

    robot: str
    free: bool
    contacts: tuple[Contact, ...]

    @property
    def colliding_links(self) -> tuple[str, ...]:
        """Links of this robot that touch anything, sorted, each once."""
        links = {c.link for c in self.contacts}
        links |= {c.other for c in self.contacts if c.kind == "self"}
        return tuple(sorted(links))


@dataclass(frozen=True)
class SceneCheck:
    """The result for a scene: one :class:`RobotCheck` per robot, in scene order."""

    method: str
    robots: tuple[RobotCheck, ...]

    @property
    def free(self) -> bool:
        return all(r.free for r in self.robots)

    @property
    def colliding_links(self) -> dict[str, tuple[str, ...]]:
        """Robot name -> its colliding links (robots without contacts are left out)."""
        return {r.robot: r.colliding_links for r in self.robots if r.colliding_links}

    def colliding_bodies(self) -> tuple[str, ...]:
        """Scene bodies touched by any robot, sorted; () for the sphere method, whose contacts
        name no body (``other`` is "world")."""
        if self.method != "exact":
            return ()
        return tuple(sorted({c.other for r in self.robots for c in r.contacts if c.kind == "world" and "/" not in c.other}))

    def to_dict(self) -> dict:
        """A JSON-ready summary: method, free, and per robot its contacts and colliding links."""
        return {
            "method": self.method,
            "free": self.free,
            "robots": [
                {
                    "name": r.robot,
                    "free": r.free,
                    "colliding_links": list(r.colliding_links),
                    "contacts": [
                        {"link": c.link, "other": c.other, "kind": c.kind, "depth": c.depth} for c in r.contacts
                    ],
                }
                for r in self.robots
            ],
            "colliding_bodies": list(self.colliding_bodies()),
        }


def robot_obstacles(robot: PlacedRobot) -> list[Obstacle]:
    """The collision shapes of ``robot`` at its configuration as obstacles ``"<robot>/<link>"``."""
    return [Obstacle(f"{robot.name}/{link}", g.shape, T) for link, g, T in robot.world_geometries("collision")]


def check_scene(scene: Scene, method: str = "exact") -> SceneCheck:
    """Check every robot of ``scene`` at its configuration.

    Args:
        scene: the scene; robots use :attr:`PlacedRobot.configuration`.
        method: "exact" (meshes and primitives with coal, reports each pair and its depth) or
            "spheres" (the robot's sphere model against the world shapes; conservative: the
            contacts name the links whose balls overlap, "world" for any obstacle, no depth;
            the base, which never moves, meets the world only where its exact geometry does).

    Returns:
        A :class:`SceneCheck`; ``free`` is True when no robot touches anything.

    Raises:
        SceneError: unknown ``method``.
    """
    if method not in METHODS:
        raise SceneError(f"unknown collision method '{method}'; valid: {', '.join(METHODS)}")
    others = {robot.name: robot_obstacles(robot) for robot in scene.robots}
    results = []
    for robot in scene.robots:
        obstacles = scene.collision_obstacles(robot.name) + [o for name, obs in others.items() if name != robot.name
                                                             for o in obs]
        results.append(_check_robot(robot, obstacles, method, scene.attached_objects(robot.name)))
    return SceneCheck(method, tuple(results))


def _check_robot(robot: PlacedRobot, obstacles: list[Obstacle], method: str,
                 attached: tuple[AttachedObject, ...]) -> RobotCheck:
    """Check ``robot`` holding the ``attached`` objects."""
    from prehensile.collision import ExactChecker, SphereChecker, allowed_collision_matrix, attach_objects
    from prehensile.collision.spheres import generate_sphere_model

    q = robot.configuration
    balls = generate_sphere_model(robot.model) if method == "spheres" else None
    model, balls, acm = attach_objects(robot.model, balls, allowed_collision_matrix(robot.model), attached)
    if method == "exact":
        checker = ExactChecker(model, obstacles, T_world_base=robot.T_world_base, acm=acm)
        contacts = _merge(robot.name, checker.collisions(q, "world"), "world") + _merge(
            robot.name, checker.collisions(q, "self"), "self")
        return RobotCheck(robot.name, not contacts, contacts)
    checker = SphereChecker(model, obstacles, T_world_base=robot.T_world_base, spheres=balls, acm=acm)
    exact = ExactChecker(model, obstacles, T_world_base=robot.T_world_base, acm=acm) if checker.static_hit else None
    if exact is not None and not exact.root_contacts(q):
        # only the bounding balls of the base meet the world (a robot on a table): the base
        # never moves, so its exact geometry decides, as in planning
        checker = SphereChecker(model, obstacles, T_world_base=robot.T_world_base, spheres=balls, acm=acm,
                                static_hit=False)
    if checker.is_free(q):
        return RobotCheck(robot.name, True, ())
    # the balls name the links, not the obstacle ("world"), and measure no depth
    return RobotCheck(robot.name, False, tuple(Contact(robot.name, link, other, 0.0, "world" if other == "world"
                                                       else "self") for link, other in checker.ball_contacts(q)))


def _merge(robot: str, pairs, kind: str) -> tuple[Contact, ...]:
    """One contact of ``kind`` ("world" or "self") per (link, other) pair, with the deepest
    penetration of its shape pairs."""
    deepest: dict[tuple[str, str], float] = {}
    for link, other, depth in pairs:
        key = (str(link), str(other))
        deepest[key] = max(deepest.get(key, 0.0), float(depth))
    return tuple(Contact(robot, link, other, depth, kind) for (link, other), depth in deepest.items())
