"""Planning to a tool pose (or position) with either pose planner: IK-RRT or J+-RRT."""

from __future__ import annotations

from functools import partial
from typing import Callable

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.ik import ChainSolver, JacobianIKSettings
from prehensile.planning.context import PlanningContext
from prehensile.planning.ik_rrt import IKRRTSettings, grasp_sampler, ik_rrt
from prehensile.planning.jplus_rrt import JPlusRRTSettings, jplus_rrt
from prehensile.planning.result import PlanResult

POSE_PLANNERS = ("ik_rrt", "jplus_rrt")

IK_RRT_MARGIN = (2.0 * JacobianIKSettings.position_tolerance, 2.0 * JacobianIKSettings.rotation_tolerance)
"""(m, rad) how far inside a goal region's bounds IK-RRT's targets stay (:func:`region_targets`):
twice its IK's tolerances, so that the configurations it finds lie in the region."""


def region_targets(goal, T_world_frame: np.ndarray, T_world_link: np.ndarray
                   ) -> tuple[np.ndarray, Callable[[np.random.Generator], np.ndarray]]:
    """IK-RRT's targets (``target``, ``more_targets`` of :func:`plan_to_pose`) for a goal region
    ``goal`` (a :class:`~prehensile.scene.PoseGoal`, its frame at world pose T_world_frame
    (4, 4)): first the target nearest to the constrained link's start pose T_world_link (4, 4),
    then random ones, all :data:`IK_RRT_MARGIN` inside the region's bounds."""
    return (goal.closest(T_world_frame, T_world_link, IK_RRT_MARGIN),
            partial(goal.sample, T_world_frame=T_world_frame, margin=IK_RRT_MARGIN))


def plan_to_pose(ctx: PlanningContext, q_start: np.ndarray, target: np.ndarray, chain: str, planner: str = "ik_rrt",
                 time_budget_s: float = 1.0, rng: np.random.Generator | int | None = None,
                 T_tip_tcp: np.ndarray | None = None,
                 more_targets: Callable[[np.random.Generator], np.ndarray] | None = None) -> PlanResult:
    """Plan from ``q_start`` (dof,) to any configuration that puts the tool frame (the tip link
    of ``chain`` times ``T_tip_tcp`` (4, 4), default the tip link itself) at the world pose
    ``target`` (4, 4), or (ik_rrt only) its origin at the world position ``target`` (3,) (m).

    Args:
        ctx: planning context that plans the chain's joints.
        planner: one of :data:`POSE_PLANNERS`: ``ik_rrt`` (goal configurations sampled by IK
            while the trees grow) or ``jplus_rrt`` (Jacobian steps toward the pose).
        time_budget_s: search time limit (s).
        rng: random source or seed.
        more_targets: (ik_rrt only) further targets like ``target``, drawn anew for each IK
            sample after the first (:func:`~prehensile.planning.ik_rrt.grasp_sampler`), e.g.
            random poses of a goal region (:func:`region_targets`).

    Raises:
        PrehensileError: an unknown planner, a position target or ``more_targets`` for jplus_rrt.
    """
    if planner not in POSE_PLANNERS:
        raise PrehensileError(f"planner '{planner}' does not plan to a pose; valid: {', '.join(POSE_PLANNERS)}")
    target = np.asarray(target, dtype=float)
    if target.shape not in ((4, 4), (3,)):
        raise PrehensileError(f"{planner}: the target must be a (4, 4) pose or a (3,) position, got {target.shape}")
    if planner == "jplus_rrt":
        if more_targets is not None:
            raise PrehensileError("jplus_rrt steps toward fixed poses: more_targets is for ik_rrt")
        if target.shape == (3,):
            raise PrehensileError("jplus_rrt steps toward a full pose: give a (4, 4) target, or plan to a position "
                                  "with ik_rrt")
        return jplus_rrt(ctx, q_start, target[None], JPlusRRTSettings(time_budget_s=time_budget_s), rng,
                         T_tip_tcp=T_tip_tcp, chain=chain)
    solver = ChainSolver(ctx.model, chain, T_tip_tcp=T_tip_tcp, T_world_root=ctx.T_world_base,
                         settings=JacobianIKSettings(position_only=target.shape == (3,)))
    more = None if more_targets is None else (lambda rng: np.asarray(more_targets(rng), dtype=float)[None])
    return ik_rrt(ctx, q_start, grasp_sampler(ctx, solver, target[None], q_start, more),
                  IKRRTSettings(time_budget_s=time_budget_s), rng)
