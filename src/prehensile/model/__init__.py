"""Robot models: the immutable :class:`RobotModel` and its loaders."""

from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.robot_model import FIXED, PRISMATIC, REVOLUTE, Chain, EndEffector, RobotModel
from prehensile.model.urdf import load_urdf

__all__ = [
    "FIXED", "PRISMATIC", "REVOLUTE", "Box", "Capsule", "Chain", "Cylinder", "EndEffector",
    "Geometry", "Mesh", "RobotModel", "Sphere", "load_urdf",
]
