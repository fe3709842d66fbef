"""Scenes: robots, obstacles and objects; YAML scene files; MoveIt PlanningScene import."""

from prehensile.scene.check import SceneCheck, check_scene
from prehensile.scene.files import bundled_scene_path, bundled_scenes, load_scene, save_scene
from prehensile.scene.moveit import (
    MBMProblem,
    MotionPlanRequest,
    iter_mbm_problems,
    load_motion_plan_request,
    load_moveit_scene,
)
from prehensile.scene.pose_goal import PoseGoal
from prehensile.scene.scene import Body, Hold, PlacedRobot, Scene

__all__ = [
    "Body", "Hold", "MBMProblem", "MotionPlanRequest", "PlacedRobot", "PoseGoal", "Scene", "SceneCheck",
    "bundled_scene_path", "bundled_scenes", "check_scene", "iter_mbm_problems", "load_motion_plan_request",
    "load_moveit_scene", "load_scene", "save_scene",
]
