"""MotionBenchMaker-style benchmark: every MoveIt scene/request pair of a folder or archive.

For each problem the robot is placed by the scene's ``robot_state``, the obstacles are the
scene's collision objects, and the planned joints are the request's planning group (a chain of
the model, e.g. an SRDF group) or, when the model has no such chain, the joints of the
request's goal constraints. Start and goal come from the request; joints not planned keep their
start values, clipped into their limits (with a warning) as the scene's ``robot_state`` is.
Every problem is read and its goal checked before the first is planned.

Our planner is RRT-Connect to the goal configuration, or a pose planner (IK-RRT, J+-RRT) to
the pose that configuration gives the tip link of the request's group (any configuration that
reaches it will do). Returned paths of a pose planner are checked to end at that pose. A
request whose goal is a pose (MoveIt position and orientation constraints,
:class:`~prehensile.scene.pose_goal.PoseGoal`) needs a pose planner (the link must be the
group's tip or a link fixed to it, the frame the world or a link the group does not move):
IK-RRT samples goals anywhere in the regions and tolerances (its first IK aims at the pose
nearest to the start's: a start that meets the goal with its margin to spare,
:data:`~prehensile.planning.to_pose.REGION_MARGINS`, is a goal), J+-RRT steps toward the pose
of the regions nearest to the tool (:func:`~prehensile.planning.to_pose.plan_to_pose`). Every
path's end is checked against the request's constraints (``goal_satisfied``): a path that
ends outside them counts as unsolved. A request's alternative goals (MoveIt's
``goal_constraints``: joint goals, or pose goals on one point of the tool) are one goal set:
RRT-Connect and OMPL plan to any of the configurations, the pose planners to any of the poses
or regions, and a path that ends at any of them solves the request.

Measured per problem and planner:

- **planning time**: search plus simplification, wall clock, the same definition for ours
  (our planner's call minus its reported certification
  time) and the peer (OMPL ``solve`` + ``simplifySolution``), with Python's garbage collector
  paused as ``timeit`` does;
- **certification time**: our planner's exact-mesh certification, reported separately;
- **path length**: workspace-weighted length (m) of the returned path, the same metric for both;
- **exact collision**: every returned path is re-checked here, independently of the planner's
  own certification, with the exact meshes at configurations ``verify_resolution`` m apart
  (workspace-weighted), so a path that only the spheres call free is counted as colliding;
- **ends**: every returned path must start at the request's start and end at its goal
  configuration (a pose planner's: meet its goal pose), else it counts as unsolved
  (``ends_elsewhere``).

Timing statistics (median, 95th percentile, mean) are over the solved problems, as in the
MotionBenchMaker and VAMP reports; ``solved`` / ``total`` and the status counts say how many
that is. Speed-ups are OMPL time / our time (> 1: ours faster): of the medians (and 95th
percentiles) of each planner's solved problems, and "paired", the median of the per-problem
ratio over the problems both solved.
"""

from __future__ import annotations

import contextlib
import functools
import gc
import logging
import time
import zlib
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Callable, Sequence

import numpy as np

from prehensile.benchmarking.stats import machine, mean_or_none, ratio, time_summary, versions
from prehensile.collision.spheres import SphereModel, generate_sphere_model, pad_sphere_model, spheres_from_urdf
from prehensile.errors import PrehensileError
from prehensile.kinematics import link_pose
from prehensile.model.robot_model import RobotModel
from prehensile.planning import PlanningContext, RRTConnectSettings, rrt_connect
from prehensile.planning.certify import certified_escape
from prehensile.planning.to_pose import POSE_PLANNERS, plan_to_pose, region_tool_frame
from prehensile.scene.moveit import MBMProblem, iter_mbm_problems
from prehensile.settings import FINITE_POSITIVE, POSITIVE, at_least, check_fields
from prehensile.spatial import rotation_error

log = logging.getLogger(__name__)

PLANNERS = ("rrt_connect", *POSE_PLANNERS)


@dataclass(frozen=True)
class MBMSettings:
    """Benchmark settings.

    Attributes:
        planner: our planner, one of :data:`PLANNERS` (``rrt_connect`` plans to the goal
            configuration, the others to the group's tip pose there).
        time_budget_s: search time limit per problem and planner (s).
        seed: seed of our planner's generators (per problem, from the seed, the scenario name and
            the problem's index, so a problem plans the same in any set) and of OMPL.
        limit: at most this many problems per scenario (0: all).
        compare_ompl: also run OMPL's RRT-Connect on every problem (to the goal configuration,
            so only beside ``rrt_connect``).
        resolution: motion-check spacing (m, workspace-weighted) of both planners.
        certify_resolution: our planner's exact certification spacing (m).
        verify_resolution: spacing (m) of the independent exact re-check of returned paths.
    """

    planner: str = "rrt_connect"
    time_budget_s: float = 1.0
    seed: int = 0
    limit: int = 0
    compare_ompl: bool = False
    resolution: float = 0.005
    certify_resolution: float = 0.002
    verify_resolution: float = 0.002

    def __post_init__(self) -> None:
        if self.planner not in PLANNERS:
            raise PrehensileError(f"planner '{self.planner}' is not available; valid: {', '.join(PLANNERS)}")
        if self.compare_ompl and self.planner != "rrt_connect":
            raise PrehensileError(f"compare_ompl: OMPL's RRT-Connect plans to the goal configuration, {self.planner} "
                                  "to a pose; compare OMPL with planner rrt_connect")
        check_fields(self, time_budget_s=FINITE_POSITIVE, seed=at_least(0), limit=at_least(0),
                     **dict.fromkeys(("resolution", "certify_resolution", "verify_resolution"), POSITIVE))


def benchmark_spheres(model: RobotModel, spherized_urdf: str | Path | None, pad: bool = False,
                      max_radius: float | None = None) -> tuple[SphereModel, SphereModel | None]:
    """(planning balls, covering balls or None) of the robot.

    Without ``spherized_urdf``: balls generated from the collision geometry (they cover it; none
    larger than ``max_radius`` m where the per-link cap allows, see
    :func:`~prehensile.collision.spheres.generate_sphere_model`). Else the
    file's balls as they are, which can miss mesh contacts (the exact certification rejects
    such paths; the planner then plans again with the covering balls, the same balls padded to
    cover the meshes, on the links that collided), or with ``pad`` the padded balls alone.
    """
    if spherized_urdf is None:
        return generate_sphere_model(model, max_radius=max_radius), None
    balls = spheres_from_urdf(model, spherized_urdf)
    padded = pad_sphere_model(balls, model)
    return (padded, None) if pad else (balls, padded)


def planned_joints(model: RobotModel, problem: MBMProblem) -> list[str]:
    """The joints to plan: the request's group as a chain of the model, else its goal joints.

    Raises:
        PrehensileError: neither gives a joint of the model.
    """
    request = problem.request
    if request.group in model.chains:
        return list(model.chain(request.group).joint_names)
    joints = [j for j in request.goal if j in model.joint_names]
    if not joints:
        chains = ", ".join(model.chains) or "(none)"
        raise PrehensileError(
            f"{request.source}: planning group '{request.group}' is not a chain of robot '{model.name}' "
            f"(chains: {chains}{'' if model.srdf_source else '; give the SRDF'}) and no goal joint is a joint "
            "of the model")
    return joints


def load_problems(path: str | Path, model: RobotModel, limit: int = 0) -> list[MBMProblem]:
    """The problems of a folder or archive (at most ``limit`` per scenario if > 0), sorted.

    Raises:
        SceneError: the path is neither a folder nor an archive, or a pair is incomplete.
        PrehensileError: no problem found.
    """
    problems = list(iter_mbm_problems(path, robot=model, per_scenario=limit))
    if not problems:
        raise PrehensileError(f"{path}: no MoveIt problems found (expected sceneNNNN.yaml / requestNNNN.yaml pairs)")
    return problems


def path_collides_exactly(space, exact, path: np.ndarray, resolution: float) -> bool:
    """Whether the exact meshes find a collision on the path (N, dof) checked ``resolution`` m apart.

    Each straight segment is sampled with ``space.interpolate`` (workspace-weighted spacing);
    segments are checked in order and the check stops at the first colliding one.
    """
    active = space.active(path)
    for a, b in zip(active[:-1], active[1:]):
        if not np.all(exact.is_free(space.full(space.interpolate(a, b, resolution)))):
            return True
    return len(active) == 1 and not bool(exact.is_free(path[0]))


def check_request(model: RobotModel, problem: MBMProblem, joints: Sequence[str]) -> None:
    """The request's goal must set every planned joint and no other joint (a mimic joint counts
    as the joint it follows), its start every planned joint.

    Raises:
        PrehensileError: naming the request file, the joints at fault and the planned ones.
    """
    request = problem.request
    planned = ", ".join(joints)
    mimics = model.mimic_joints
    known = [*model.joint_names, *mimics]
    for k, goal in enumerate(request.joint_goals):
        where = f"{request.source}: goal_constraints[{k}].joint_constraints"
        unknown = [j for j in goal if j not in known]
        if unknown:
            raise PrehensileError(f"{where}: robot '{model.name}' has no joint {', '.join(unknown)} "
                                  f"(planned: {planned})")
        outside = [j for j in goal if (model.joint_names[mimics[j][0]] if j in mimics else j) not in joints]
        if outside:
            raise PrehensileError(f"{where}: {', '.join(outside)} not in the planned group '{request.group}' "
                                  f"(planned: {planned})")
        missing = [j for j in joints if j not in goal]
        if missing:
            raise PrehensileError(f"{where}: no goal for planned joint(s) {', '.join(missing)} (planned: {planned})")
    missing = [j for j in joints if j not in request.start]
    if missing:
        unknown = [j for j in request.start if j not in known]
        raise PrehensileError(f"{request.source}: start_state.joint_state: no start for planned joint(s) "
                              f"{', '.join(missing)}"
                              + (f"; robot '{model.name}' has no joint {', '.join(unknown)}" if unknown else "")
                              + f" (planned: {planned})")


class PreparedProblem:
    """One problem prepared for planning: context, start and goal."""

    def __init__(self, model: RobotModel, spheres: tuple[SphereModel, SphereModel | None], problem: MBMProblem,
                 settings: MBMSettings) -> None:
        self.problem = problem
        joints = planned_joints(model, problem)
        check_request(model, problem, joints)
        self.q_start, self.q_goal = _clip_unplanned(model, problem, joints)
        scene = problem.scene
        robot, T_world_base = (scene.robots[0].name, scene.robots[0].T_world_base) if scene.robots else (None, None)
        self.tip = goal_tip(model, problem, settings.planner)
        # the pose planners' goal: the world pose (4, 4) or position (3,) of the tool frame T_tip_tcp on
        # the tip link (k of them, (k, 4, 4) or (k, 3), for k alternative goals); for a joint goal the tip
        # link's pose at the goal configuration. T_world_frames: the pose goals' frames.
        self.T_tip_tcp, self.T_world_frames, self.target = None, (), None
        pose_goals = problem.request.pose_goals
        if pose_goals:
            self.T_world_frames, self.T_tip_tcp = pose_goal_frames(model, problem, self.tip, self.q_start,
                                                                   T_world_base)
            targets = [goal.target(T) for goal, T in zip(pose_goals, self.T_world_frames)]
            self.target, self.q_goal = targets[0] if len(targets) == 1 else np.array(targets), None
        elif self.tip is not None:
            self.target = np.array([link_pose(model, q, self.tip, T_world_base=T_world_base)
                                    for q in np.reshape(self.q_goal, (-1, model.dof))]).reshape(
                np.shape(self.q_goal)[:-1] + (4, 4))
        self.ctx = PlanningContext(model, scene.collision_obstacles(robot), joints=joints, q_ref=self.q_start,
                                   T_world_base=T_world_base, spheres=spheres[0], cover=spheres[1],
                                   attached=scene.attached_objects(robot), resolution=settings.resolution,
                                   certify_resolution=settings.certify_resolution)
        # the exact certifier is built on first use: build it here, outside the timed planner call
        _ = self.ctx.certifier


def goal_tip(model: RobotModel, problem: MBMProblem, planner: str) -> str | None:
    """The link a pose planner brings to the goal pose (the tip of the request's group), None
    for ``rrt_connect``.

    Raises:
        PrehensileError: the request's group is not a chain of the model; a pose goal for
            ``rrt_connect``, or one without orientation for ``jplus_rrt``.
    """
    request = problem.request
    if request.pose_goals and planner not in POSE_PLANNERS:
        raise PrehensileError(f"{request.source}: goal_constraints[0]: a pose goal (position and orientation "
                              f"constraints) needs a pose planner: {' or '.join(POSE_PLANNERS)}")
    if planner not in POSE_PLANNERS:
        return None
    for k, goal in enumerate(request.pose_goals):
        if goal.orientation is None and planner == "jplus_rrt":
            raise PrehensileError(f"{request.source}: goal_constraints[{k}]: jplus_rrt steps toward a full pose, and "
                                  "the goal has no orientation constraint; use ik_rrt")
    group = request.group
    if group not in model.chains:
        raise PrehensileError(f"{request.source}: group: {planner} plans to the pose of a chain's tip, and "
                              f"'{group}' is not a chain of robot '{model.name}' (chains: "
                              f"{', '.join(model.chains) or '(none)'}{'' if model.srdf_source else '; give the SRDF'})")
    chain = model.chain(group)
    tip_path = set(model.path_to_root(chain.tip_link))
    astray = [joint for joint in chain.joint_names if not any(  # off the chain and not below its tip
        link in tip_path or tip_path <= set(model.path_to_root(link))
        for link, name in enumerate(model.link_joint_names) if name == joint)]
    if astray:
        raise PrehensileError(f"{request.source}: group: {planner} plans the pose of one tip, and group '{group}' "
                              f"branches: {', '.join(astray)} move(s) neither the path to its tip '{chain.tip_link}' "
                              "nor what lies below it; plan it with rrt_connect")
    return chain.tip_link


def pose_goal_frames(model: RobotModel, problem: MBMProblem, tip: str, q_start: np.ndarray,
                     T_world_base: np.ndarray | None) -> tuple[tuple[np.ndarray, ...], np.ndarray]:
    """(T_world_frame (4, 4) of each pose goal of a request, T_tip_tcp (4, 4)): the pose of
    the goal's frame with the robot at q_start (dof,), and the constrained point's frame on the
    group's tip link, the same for every goal.

    Raises:
        PrehensileError: a frame or link the robot does not have, a frame that the group's
            joints move (MoveIt would place it where each checked state puts it), a
            constrained link that they move relative to the group's tip, alternative goals
            on different points or some with an orientation constraint and some without.
    """
    request = problem.request
    planned = set(model.chain_q_indices(request.group).tolist())
    frames, tools = [], []
    for k, goal in enumerate(request.pose_goals):
        where = f"{request.source}: goal_constraints[{k}]"
        for name, what in ((goal.frame, "header.frame_id"), (goal.link, "link_name")):
            if name and name not in model.link_names:
                raise PrehensileError(f"{where}: {what} '{name}' is not {'the world or ' * (what != 'link_name')}a "
                                      f"link of robot '{model.name}'")
        if goal.frame and model.variables_to_root(goal.frame) & planned:
            raise PrehensileError(f"{where}: header.frame_id '{goal.frame}' is moved by group '{request.group}'; "
                                  "give the constraints in the world or in a link the group does not move")
        T_tip_tcp = region_tool_frame(model, tip, goal, q_start, planned)
        if T_tip_tcp is None:
            raise PrehensileError(f"{where}: link_name '{goal.link}' moves relative to the tip '{tip}' of group "
                                  f"'{request.group}'; constrain the tip or a link fixed to it")
        if tools and not np.allclose(T_tip_tcp, tools[0], atol=1e-9):
            raise PrehensileError(f"{where}: constrains another point than goal_constraints[0] (links "
                                  f"'{goal.link}', '{request.pose_goals[0].link}'); give alternatives on one point")
        if (goal.orientation is None) != (request.pose_goals[0].orientation is None):
            raise PrehensileError(f"{where}: constrains the orientation where goal_constraints[0] does not, or the "
                                  "other way round; give alternatives of one kind")
        frames.append(link_pose(model, q_start, goal.frame, T_world_base=T_world_base) if goal.frame else np.eye(4))
        tools.append(T_tip_tcp)
    return tuple(frames), tools[0]


def _unplanned_outside(model: RobotModel, q_start: np.ndarray, joints: Sequence[str]) -> np.ndarray:
    """Indices of the joints not planned whose start value q_start (dof,) lies outside their limits."""
    fixed = np.array([name not in joints for name in model.joint_names])
    return np.flatnonzero(fixed & ((q_start < model.lower) | (q_start > model.upper)))


def _clip_unplanned(model: RobotModel, problem: MBMProblem, joints: Sequence[str]) -> tuple[np.ndarray, np.ndarray]:
    """The request's start (dof,) and goal (dof,) (the start for a pose goal; (k, dof) for k
    alternative joint goals) with the joints not planned clipped into their limits (MBM's
    requests hold Panda finger values beyond some models' limits; :func:`check_problems` names
    them)."""
    request = problem.request
    q_start = request.start_configuration(model)
    goals = request.goal_configurations(model)
    q_goal = goals if len(goals) > 1 else request.goal_configuration(model)
    outside = _unplanned_outside(model, q_start, joints)
    q_start[outside] = q_goal[..., outside] = np.clip(q_start[outside], model.lower[outside], model.upper[outside])
    return q_start, q_goal


def check_problems(model: RobotModel, problems: Sequence[MBMProblem], planner: str = "rrt_connect") -> None:
    """Check every problem's planned joints, start and goal (and for a pose planner its
    group's tip) before any is planned; a warning names the joints not planned whose start lies
    outside their limits (:class:`PreparedProblem` clips them into them).

    Raises:
        PrehensileError: naming the first request at fault (see :func:`check_request`, :func:`goal_tip`).
    """
    for problem in problems:
        joints = planned_joints(model, problem)
        check_request(model, problem, joints)
        tip = goal_tip(model, problem, planner)
        problem.request.goal_configurations(model)  # and the start they build on
        q_start = problem.request.start_configuration(model)
        if problem.request.pose_goals:
            robots = problem.scene.robots
            pose_goal_frames(model, problem, tip, q_start, robots[0].T_world_base if robots else None)
        outside = _unplanned_outside(model, q_start, joints)
        if len(outside):
            log.warning("%s: start_state: %s outside the joint limits and not planned, clipped into them",
                        problem.request.source,
                        ", ".join(f"{model.joint_names[i]} = {q_start[i]:.6g}" for i in outside))


def problem_seed(settings: MBMSettings, problem: MBMProblem) -> list[int]:
    """Our planner's seed for one problem: the same whichever other problems run with it."""
    return [settings.seed, zlib.crc32(problem.scenario.encode()), problem.index]


@contextlib.contextmanager
def _without_gc():
    """Python's cyclic garbage collector paused, as ``timeit`` does: a collection of what
    preparing the problem left behind would otherwise land, at tens of milliseconds, in
    whichever timed call allocates next."""
    enabled = gc.isenabled()
    gc.disable()
    try:
        yield
    finally:
        if enabled:
            gc.enable()


def run_ours(prepared: PreparedProblem, settings: MBMSettings) -> dict:
    """The per-problem record of our planner (``settings.planner``) on one prepared problem."""
    rng = np.random.default_rng(problem_seed(settings, prepared.problem))
    with _without_gc():
        start = time.perf_counter()
        result = _plan(prepared, settings, rng)
        wall = time.perf_counter() - start
    return _record(prepared, result, wall - result.stats.certify_time_s, settings, certified=True)


@functools.lru_cache(maxsize=8)
def _rrt_settings(settings: MBMSettings) -> RRTConnectSettings:
    """RRT-Connect's settings, built (and validated) once per benchmark, not in each timed call."""
    return RRTConnectSettings(time_budget_s=settings.time_budget_s)


def _plan(prepared: PreparedProblem, settings: MBMSettings, rng: np.random.Generator | None = None):
    """Our planner's PlanResult on one problem."""
    if prepared.target is None:
        return rrt_connect(prepared.ctx, prepared.q_start, prepared.q_goal, settings=_rrt_settings(settings), rng=rng)
    request = prepared.problem.request
    if request.pose_goals:
        return plan_to_pose(prepared.ctx, prepared.q_start, None, request.group, settings.planner,
                            settings.time_budget_s, rng, region=list(zip(request.pose_goals, prepared.T_world_frames)))
    return plan_to_pose(prepared.ctx, prepared.q_start, prepared.target, request.group, settings.planner,
                        settings.time_budget_s, rng)


def run_ompl(prepared: PreparedProblem, settings: MBMSettings) -> dict:
    """The per-problem record of OMPL's RRT-Connect with our sphere checker on one prepared problem."""
    from prehensile.benchmarking.ompl_peer import OMPLSettings, ompl_rrt_connect

    ompl_settings = OMPLSettings(time_budget_s=settings.time_budget_s, resolution=settings.resolution)
    with _without_gc():
        result = ompl_rrt_connect(prepared.ctx.space, prepared.ctx.spheres, prepared.q_start, prepared.q_goal,
                                  ompl_settings, seed=settings.seed)
    return _record(prepared, result, result.stats.plan_time_s + result.stats.simplify_time_s, settings, certified=False)


def _record(prepared: PreparedProblem, result, time_s: float, settings: MBMSettings, certified: bool) -> dict:
    """The per-problem record of one planner's result (``certified``: the planner certifies its paths)."""
    space = prepared.ctx.space
    record = {
        "status": result.status.value, "solved": result.success, "time_s": time_s,
        "search_s": result.stats.plan_time_s, "simplify_s": result.stats.simplify_time_s,
        "certify_s": result.stats.certify_time_s if certified else None,
        "collision_checks": result.stats.collision_checks,
        "waypoints": len(result.path), "path_length": None, "exact_colliding": None,
        # pose planners: the path's end against the goal pose (a pose goal's: its first region's centre)
        "goal_error_m": None, "goal_error_rad": None,
        "goal_satisfied": None,  # pose goals: the path's end meets the request's constraints
        "ends_as_asked": None,  # the path starts at the start and (a joint goal) ends at the goal
        "attempts": result.info.get("attempts", 1),  # > 1: planned again after a failed certification
    }
    reason = prepared.ctx.explain(result, prepared.q_start, prepared.q_goal).info.get("reason")  # OMPL's has none
    if reason:  # an unusable end explains most failures
        record["reason"] = reason
    if result.success:
        record["path_length"] = space.path_length(space.active(result.path))
        record["exact_colliding"] = path_collides_exactly(space, prepared.ctx.exact, result.path,
                                                          settings.verify_resolution)
        record["ends_as_asked"] = _ends_as_asked(prepared, result.path)
        if prepared.target is not None:
            record.update(_goal_errors(prepared, result.path[-1]))
        # a path that starts or ends elsewhere solves nothing (its status stays the planner's)
        record["solved"] = record["ends_as_asked"] and record["goal_satisfied"] is not False
    return record


def _ends_as_asked(prepared: PreparedProblem, path: np.ndarray) -> bool:
    """Whether the path (N, dof) starts at the request's start and, for a joint goal planned
    to (not a pose planner's), ends at its goal configuration (one of them), within 1e-9 (a
    continuous joint's goal counts modulo whole turns)."""
    space, tolerance = prepared.ctx.space, 1e-9
    starts = bool(np.all(np.abs(path[0] - prepared.q_start) <= tolerance))
    if prepared.target is not None:  # a pose planner: its end is checked against the pose (goal errors)
        return starts
    end = space.active(path[-1])
    return starts and any(np.all(np.abs(space.nearest_turn(end, goal) - goal) <= tolerance)
                          for goal in space.active(np.reshape(prepared.q_goal, (-1, space.model.dof))))


def _goal_errors(prepared: PreparedProblem, q: np.ndarray) -> dict:
    """How far the tool frame at q (dof,) is from a pose planner's target, the nearest of
    alternative ones (m, rad; None: a position target), and whether q meets one of the
    request's pose goals (None: joint goals)."""
    model, target, T_world_base = prepared.ctx.model, prepared.target, prepared.ctx.T_world_base
    reached = link_pose(model, q, prepared.tip, prepared.T_tip_tcp, T_world_base=T_world_base)
    if target.shape[-1] == 3:
        errors = {"goal_error_m": float(np.min(np.linalg.norm(reached[:3, 3] - target.reshape(-1, 3), axis=1))),
                  "goal_error_rad": None}
    else:
        target = min(target.reshape(-1, 4, 4), key=lambda T: np.linalg.norm(reached[:3, 3] - T[:3, 3]))
        errors = {"goal_error_m": float(np.linalg.norm(reached[:3, 3] - target[:3, 3])),
                  "goal_error_rad": float(np.linalg.norm(rotation_error(target[:3, :3], reached[:3, :3])))}
    request = prepared.problem.request
    if request.pose_goals:
        errors["goal_satisfied"] = any(
            goal.satisfied(T_world_frame, link_pose(model, q, goal.link, T_world_base=T_world_base))
            for goal, T_world_frame in zip(request.pose_goals, prepared.T_world_frames))
    return errors


def summarize(records: Sequence[dict]) -> dict:
    """Solved / total, timing statistics over solved problems, mean path length, colliding
    paths and status counts of one planner's per-problem records."""
    solved = [r for r in records if r["solved"]]
    statuses: dict[str, int] = {}
    for r in records:
        statuses[r["status"]] = statuses.get(r["status"], 0) + 1
    search = time_summary([r["search_s"] for r in solved])
    simplify = time_summary([r["simplify_s"] for r in solved])
    certify = time_summary([r["certify_s"] for r in solved if r["certify_s"] is not None])
    return {
        "solved": len(solved), "total": len(records),
        "solved_fraction": len(solved) / len(records) if records else None,
        **time_summary([r["time_s"] for r in solved]),
        "search_median_ms": search["median_ms"], "simplify_median_ms": simplify["median_ms"],
        "certify_median_ms": certify["median_ms"], "certify_p95_ms": certify["p95_ms"],
        "path_length": mean_or_none(r["path_length"] for r in solved),
        "colliding_paths": sum(bool(r["exact_colliding"]) for r in solved),
        "collision_checks_median": float(np.median([r["collision_checks"] for r in solved])) if solved else None,
        **{f"{key}_max": max((r[key] for r in solved if r[key] is not None), default=None)
           for key in ("goal_error_m", "goal_error_rad")},
        # pose goals: paths that end outside the request's constraints, not solved (None: no pose goal checked)
        "goal_unsatisfied": sum(r.get("goal_satisfied") is False for r in records)
        if any(r.get("goal_satisfied") is not None for r in records) else None,
        # paths that start or end elsewhere than the request asks (not solved)
        "ends_elsewhere": sum(r.get("ends_as_asked") is False for r in records),
        "planned_again": sum(r["attempts"] > 1 for r in records),
        "statuses": statuses,
    }


def _by_scenario(runs: Sequence[dict], key: str) -> dict:
    scenarios: dict[str, list[dict]] = {}
    for run in runs:
        scenarios.setdefault(run["scenario"], []).append(run[key])
    return {"overall": summarize([run[key] for run in runs]),
            "scenarios": {name: summarize(records) for name, records in scenarios.items()}}


def speedups(ours: dict, ompl: dict) -> dict:
    """OMPL / ours for the time statistics of two summaries, ours / OMPL for path length."""
    return {
        "median_speedup": ratio(ompl["median_ms"], ours["median_ms"]),
        "p95_speedup": ratio(ompl["p95_ms"], ours["p95_ms"]),
        "mean_speedup": ratio(ompl["mean_ms"], ours["mean_ms"]),
        "search_median_speedup": ratio(ompl["search_median_ms"], ours["search_median_ms"]),
        "path_length_ratio": ratio(ours["path_length"], ompl["path_length"]),
    }


def _paired(runs: Sequence[dict]) -> dict:
    """Problems both planners solved and the median over them of OMPL's time / ours."""
    both = [r for r in runs if r["ours"]["solved"] and r["ompl"]["solved"] and r["ours"]["time_s"] > 0]
    speedups_ = [r["ompl"]["time_s"] / r["ours"]["time_s"] for r in both]
    return {"paired_problems": len(both), "paired_median_speedup": float(np.median(speedups_)) if both else None}


def _ratios(runs: Sequence[dict], ours: dict, ompl: dict) -> dict:
    return {
        **speedups(ours["overall"], ompl["overall"]), **_paired(runs),
        "scenarios": {name: {**speedups(summary, ompl["scenarios"][name]),
                             **_paired([r for r in runs if r["scenario"] == name])}
                      for name, summary in ours["scenarios"].items()},
    }


def run_mbm(problems_path: str | Path, model: RobotModel, spheres: tuple[SphereModel, SphereModel | None],
            settings: MBMSettings = MBMSettings(),
            progress: Callable[[int, int, dict | None], None] | None = None) -> dict:
    """Run the benchmark; returns the JSON-ready report.

    Args:
        problems_path: folder or archive of MoveIt scene/request YAML pairs.
        model: the robot (with its SRDF for groups and disabled collision pairs).
        spheres: planning balls and covering balls (see :func:`benchmark_spheres`).
        settings: see :class:`MBMSettings`.
        progress: called with (0, total, None) once the problems are loaded and checked, then
            after each problem with (done, total, per-problem record).

    Returns:
        ``{"overall", "scenarios", "ompl", "ratios", "runs", "settings", "robot", "machine",
        "versions"}``; ``ompl`` and ``ratios`` are None without ``compare_ompl``.
    """
    problems = load_problems(problems_path, model, settings.limit)
    check_problems(model, problems, settings.planner)
    if progress is not None:
        progress(0, len(problems), None)
    warm_up(model, spheres, problems[0], settings)
    runs = []
    for number, problem in enumerate(problems):
        prepared = PreparedProblem(model, spheres, problem, settings)
        run = {"scenario": problem.scenario, "index": problem.index, "ours": run_ours(prepared, settings)}
        if settings.compare_ompl:
            run["ompl"] = run_ompl(prepared, settings)
        runs.append(run)
        if progress is not None:
            progress(number + 1, len(problems), run)
    ours = _by_scenario(runs, "ours")
    ompl = _by_scenario(runs, "ompl") if settings.compare_ompl else None
    report = {
        "benchmark": "mbm", "problems": str(problems_path), **ours, "ompl": ompl,
        "ratios": _ratios(runs, ours, ompl) if ompl else None,
        "settings": asdict(settings),
        "robot": {"name": model.name, "source": model.source, "spheres": spheres[0].n_spheres,
                  "cover_spheres": None if spheres[1] is None else spheres[1].n_spheres,
                  "joints": planned_joints(model, problems[0])},
        "machine": machine(), "versions": versions(), "runs": runs,
    }
    if settings.compare_ompl:
        from prehensile.benchmarking.ompl_peer import segment_fraction, validity_call_seconds

        prepared = PreparedProblem(model, spheres, problems[0], settings)
        report["ompl"]["validity_call_us"] = 1e6 * validity_call_seconds(prepared.ctx.spheres, prepared.q_start)
        space = prepared.ctx.space  # the problem's start sets the sampled turn of a continuous joint
        bounds = space.sampling_bounds(space.active(prepared.q_start))
        report["ompl"]["segment_fraction"] = segment_fraction(space, settings.resolution, *bounds)
    return report


def warm_up(model: RobotModel, spheres: tuple[SphereModel, SphereModel | None], problem: MBMProblem,
            settings: MBMSettings) -> None:
    """Compile (or load from numba's cache) every kernel on one problem before timing, those of
    certified escapes too (few problems need one: the screening of the ends, the escape's
    search and certification)."""
    start = time.perf_counter()
    prepared = PreparedProblem(model, spheres, problem, settings)
    _plan(prepared, settings)
    ctx, q = prepared.ctx, prepared.q_start
    ctx.spheres.is_free(q)
    ctx.spheres.clearance(q, self_pairs=False)
    ctx.spheres.screen(q, ctx.end_margin)
    ctx.exact_screen(q)
    certified_escape(ctx, q, q, np.random.default_rng(0), ctx.end_margin, attempts=2)  # a random direction
    log.info("warm-up (compilation) took %.2f s", time.perf_counter() - start)
