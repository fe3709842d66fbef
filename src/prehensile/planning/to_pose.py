"""Planning to a tool pose (or position), or into a goal region, with either pose planner:
IK-RRT or J+-RRT."""

from __future__ import annotations

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.ik import ChainSolver, JacobianIKSettings
from prehensile.kinematics.forward import link_pose
from prehensile.planning.context import PlanningContext
from prehensile.planning.ik_rrt import IKRRTSettings, grasp_sampler, ik_rrt
from prehensile.planning.jplus_rrt import JPlusRRTSettings, jplus_rrt
from prehensile.planning.result import PlanResult
from prehensile.scene.pose_goal import PoseGoal
from prehensile.spatial.transforms import invert

POSE_PLANNERS = ("ik_rrt", "jplus_rrt")

REGION_MARGINS = {
    "ik_rrt": (2.0 * JacobianIKSettings.position_tolerance, 2.0 * JacobianIKSettings.rotation_tolerance),
    "jplus_rrt": (2.0 * JPlusRRTSettings.position_tolerance, 2.0 * JPlusRRTSettings.rotation_tolerance),
}
"""(m, rad) per pose planner: how far inside a goal region's bounds its targets stay, twice the
precision to which it reaches a target (its IK's tolerances; J+-RRT's goal tolerances), so that
the configuration it ends at lies in the region."""


def plan_to_pose(ctx: PlanningContext, q_start: np.ndarray, target: np.ndarray | None, chain: str,
                 planner: str = "ik_rrt", time_budget_s: float = 1.0, rng: np.random.Generator | int | None = None,
                 T_tip_tcp: np.ndarray | None = None, region: tuple | None = None) -> PlanResult:
    """Plan from ``q_start`` (dof,) to any configuration that puts the tool frame (the tip link
    of ``chain`` times ``T_tip_tcp`` (4, 4), default the tip link itself) at the world pose
    ``target`` (4, 4) or one of the poses (k, 4, 4), or (ik_rrt only) its origin at the world
    position ``target`` (3,) or one of (k, 3) (m); or anywhere in a goal ``region``.

    Args:
        ctx: planning context that plans the chain's joints.
        target: the tool's world pose(s) or position(s); None with a ``region``.
        planner: one of :data:`POSE_PLANNERS`: ``ik_rrt`` (goal configurations sampled by IK
            while the trees grow) or ``jplus_rrt`` (Jacobian steps toward the pose).
        time_budget_s: search time limit (s).
        rng: random source or seed.
        T_tip_tcp: the tool frame on the tip link; None with a ``region``.
        region: (:class:`~prehensile.scene.PoseGoal`, T_world_frame (4, 4) the pose of its
            frame), or a list of such pairs, alternatives (MoveIt's goal_constraints) that
            constrain the same point and all or none the orientation: the goal's constrained
            point frame is the tool (its link must be the chain's tip or fixed to it). IK-RRT
            aims its first IK sample at the regions' pose nearest to the start's tool, later
            ones at random poses of a random goal; J+-RRT steps toward the regions' pose
            nearest to the tool (in position). Both keep :data:`REGION_MARGINS` inside the
            bounds (a region smaller than that is aimed at its centre).

    Raises:
        PrehensileError: an unknown planner, a malformed target, a position target (or a
            region without orientation) for jplus_rrt, a region given with a target or
            T_tip_tcp.
    """
    if planner not in POSE_PLANNERS:
        raise PrehensileError(f"planner '{planner}' does not plan to a pose; valid: {', '.join(POSE_PLANNERS)} "
                              "(ik_rrt is RRT-Connect with goal configurations sampled by IK as it searches)")
    more = None
    if region is not None:
        if target is not None or T_tip_tcp is not None:
            raise PrehensileError(f"{planner}: a region is the goal: give target=None and T_tip_tcp=None with it")
        target, more, T_tip_tcp = _region_goal(ctx, q_start, chain, planner,
                                               [region] if isinstance(region[0], PoseGoal) else list(region))
    if planner == "jplus_rrt":
        if not callable(target):
            target = _checked_target(target, planner)
            if target.shape[-1] == 3:
                raise PrehensileError("jplus_rrt steps toward a full pose: give a (4, 4) target, or plan to a "
                                      "position with ik_rrt")
        return jplus_rrt(ctx, q_start, target, JPlusRRTSettings(time_budget_s=time_budget_s), rng,
                         T_tip_tcp=T_tip_tcp, chain=chain)
    target = _checked_target(target, planner)
    solver = ChainSolver(ctx.model, chain, T_tip_tcp=T_tip_tcp, T_world_root=ctx.T_world_base,
                         settings=JacobianIKSettings(position_only=target.shape[-1] == 3))
    return ik_rrt(ctx, q_start, grasp_sampler(ctx, solver, target, q_start, more),
                  IKRRTSettings(time_budget_s=time_budget_s), rng)


def region_tool_frame(model, tip: str, goal, q: np.ndarray, planned: set[int]) -> np.ndarray | None:
    """T_tip_tcp (4, 4): the constrained point frame of ``goal`` (a
    :class:`~prehensile.scene.PoseGoal`) on the link ``tip``, as q (dof,) places them; None if
    the goal's link moves relative to the tip when the variables ``planned`` (indices into q) move."""
    if model.variables_to_root(goal.link) & planned != model.variables_to_root(tip) & planned:
        return None
    return invert(link_pose(model, q, tip)) @ link_pose(model, q, goal.link) @ goal.T_link_point


def _checked_target(target, planner: str) -> np.ndarray:
    """The target as poses (k, 4, 4) or positions (k, 3)."""
    target = np.asarray(target, dtype=float)
    if target.shape in ((4, 4), (3,)):
        return target[None]
    if target.ndim == 3 and target.shape[1:] == (4, 4) or target.ndim == 2 and target.shape[1] == 3:
        if len(target):
            return target
    raise PrehensileError(f"{planner}: the target must be a (4, 4) pose, a (3,) position or a non-empty set of "
                          f"them, (k, 4, 4) or (k, 3), got {target.shape}")


def _region_goal(ctx: PlanningContext, q_start: np.ndarray, chain: str, planner: str, regions: list):
    """(target, more_targets, T_tip_tcp) of goal regions, alternatives ``regions`` [(PoseGoal,
    T_world_frame (4, 4))], for ``planner`` (:func:`plan_to_pose`): for IK-RRT the target
    nearest to the start's tool and a function drawing random ones, for J+-RRT a function from
    a tool pose to the nearest target; the tool frame is the goals' point frame on the chain's
    tip link (placed as ``q_start`` (dof,) puts it)."""
    model, margin, tip = ctx.model, REGION_MARGINS[planner], ctx.model.chain(chain).tip_link
    planned = set(ctx.space.indices.tolist())
    frames = []
    for goal, _ in regions:
        T_tip_tcp = region_tool_frame(model, tip, goal, q_start, planned)
        if T_tip_tcp is None:
            raise PrehensileError(f"{planner}: the goal's link '{goal.link}' moves relative to the tip '{tip}' of "
                                  f"chain '{chain}'; constrain the tip or a link fixed to it")
        frames.append(T_tip_tcp)
    if any(not np.allclose(T, frames[0], atol=1e-9) for T in frames[1:]):
        raise PrehensileError(f"{planner}: alternative goals constrain different points of links "
                              f"{', '.join(sorted({goal.link for goal, _ in regions}))}; give goals on one point")
    if len({goal.orientation is None for goal, _ in regions}) > 1:
        raise PrehensileError(f"{planner}: some alternative goals constrain the orientation and some do not; give "
                              "goals of one kind")
    if planner == "jplus_rrt":
        if regions[0][0].orientation is None:
            raise PrehensileError(f"jplus_rrt steps toward a full pose, and the goal of link '{regions[0][0].link}' "
                                  "has no orientation constraint; use ik_rrt")

        T_point_links = [invert(goal.T_link_point) for goal, _ in regions]

        def nearest(T_world_tool: np.ndarray) -> np.ndarray:
            targets = [goal.closest(T_world_frame, T_world_tool @ T_point_link, margin)
                       for (goal, T_world_frame), T_point_link in zip(regions, T_point_links)]
            return min(targets, key=lambda T: np.linalg.norm(T[:3, 3] - T_world_tool[:3, 3]))

        return nearest, None, frames[0]
    tool = (link_pose(model, q_start, tip, T_world_base=ctx.T_world_base) @ frames[0])[:3, 3]
    firsts = [np.asarray(goal.closest(T_world_frame, link_pose(model, q_start, goal.link,
                                                               T_world_base=ctx.T_world_base), margin))
              for goal, T_world_frame in regions]  # poses (4, 4) or positions (3,)
    first = min(firsts, key=lambda target: np.linalg.norm((target[:3, 3] if target.ndim == 2 else target) - tool))

    def more(rng: np.random.Generator) -> np.ndarray:
        goal, T_world_frame = regions[rng.integers(len(regions))]
        return np.asarray(goal.sample(rng, T_world_frame=T_world_frame, margin=margin))[None]

    return first, more, frames[0]
