"""Inverse kinematics: Jacobian solvers, random-restart complete IK, analytic NAO arms, FABRIK."""

from prehensile.ik.analytic_nao import nao_arm_ik, nao_arm_ik_batch
from prehensile.ik.complete import CompleteIKSettings, collision_filter, solve_ik_complete
from prehensile.ik.fabrik import FabrikSettings, fabrik
from prehensile.ik.hand_pair import HandPair
from prehensile.ik.hybrid import HybridIKSettings, ObjectRegion, solve_ik_hybrid, solve_regrasp_ik
from prehensile.ik.jacobian import METHODS, ChainSolver, JacobianIKSettings, solve_ik
from prehensile.ik.reach import ReachSamples, reach_samples
from prehensile.ik.result import IKResult, IKStatus

__all__ = ["METHODS", "ChainSolver", "CompleteIKSettings", "FabrikSettings", "HandPair", "HybridIKSettings", "IKResult",
           "IKStatus", "JacobianIKSettings", "ObjectRegion", "ReachSamples", "collision_filter", "fabrik", "nao_arm_ik",
           "nao_arm_ik_batch", "reach_samples", "solve_ik", "solve_ik_complete", "solve_ik_hybrid", "solve_regrasp_ik"]
