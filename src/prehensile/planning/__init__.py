"""Motion planning: configuration space, planning context, RRT-Connect, J+-RRT, IK-RRT,
shortcutting, exact certification and time parameterization (Vahrenkamp 2011 ch. 2, 4,
appendices B and C.2)."""

from prehensile.collision.attached import AttachedObject
from prehensile.planning.certify import CertifyReport, certify_path
from prehensile.planning.context import PlanningContext
from prehensile.planning.cspace import ConfigurationSpace
from prehensile.planning.elastic_band import ElasticBandSettings, elastic_band
from prehensile.planning.ik_rrt import (
    GoalSampler, IKRRTSettings, dual_arm_sampler, grasp_sampler, ik_rrt, multi_eef_rrt, regrasp_sampler,
)
from prehensile.planning.jplus_rrt import JPlusRRTSettings, jplus_rrt, regrasp_jplus_rrt
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus
from prehensile.planning.rrt_connect import RRTConnectSearch, RRTConnectSettings, rrt_connect
from prehensile.planning.shortcut import shortcut
from prehensile.planning.to_pose import POSE_PLANNERS, plan_to_pose

_TRAJECTORY = ("Trajectory", "model_limits", "time_parameterize")

__all__ = [
    "AttachedObject", "CertifyReport", "ConfigurationSpace", "ElasticBandSettings", "GoalSampler", "IKRRTSettings",
    "JPlusRRTSettings", "POSE_PLANNERS", "PlanResult", "PlanStats", "PlanStatus", "PlanningContext", "RRTConnectSearch",
    "RRTConnectSettings", "certify_path", "dual_arm_sampler", "elastic_band", "grasp_sampler", "ik_rrt", "jplus_rrt",
    "multi_eef_rrt", "plan_to_pose", "regrasp_jplus_rrt", "regrasp_sampler", "rrt_connect", "shortcut", *_TRAJECTORY,
]


def __getattr__(name: str):
    """The trajectory names, imported on first use (toppra takes about a second to import)."""
    if name in _TRAJECTORY:
        from prehensile.planning import trajectory

        return getattr(trajectory, name)
    raise AttributeError(f"module 'prehensile.planning' has no attribute '{name}'")
