"""Scenes: robots, obstacles and objects; YAML scene files; MoveIt PlanningScene import."""

from prehensile.scene.scene import Body, PlacedRobot, Scene

__all__ = ["Body", "PlacedRobot", "Scene"]
