"""What a robot can collide with, as the collision layer sees it."""

from __future__ import annotations

from typing import NamedTuple, Sequence

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.model.geometry import Box, Capsule, Cylinder, Mesh, Shape, Sphere
from prehensile.spatial.transforms import check_one_pose


class Obstacle(NamedTuple):
    """A shape fixed in the world: ``name`` (the body it belongs to), ``shape`` and its pose
    ``T_world_shape`` (4, 4)."""

    name: str
    shape: Shape
    T_world_shape: np.ndarray


def check_obstacles(obstacles: Sequence[Obstacle], what: str = "obstacles") -> list[Obstacle]:
    """The obstacles as a list, each checked: an :class:`Obstacle` with a rigid pose (returned as a
    (4, 4) float array) and a shape of positive size (a zero-length capsule is a ball, a mesh has
    triangles). Raises PrehensileError naming the first bad one."""
    if isinstance(obstacles, Obstacle):
        raise PrehensileError(f"{what}: expected a list of Obstacle, got one Obstacle")
    out = list(obstacles)
    for i, obstacle in enumerate(out):
        if not isinstance(obstacle, Obstacle):
            raise PrehensileError(f"{what}[{i}]: expected an Obstacle(name, shape, T_world_shape), "
                                  f"got {type(obstacle).__name__}")
        where = f"{what}[{i}] '{obstacle.name}'"
        out[i] = obstacle._replace(T_world_shape=check_one_pose(obstacle.T_world_shape, f"{where}: T_world_shape"))
        if not positive_size(obstacle.shape):
            raise PrehensileError(f"{where}: {obstacle.shape} {SHAPE_SIZES}")
    return out


SHAPE_SIZES = ("needs a positive size (m); valid shapes: Box(size (3,)), Sphere(radius), Cylinder(radius, length), "
               "Capsule(radius, length >= 0), Mesh (with triangles)")


def positive_size(shape: Shape) -> bool:
    """``shape`` is one of the shapes (each checks its sizes when built) and, if a mesh
    (mirrored by negative scale factors or not), has triangles."""
    if isinstance(shape, Mesh):
        return len(shape.trimesh.faces) > 0
    return isinstance(shape, (Box, Sphere, Cylinder, Capsule))
