"""Robot models: the immutable :class:`RobotModel` and its loaders (URDF + SRDF, MJCF, Simox XML)."""

from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.mjcf import load_mjcf
from prehensile.model.robot_model import FIXED, PRISMATIC, REVOLUTE, Chain, EndEffector, RobotModel
from prehensile.model.simox import load_simox
from prehensile.model.urdf import load_urdf

__all__ = [
    "FIXED", "PRISMATIC", "REVOLUTE", "Box", "Capsule", "Chain", "Cylinder", "EndEffector",
    "Geometry", "Mesh", "RobotModel", "Sphere", "load_mjcf", "load_simox", "load_urdf",
]
