"""``prehensile plan SCENE``: a collision-free path for one robot of a YAML scene.

The start is the robot's configuration in the scene. The goal is a configuration, from
``--goal`` or the robot's ``goal:`` entry in the scene file
(:func:`~prehensile.scene.files.robot_goals`), planned with RRT-Connect; or a world pose of
``--chain``'s tip (``--target x y z roll pitch yaw``), planned with IK-RRT (goal
configurations sampled by IK during the search) or J+-RRT (Jacobian steps toward the pose),
or a world position of the tip (``--target x y z``, any orientation: for arms with fewer than
six joints, such as NAO's), planned with IK-RRT. With ``--position-tolerance`` and
``--rotation-tolerance`` the pose planner may end anywhere in that region around the target
(:func:`tolerance_region`).
The planned joints are ``--chain``'s, else the joints the scene's goal names, else all of the
robot's; joints not planned stay at their start values. The world is the scene's obstacles
and objects plus the other robots at their configurations; the objects the robot holds
(``held_by`` in the scene file) move with their links instead.

Writes to ``--out``: ``path.json`` (status, joint names, waypoints, the held objects with their
links and poses in them, statistics; ``path_length_m`` is the workspace-weighted length, a
bound on how far any point of the robot travels), on success ``trajectory.json`` (time-optimal
under the limits it records, at rest at both ends; the corners are blended by a spline where
the exact check accepts it, else the motion stops there; with the values of the joints not
planned) and always ``plan.png`` (the robot at the start, a few waypoints and the goal, with
the objects it holds).
A failed plan removes the ``trajectory.json`` of an earlier one. Exit codes: 0 path found, 1 no
path (the status says why, e.g. ``invalid_goal`` for a goal in collision), 2 bad input, 3 a bug.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import List, Optional

import numpy as np
import typer

from prehensile.cli.app import (BALL_RADIUS_OPTION, app, check_ball_radius, check_budget, check_seed, console,
                                extra_values, handles_errors)
from prehensile.collision.attached import AttachedObject
from prehensile.errors import PrehensileError, SceneError, UnknownFrameError, missing_file
from prehensile.kinematics import link_pose
from prehensile.model.geometry import Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.planning.to_pose import POSE_PLANNERS, REGION_MARGINS, plan_to_pose
from prehensile.scene.pose_goal import PoseGoal
from prehensile.scene.scene import Body, PlacedRobot, Scene
from prehensile.spatial import make_pose

EXIT_NO_PATH = 1
CONFIGURATION_PLANNERS = ("rrt_connect",)
PLANNERS = CONFIGURATION_PLANNERS + POSE_PLANNERS
PICTURE_WAYPOINTS = 3  # intermediate waypoints drawn besides start and goal


def scene_path(scene: str) -> Path:
    """A scene file path, or the path of the bundled scene of that name."""
    from prehensile.scene.files import bundled_scene_path, bundled_scenes

    path = Path(scene)
    if path.is_file():
        return path
    if scene in bundled_scenes():
        return bundled_scene_path(scene)
    raise SceneError(f"{scene}: {missing_file(scene, 'scene file')}; bundled scenes: {', '.join(bundled_scenes())}")


def choose_robot(scene: Scene, name: str | None, goals: dict) -> PlacedRobot:
    """The robot named ``name``; by default the only robot, or the only one with a goal."""
    names = [r.name for r in scene.robots]
    if not names:
        raise SceneError(f"{scene.source}: the scene has no robots; add one under 'robots:' (see docs/scenes.md)")
    if name is not None:
        if name not in names:
            raise SceneError(f"{scene.source}: no robot '{name}'; robots: {', '.join(names)}")
        return scene.robots[names.index(name)]
    candidates = [r for r in scene.robots if r.name in goals] if len(scene.robots) > 1 else list(scene.robots)
    if len(candidates) != 1:
        raise SceneError(f"{scene.source}: give --robot; robots: {', '.join(names)}")
    return candidates[0]


def goal_configuration(robot: PlacedRobot, joints: list[str], values: list[str] | None,
                       scene_goal: dict[str, float] | None) -> np.ndarray:
    """q (dof,): the start with the planned joints at the goal (command line, else scene).

    Raises:
        PrehensileError: no goal, a value count that differs from the planned joints, a
            non-number or a value outside the joint's limits.
    """
    model = robot.model
    if values:
        try:
            numbers = [float(v) for v in values]
        except ValueError:
            raise PrehensileError(f"--goal: expected numbers (rad or m), got {' '.join(values)}") from None
        if len(numbers) != len(joints):
            plural = "s" * (len(joints) != 1)
            raise PrehensileError(f"--goal: expected {len(joints)} value{plural}, one per planned joint "
                                  f"({', '.join(joints)}), got {len(numbers)}")
        goal = dict(zip(joints, numbers))
    elif scene_goal:
        goal = scene_goal
        unplanned = [j for j in goal if j not in joints]
        if unplanned:
            raise PrehensileError(f"robot '{robot.name}': the scene's goal sets {', '.join(unplanned)}, which the "
                                  f"planned joints ({', '.join(joints)}, from --chain) do not include; give --goal "
                                  "with one value per planned joint, or a --chain that moves them")
    else:
        raise PrehensileError(f"robot '{robot.name}': no goal; give --goal with {len(joints)} values "
                              f"({', '.join(joints)}) or a 'goal:' entry in the scene file")
    q = model.configuration_from_dict(goal, robot.configuration)
    for joint, value in goal.items():
        i = model.joint_index(joint)
        if not np.isfinite(value):
            raise PrehensileError(f"goal: {joint} = {value} is not a finite number (rad or m)")
        if not model.lower[i] - 1e-9 <= value <= model.upper[i] + 1e-9:
            raise PrehensileError(f"goal: {joint} = {value:.6g} is outside its limits "
                                  f"[{model.lower[i]:.6g}, {model.upper[i]:.6g}]")
    return q


def tolerance_region(model: RobotModel, chain: str | None, target: np.ndarray | None, planner: str,
                     position_tolerance: float | None, rotation_tolerance: float | None) -> PoseGoal | None:
    """The goal region that ``--position-tolerance`` and ``--rotation-tolerance`` give around the
    ``--target`` pose (4, 4) or position (3,) of ``chain``'s tip: a ball of that radius (m), the
    orientation within that angle (rad) per rotation-vector component; a tolerance not given,
    or below the planner's precision, is that precision (:data:`REGION_MARGINS`). None without
    either."""
    if position_tolerance is None and rotation_tolerance is None:
        return None
    if target is None:
        raise PrehensileError("--position-tolerance, --rotation-tolerance: tolerances of a --target; give one")
    if rotation_tolerance is not None and target.shape == (3,):
        raise PrehensileError("--rotation-tolerance: the --target is a position (x y z); give x y z roll pitch yaw")
    for name, value in (("--position-tolerance", position_tolerance), ("--rotation-tolerance", rotation_tolerance)):
        if value is not None and not 0.0 <= value < np.inf:
            raise PrehensileError(f"{name}: must be a finite number >= 0, got {value}")
    radius, angle = (max(value or 0.0, least) for value, least in zip((position_tolerance, rotation_tolerance),
                                                                      REGION_MARGINS[planner]))
    position = target if target.shape == (3,) else target[:3, 3]
    return PoseGoal(model.chain(chain).tip_link, ((Sphere(radius), make_pose(position=position)),),
                    orientation=None if target.shape == (3,) else target[:3, :3], tolerances=np.full(3, angle),
                    rotation_vector=True)


def plan_report(result, ctx, scene: Path, robot: PlacedRobot, q_goal: np.ndarray | None, target: np.ndarray | None,
                planner: str, seed: int, region: PoseGoal | None = None) -> dict:
    """The JSON of ``path.json``: start, goal (the configuration reached on success: for a
    target pose, or a continuous joint a whole turn from the one asked, else the one asked)
    and waypoints in the planned joints, the target pose and its ``tolerance`` (the ``region``
    of :func:`tolerance_region`; ``goal_satisfied``: the path ends in it), the other joints'
    values, the held objects (link, ``T_link_object``), status and statistics; for an invalid
    start or goal, why (``reason``, :func:`_end_reason`)."""
    space = ctx.space
    fixed = [j for j in robot.model.joint_names if j not in space.joint_names]
    if result.success:
        q_goal = result.path[-1]
    tolerance = satisfied = None
    if region is not None:
        tolerance = {"position_m": region.regions[0][0].radius,
                     "rotation_rad": None if region.orientation is None else float(region.tolerances[0])}
        if result.success:
            T_world_tip = link_pose(robot.model, q_goal, region.link, T_world_base=robot.T_world_base)
            satisfied = region.satisfied(np.eye(4), T_world_tip)
    return {
        "scene": str(scene), "robot": robot.name, "planner": planner, "seed": seed, "status": result.status.value,
        "joint_names": list(space.joint_names), "start": space.active(robot.configuration).tolist(),
        "goal": None if q_goal is None else space.active(q_goal).tolist(),
        "target": None if target is None else target.tolist(), "tolerance": tolerance, "goal_satisfied": satisfied,
        "waypoints": space.active(result.path).tolist() if result.success else [],
        "fixed_joints": {j: float(space.q_ref[robot.model.joint_index(j)]) for j in fixed},
        "held_objects": {obj.name: {"link": obj.link, "T_link_object": np.asarray(obj.T_link_object).tolist()}
                         for obj in ctx.attached},
        "path_length_m": space.path_length(space.active(result.path)) if result.success else None,
        "stats": dataclasses.asdict(result.stats),
        "reason": _end_reason(result, ctx, robot.configuration, q_goal),
    }


def _end_reason(result, ctx, q_start: np.ndarray, q_goal: np.ndarray | None) -> str | None:
    """Why the planner could not use the start or goal, "start: ..." / "goal: ..." (the
    planner's ``info["reason"]``, :meth:`~prehensile.planning.context.PlanningContext.explain`),
    with a hint at finer balls (``--ball-radius``) where only the sphere model rejects an end;
    for a target no IK solution reached; None otherwise."""
    from prehensile.planning import PlanStatus

    if result.status is PlanStatus.NO_GOAL_CONFIGURATION:
        return ("goal: IK found no configuration that puts the chain's tip at the target and is free within the "
                "budget (the target may be out of reach, or every solution found collides)")
    reason = result.info.get("reason")
    if reason is None:
        return None
    blamed = [q for end, q in (("start", q_start), ("goal", q_goal)) if end in result.blamed_ends and q is not None]
    if any(ctx.model.within_limits(q) and ctx.exact.is_free(q) and not ctx.is_valid(q) for q in blamed):
        reason += ("; finer balls (a smaller --ball-radius, down to what the links' meshes allow) may make such "
                   "ends valid")
    return reason


def picture_scene(scene: Scene, robot: PlacedRobot, configurations: np.ndarray,
                  attached: tuple[AttachedObject, ...] = ()) -> Scene:
    """``scene`` with ``robot`` replaced by copies at each configuration (N, dof), each with
    a copy of the ``attached`` objects (held by ``robot``, in place of the scene's bodies)."""
    labels = ["start"] + [f"waypoint {k}" for k in range(1, len(configurations) - 1)] + ["goal"]
    copies = tuple(dataclasses.replace(robot, name=f"{robot.name} ({label})", q=q)
                   for label, q in zip(labels, configurations))
    carried = tuple(Body(f"{obj.name} ({copy.name})", obj.geometries(),
                         copy.link_poses()[robot.model.link_index(obj.link)] @ obj.T_link_object)
                    for copy in copies for obj in attached)
    held = {obj.name for obj in attached}
    others = tuple(r for r in scene.robots if r.name != robot.name)
    return dataclasses.replace(scene, robots=copies + others,
                               objects=tuple(b for b in scene.objects if b.name not in held) + carried)


def write_outputs(result, context, scene: Scene, robot: PlacedRobot, report: dict, out: Path) -> list[Path]:
    """Write path.json, trajectory.json (on success, else an earlier one is removed) and
    plan.png to ``out``, together (:func:`~prehensile.storage.atomic_write_files`); returns the paths."""
    from prehensile.planning import certify_path
    from prehensile.planning.trajectory import model_limits, time_parameterize
    from prehensile.storage import atomic_write_files, json_bytes
    from prehensile.viz import scene_image
    from prehensile.viz.picture import IDLE_ROBOT_COLOR, PATH_GOAL, PATH_START, path_colors

    files = {out / "path.json": json_bytes(report)}
    if result.success:
        space = context.space
        velocity, acceleration = model_limits(robot.model, space.indices)

        def certified(qa: np.ndarray, qb: np.ndarray) -> bool:
            """The blend check: exact, as for the path, whose ends may be ones only the balls reject."""
            return certify_path(context, space.full(np.stack([qa, qb]))).ok

        trajectory = time_parameterize(space.active(result.path), velocity, acceleration, blend_check=certified,
                                       joint_names=space.joint_names)
        extra = {"velocity_limits": velocity.tolist(), "acceleration_limits": acceleration.tolist(),
                 "fixed_joints": report["fixed_joints"]}  # the robot's other joints, held throughout
        files[out / "trajectory.json"] = json_bytes({**trajectory.to_dict(), **extra})
        inner = result.path[1:-1]
        picks = inner[np.linspace(0, len(inner) - 1, min(PICTURE_WAYPOINTS, len(inner))).round().astype(int)]
        shown = np.concatenate([result.path[:1], picks, result.path[-1:]])
        title = (f"{robot.name} from start ({PATH_START[1]}) to goal ({PATH_GOAL[1]}): "
                 f"{len(result.path)} waypoints, {report['path_length_m']:.2f} m (no point of the robot travels "
                 f"farther), {trajectory.duration:.2f} s")
    else:
        known = [report["start"]] + ([] if report["goal"] is None else [report["goal"]])
        shown = context.space.full(np.array(known))
        title = (f"{robot.name}: no path ({result.status.value}); start ({PATH_START[1]})"
                 f"{f' and goal ({PATH_GOAL[1]})' if len(known) == 2 else ''} shown")
    drawn = picture_scene(scene, robot, shown, context.attached)
    colors = dict(zip((r.name for r in drawn.robots), path_colors(len(shown))))
    colors.update((r.name, IDLE_ROBOT_COLOR) for r in drawn.robots[len(shown):])
    files[out / "plan.png"] = scene_image(drawn, title=title, robot_colors=colors)
    written = atomic_write_files(files)
    if not result.success:
        (out / "trajectory.json").unlink(missing_ok=True)  # never leave an earlier plan's trajectory
    return written


@app.command("plan", context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
@handles_errors
def plan(
    ctx: typer.Context,
    scene: str = typer.Argument(..., metavar="SCENE",
                                help="YAML scene file or bundled scene name (e.g. plan_demo)."),
    robot: Optional[str] = typer.Option(None, "--robot", help="Robot of the scene (default: the only one, "
                                        "or the only one with a goal)."),
    chain: Optional[str] = typer.Option(None, "--chain", help="Plan this chain's joints (default: the joints "
                                        "of the scene's goal, else all)."),
    goal: Optional[List[str]] = typer.Option(None, "--goal", metavar="V...",
                                             help="Goal values, one per planned joint (rad or m): "
                                             "--goal v1 v2 ... (default: the scene's goal)."),
    target: Optional[List[str]] = typer.Option(None, "--target", metavar="X Y Z [R P Y]",
                                               help="Goal pose of --chain's tip in the world "
                                               "instead: --target x y z roll pitch yaw (m, rad), or its "
                                               "position alone: --target x y z (ik_rrt)."),
    planner: Optional[str] = typer.Option(None, "--planner", help="rrt_connect (to a configuration; the default) "
                                          "or, to a --target pose, ik_rrt (the default) or jplus_rrt."),
    position_tolerance: Optional[float] = typer.Option(
        None, "--position-tolerance", metavar="M", help="The tip may end anywhere within M m of the "
        "--target position (default: the planner's own precision: ik_rrt 0.2 mm, jplus_rrt 2 mm)."),
    rotation_tolerance: Optional[float] = typer.Option(
        None, "--rotation-tolerance", metavar="RAD", help="The tip's orientation may differ from the "
        "--target's by up to RAD about each axis (rotation vector; default: the planner's own precision: ik_rrt "
        "2 mrad, jplus_rrt 20 mrad)."),
    budget: float = typer.Option(1.0, "--budget", help="Search time limit (s)."),
    ball_radius: Optional[float] = BALL_RADIUS_OPTION,
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    out: Path = typer.Option(Path("prehensile-plan"), "--out", help="Folder for path.json, trajectory.json, plan.png."),
) -> None:
    """Plan from the robot's scene configuration to a goal configuration or tool pose.

    Exit code 0 when a path is found, 1 when none is, 2 on bad input, 3 on a bug.
    """
    from prehensile.cli.ik_cmd import parse_target
    from prehensile.collision.spheres import generate_sphere_model
    from prehensile.planning import PlanningContext, RRTConnectSettings, rrt_connect
    from prehensile.scene.check import robot_obstacles
    from prehensile.scene.files import load_scene, robot_goals
    from prehensile.storage import check_writable

    if goal and target:
        raise PrehensileError("give either --goal (a configuration) or --target (a tool pose), not both")
    values = extra_values(ctx.args, goal or target, "--target" if target else "--goal", "goal values")
    planner = planner or (POSE_PLANNERS[0] if target else CONFIGURATION_PLANNERS[0])
    if planner not in PLANNERS:
        raise PrehensileError(f"--planner: unknown planner '{planner}'; valid: {', '.join(PLANNERS)}")
    if (planner in POSE_PLANNERS) != bool(target):
        raise PrehensileError(f"--planner {planner} plans to " + (
            "a tool pose: give --target x y z roll pitch yaw and --chain" if planner in POSE_PLANNERS else
            f"a configuration; for a --target pose use {' or '.join(POSE_PLANNERS)}"))
    if target and chain is None:
        raise PrehensileError("--target: give --chain, the chain whose tip goes to the pose")
    check_budget(budget)
    check_seed(seed)
    check_ball_radius(ball_radius)
    check_writable(out, "--out", folder=True)
    path = scene_path(scene)
    loaded = load_scene(path)
    goals = robot_goals(path, loaded)
    placed = choose_robot(loaded, robot, goals)
    model = placed.model
    scene_goal = goals.get(placed.name)
    if chain is not None:
        try:
            joints = list(model.chain(chain).joint_names)
        except UnknownFrameError as error:
            raise PrehensileError(f"--chain: {error} (scene {path})") from None
    elif scene_goal:
        joints = list(scene_goal)
    else:
        joints = list(model.joint_names)
    pose = parse_target(values) if target else None
    if pose is not None and pose.shape == (3,) and planner == "jplus_rrt":
        raise PrehensileError("--planner jplus_rrt steps toward a full pose: give --target x y z roll pitch yaw, "
                              "or plan to a position with ik_rrt")
    region = tolerance_region(model, chain, pose, planner, position_tolerance, rotation_tolerance)
    q_goal = None if target else goal_configuration(placed, joints, values, scene_goal)
    q_start = placed.configuration
    obstacles = loaded.collision_obstacles(placed.name) + [o for r in loaded.robots if r.name != placed.name
                                                           for o in robot_obstacles(r)]
    spheres = None if ball_radius is None else generate_sphere_model(model, max_radius=ball_radius)
    context = PlanningContext(model, obstacles, joints=joints, q_ref=q_start, T_world_base=placed.T_world_base,
                              spheres=spheres, attached=loaded.attached_objects(placed.name))
    if pose is None:
        result = rrt_connect(context, q_start, q_goal, settings=RRTConnectSettings(time_budget_s=budget),
                             rng=np.random.default_rng(seed))
    else:
        result = plan_to_pose(context, q_start, pose if region is None else None, chain, planner, budget, seed,
                              region=None if region is None else (region, np.eye(4)))
    report = plan_report(result, context, path, placed, q_goal, pose, planner, seed, region)
    written = write_outputs(result, context, loaded, placed, report, out)
    stats = result.stats
    console.print(f"status: [{'green' if result.success else 'bold red'}]{result.status.value}[/]  "
                  f"search {1e3 * stats.plan_time_s:.2f} ms, simplify {1e3 * stats.simplify_time_s:.2f} ms, "
                  f"certify {1e3 * stats.certify_time_s:.2f} ms, {len(result.path)} waypoints")
    if report["reason"]:
        console.print(report["reason"])
    console.print("wrote " + ", ".join(str(p) for p in written))
    raise typer.Exit(0 if result.success else EXIT_NO_PATH)

