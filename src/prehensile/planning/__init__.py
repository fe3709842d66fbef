"""Motion planning: configuration space, planning context, RRT-Connect, shortcutting and exact
certification (Vahrenkamp 2011 ch. 2, appendices B and C.2)."""

from prehensile.planning.certify import CertifyReport, certify_path
from prehensile.planning.context import AttachedObject, PlanningContext
from prehensile.planning.cspace import ConfigurationSpace
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus
from prehensile.planning.rrt_connect import RRTConnectSearch, RRTConnectSettings, rrt_connect
from prehensile.planning.shortcut import shortcut

__all__ = [
    "AttachedObject", "CertifyReport", "ConfigurationSpace", "PlanResult", "PlanStats", "PlanStatus",
    "PlanningContext", "RRTConnectSearch", "RRTConnectSettings", "certify_path", "rrt_connect", "shortcut",
]
