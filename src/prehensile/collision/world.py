"""What a robot can collide with, as the collision layer sees it."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from prehensile.model.geometry import Shape


class Obstacle(NamedTuple):
    """A shape fixed in the world: ``name`` (the body it belongs to), ``shape`` and its pose
    ``T_world_shape`` (4, 4)."""

    name: str
    shape: Shape
    T_world_shape: np.ndarray
