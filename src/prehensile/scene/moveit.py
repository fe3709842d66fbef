"""Import MoveIt PlanningScene and MotionPlanRequest YAML files (e.g. MotionBenchMaker).

MoveIt conventions and how they are mapped:

- Quaternions in MoveIt messages are ``(x, y, z, w)`` (lists or ``{x, y, z, w}`` mappings);
  prehensile converts them to its own ``(w, x, y, z)``. As MoveIt, it takes an all-zero one
  (the message default) as the identity and normalises others, with a warning. Positions are
  in m.
- A collision object may carry an object ``pose`` (MoveIt >= 2 / Noetic-late) plus a pose per
  primitive or mesh; the shape's world pose is ``T_world_object @ T_object_shape``. Without an
  object pose the per-shape poses are world poses (older MoveIt).
- ``header.frame_id`` must be empty, ``world``, a frame of ``fixed_frame_transforms`` or, when the
  scene is read for a robot, one of its links, placed by ``robot_state`` (as MoveIt places an
  object given in a link frame: where that link is in the scene's state); other frames are
  rejected with a :class:`~prehensile.errors.SceneError`.
- ``robot_state.attached_collision_objects`` (read for a robot) become objects held by their
  ``link_name`` (:class:`~prehensile.scene.scene.Hold`, with the ``touch_links``); an empty
  ``header.frame_id`` of such an object is its link's frame. Their pose in the link frame is
  taken at the state's joint values as given, before any is clipped into its limits (as MoveIt
  attaches them). Without a robot they are skipped with a warning. A request's ``start_state``
  with attached objects is refused.
- Primitive dimensions follow ``shape_msgs/SolidPrimitive``: box ``[x, y, z]`` (full sides),
  sphere ``[radius]``, cylinder ``[height, radius]`` (note the order: height first), cone
  ``[height, radius]``. A cone becomes a **conservative cylinder** of the same height and base
  radius (it encloses the cone), logged at warning level. Prisms and planes are rejected.
- A request's ``start_state`` with ``is_diff: true`` changes the scene's ``robot_state``: the
  problems of :func:`iter_mbm_problems` start from the scene's joint values with the request's
  set over them.
- A request's goals are its ``goal_constraints``, alternatives as in MoveIt (a path that reaches
  any of them solves the request): each is its ``joint_constraints``, or one position
  constraint (regions: box, sphere and cylinder primitives) with at most one orientation
  constraint on the same link and frame, read as a :class:`~prehensile.scene.pose_goal.PoseGoal`
  (``header.frame_id`` empty, ``world`` or a link of the robot). Joint and pose constraints
  together (in one goal, or joint and pose goals as alternatives) and mesh or cone regions are
  refused.
- The scene's ``allowed_collision_matrix`` is not read: the robot's own SRDF (disabled
  collision pairs) decides which of its link pairs are checked.
- Meshes (``vertices`` / ``triangles``) become in-memory :class:`~prehensile.model.geometry.Mesh`
  shapes (``Mesh.from_arrays``, no file).
- ``robot_state`` (joint values and the ``virtual_joint`` base transform) is applied only when
  a robot model is passed: MoveIt scenes name the robot but prehensile does not guess which
  model file matches it. Joint values outside the limits are clipped into them (warning), so
  that the scene can be saved and loaded again as a scene file.
"""

from __future__ import annotations

import dataclasses
import logging
import os
import re
import tarfile
from dataclasses import dataclass, field
from pathlib import Path, PurePosixPath
from types import MappingProxyType
from typing import Any, Iterator, Mapping

import numpy as np
import yaml

from prehensile.errors import SceneError, missing_file
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Box, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.scene.pose_goal import PoseGoal
from prehensile.scene.scene import Body, Hold, PlacedRobot, Scene, check_hold
from prehensile.scene.schema import YamlLoader, check_mimic_values
from prehensile.spatial import invert, make_pose, quaternion_to_matrix

log = logging.getLogger(__name__)

_PRIMITIVE_IDS = {1: "box", 2: "sphere", 3: "cylinder", 4: "cone", 5: "prism"}
_WORLD_FRAMES = ("", "world", "/world")
_PROBLEM_FILE = re.compile(r"^(scene|request)(\d+)\.ya?ml$")


@dataclass(frozen=True)
class MotionPlanRequest:
    """A MoveIt MotionPlanRequest reduced to a joint-space start and a joint or pose goal.

    Unpacks as ``group, start, goal = request``.

    Attributes:
        group: planning group (e.g. "panda_arm").
        start: joint name -> value (rad or m) of ``start_state.joint_state``.
        goal: joint name -> value of ``goal_constraints[0].joint_constraints`` (empty for a pose goal).
        pose_goal: ``goal_constraints[0]``'s position (and orientation) constraint, or None.
        alternatives: the other goals, ``goal_constraints[1:]``, of the first one's kind: joint
            goals (joint name -> value) or pose goals (:class:`~prehensile.scene.pose_goal.PoseGoal`).
        start_is_diff: ``start_state.is_diff``: the start is the scene's robot state with
            ``start``'s joints changed (:func:`iter_mbm_problems` merges the two into ``start``).
        planner_id: MoveIt planner name ("" if absent).
        allowed_planning_time: s (0 if absent).
        num_planning_attempts: attempts requested (1 if absent).
        source: the file it came from.
    """

    group: str
    start: Mapping[str, float]
    goal: Mapping[str, float]
    pose_goal: PoseGoal | None = None
    alternatives: tuple = ()
    start_is_diff: bool = False
    planner_id: str = ""
    allowed_planning_time: float = 0.0
    num_planning_attempts: int = 1
    source: str = ""

    def __post_init__(self) -> None:
        object.__setattr__(self, "start", MappingProxyType(dict(self.start)))
        object.__setattr__(self, "goal", MappingProxyType(dict(self.goal)))
        object.__setattr__(self, "alternatives", tuple(
            goal if isinstance(goal, PoseGoal) else MappingProxyType(dict(goal)) for goal in self.alternatives))

    @property
    def joint_goals(self) -> tuple[Mapping[str, float], ...]:
        """Every joint goal: :attr:`goal` and the joint goals among the :attr:`alternatives` (none for pose goals)."""
        return tuple(goal for goal in (self.goal, *self.alternatives) if goal and not isinstance(goal, PoseGoal))

    @property
    def pose_goals(self) -> tuple[PoseGoal, ...]:
        """Every pose goal: :attr:`pose_goal` and the pose goals among the :attr:`alternatives`."""
        return tuple(goal for goal in (self.pose_goal, *self.alternatives) if isinstance(goal, PoseGoal))

    def __iter__(self):
        return iter((self.group, self.start, self.goal))

    def start_configuration(self, model: RobotModel, strict: bool = False) -> np.ndarray:
        """q (dof,) with the start joints set and the rest neutral.

        Joints the model does not have (e.g. MBM's finger joints on a model with fixed fingers)
        are skipped unless ``strict``; a request sharing no joint with the model is an error.
        """
        return _configuration(model, self.start, None, f"{self.source}: start_state", strict)

    def goal_configuration(self, model: RobotModel, strict: bool = False) -> np.ndarray:
        """q (dof,): the start configuration with the joints of :attr:`goal` set (fingers keep
        start values; the start itself for a pose goal)."""
        return _configuration(model, self.goal, self.start_configuration(model, strict), f"{self.source}: goal", strict)

    def goal_configurations(self, model: RobotModel, strict: bool = False) -> np.ndarray:
        """(k, dof): each of the k :attr:`joint_goals` as :meth:`goal_configuration` makes the
        first (k = 0 for pose goals)."""
        start = self.start_configuration(model, strict)
        return np.array([_configuration(model, goal, start, f"{self.source}: goal_constraints[{k}]", strict)
                         for k, goal in enumerate(self.joint_goals)]).reshape(-1, model.dof)


@dataclass(frozen=True)
class MBMProblem:
    """One MotionBenchMaker problem: ``scenario`` folder name, ``index`` (NNNN), scene, request."""

    scenario: str
    index: int
    scene: Scene
    request: MotionPlanRequest = field(repr=False)

    def __iter__(self):
        return iter((self.scenario, self.index, self.scene, self.request))


def load_moveit_scene(path: str | os.PathLike, robot: RobotModel | None = None) -> Scene:
    """Read a MoveIt PlanningScene YAML file; collision objects become obstacles, attached ones
    (given a robot) objects held by its links.

    Args:
        path: the ``sceneNNNN.yaml`` file.
        robot: if given, the scene holds it as ``robot.name`` placed by the ``virtual_joint``
            transform of ``robot_state`` (identity if absent) at the ``robot_state`` joint values
            (joints the model does not have are ignored; the rest stay neutral).

    Raises:
        SceneError: unreadable file or a malformed / unsupported collision object.
    """
    path = Path(path)
    return moveit_scene_from_dict(_read_yaml_file(path), str(path), robot)


def load_motion_plan_request(path: str | os.PathLike) -> MotionPlanRequest:
    """Read a MoveIt MotionPlanRequest YAML file (joint-space start and goal)."""
    path = Path(path)
    return motion_plan_request_from_dict(_read_yaml_file(path), str(path))


def iter_mbm_problems(path: str | os.PathLike, robot: RobotModel | None = None,
                      per_scenario: int = 0) -> Iterator[MBMProblem]:
    """Every sceneNNNN / requestNNNN pair under a folder or in a ``.tar.bz2`` (read in memory).

    Problems come sorted by scenario (the folder holding the pair) and index. Each unpacks as
    ``scenario, index, scene, request``.

    Args:
        path: a folder (searched recursively) or a tar archive (any compression tarfile reads).
        robot: passed to :func:`load_moveit_scene`.
        per_scenario: if > 0, only the first that many problems of each scenario (the others
            are not parsed).

    Raises:
        SceneError: the path does not exist, or a scene has no request (or vice versa).
    """
    path = Path(path)
    texts: dict[tuple[str, int], dict[str, tuple[str, str]]] = {}
    for name, relative, read in _problem_files(path):
        kind, index = _PROBLEM_FILE.match(PurePosixPath(relative).name).groups()
        texts.setdefault((str(PurePosixPath(relative).parent), int(index)), {})[kind] = (name, read())
    label = _scenario_labels({folder for folder, _ in texts}, path)
    counts: dict[str, int] = {}
    for (folder, index), pair in sorted(texts.items(), key=lambda item: (label[item[0][0]], item[0][1])):
        scenario = label[folder]
        counts[scenario] = counts.get(scenario, 0) + 1
        if 0 < per_scenario < counts[scenario]:
            continue
        if set(pair) != {"scene", "request"}:
            missing = "request" if "scene" in pair else "scene"
            raise SceneError(f"{path}: {scenario} problem {index:04d} has no {missing} file")
        scene_name, scene_text = pair["scene"]
        request_name, request_text = pair["request"]
        scene_data = _parse(scene_text, scene_name)
        scene = moveit_scene_from_dict(scene_data, scene_name, robot)
        request = motion_plan_request_from_dict(_parse(request_text, request_name), request_name)
        if request.start_is_diff:  # the scene's robot state, with the request's joints changed
            state = _mapping(scene_data.get("robot_state") or {}, f"{scene_name}: robot_state")
            given = _joint_state(state.get("joint_state") or {}, f"{scene_name}: robot_state.joint_state")
            request = dataclasses.replace(request, start={**given, **request.start})
        yield MBMProblem(scenario, index, scene, request)


def moveit_scene_from_dict(data: Any, source: str, robot: RobotModel | None = None) -> Scene:
    """Build a :class:`Scene` from a parsed PlanningScene mapping; ``source`` prefixes errors."""
    data = _mapping(data, source)
    where = f"{source}: fixed_frame_transforms"
    frames = {str(t.get("child_frame_id", "")): _transform(t.get("transform", {}), where)
              for t in _list(data.get("fixed_frame_transforms"), where) if isinstance(t, Mapping)}
    state = _mapping(data.get("robot_state") or {}, f"{source}: robot_state")
    robots: tuple[PlacedRobot, ...] = ()
    held: tuple[Body, ...] = ()
    if robot is not None:
        placed, q_given = _placed_robot(state, robot, f"{source}: robot_state")
        robots = (placed,)
        given = forward_kinematics(robot, q_given, placed.T_world_base)  # as the state places the links
        for link, T_world_link in zip(robot.link_names, given):
            frames.setdefault(link, T_world_link)
        held = _attached_objects(state, placed, given, frames, f"{source}: robot_state")
    elif state.get("attached_collision_objects"):
        log.warning("%s: robot_state.attached_collision_objects skipped: read the scene for a robot model to "
                    "attach them", source)
    world = _mapping(data.get("world") or {}, f"{source}: world")
    objects = _list(world.get("collision_objects"), f"{source}: world.collision_objects")
    bodies = tuple(
        _collision_object(obj, frames, f"{source}: world.collision_objects[{i}]{_label(obj)}")
        for i, obj in enumerate(objects)
    )
    names, world_ids = [body.name for body in held], {body.name for body in bodies}
    for i, name in enumerate(names):
        if name in names[:i] or name in world_ids:
            raise SceneError(f"{source}: robot_state.attached_collision_objects[{i}] '{name}': the object id is "
                             "used twice; ids must be unique among the attached and the world's objects")
    return Scene(robots=robots, obstacles=bodies, objects=held, source=source)


def _attached_objects(state: Mapping, robot: PlacedRobot, given: np.ndarray, frames: Mapping[str, np.ndarray],
                      where: str) -> tuple[Body, ...]:
    """The ``attached_collision_objects`` of a robot state: bodies held by their links, in the
    link frames where the state's links (``given`` (L, 4, 4), before joint values were clipped
    into the limits) hold them, placed where ``robot``'s links are."""
    model, out = robot.model, []
    entries = _list(state.get("attached_collision_objects"), f"{where}.attached_collision_objects")
    poses = robot.link_poses()
    for i, entry in enumerate(entries):
        at = f"{where}.attached_collision_objects[{i}]"
        entry = _mapping(entry, at)
        touch = entry.get("touch_links") or []
        if not isinstance(touch, list):
            raise SceneError(f"{at}.touch_links: expected a list of link names, got {touch!r}")
        if not entry.get("link_name"):
            raise SceneError(f"{at}: missing 'link_name' (the link that holds the object)")
        link = str(entry["link_name"])
        hold = Hold(robot.name, link, tuple(str(name) for name in touch))
        check_hold(model, hold, at, link_key="link_name")
        obj = _mapping(entry.get("object") or {}, f"{at}.object")
        if not obj.get("id"):
            raise SceneError(f"{at}.object: missing 'id' (the object's name)")
        header = _mapping(obj.get("header") or {}, f"{at}.object.header")
        obj = {**obj, "header": {**header, "frame_id": header.get("frame_id") or link}}
        body = _collision_object(obj, frames, f"{at}.object{_label(obj)}")
        k = model.link_index(link)
        T_world_body = poses[k] @ invert(given[k]) @ body.T_world_body
        out.append(dataclasses.replace(body, T_world_body=T_world_body, held_by=hold))
    return tuple(out)


def motion_plan_request_from_dict(data: Any, source: str) -> MotionPlanRequest:
    """Build a :class:`MotionPlanRequest` from a parsed mapping; ``source`` prefixes errors."""
    data = _mapping(data, source)
    start_state = _mapping(data.get("start_state") or {}, f"{source}: start_state")
    start = _joint_state(start_state.get("joint_state") or {}, f"{source}: start_state.joint_state")
    is_diff = start_state.get("is_diff", False)
    if not isinstance(is_diff, bool):
        raise SceneError(f"{source}: start_state.is_diff: expected true or false, got {is_diff!r}")
    if start_state.get("attached_collision_objects"):
        raise SceneError(f"{source}: start_state.attached_collision_objects: not supported in a request; attach the "
                         "objects in the scene's robot_state")
    constraints = _list(data.get("goal_constraints"), f"{source}: goal_constraints")
    if not constraints:
        raise SceneError(f"{source}: goal_constraints: no goal given")
    goals = [_goal(c, f"{source}: goal_constraints[{k}]") for k, c in enumerate(constraints)]
    kinds = {isinstance(goal, PoseGoal) for goal in goals}
    if len(kinds) > 1:
        raise SceneError(f"{source}: goal_constraints: joint goals and pose goals mixed as alternatives are not "
                         "supported; give alternatives of one kind")
    first = goals[0]
    return MotionPlanRequest(
        group=str(data.get("group_name", "")),
        start=start,
        goal={} if isinstance(first, PoseGoal) else first,
        pose_goal=first if isinstance(first, PoseGoal) else None,
        alternatives=tuple(goals[1:]),
        start_is_diff=is_diff,
        planner_id=str(data.get("planner_id", "") or ""),
        allowed_planning_time=_number(data.get("allowed_planning_time", 0.0), f"{source}: allowed_planning_time"),
        num_planning_attempts=_count(data.get("num_planning_attempts", 1) or 1, f"{source}: num_planning_attempts"),
        source=source,
    )


def _goal(constraints: Any, where: str) -> dict[str, float] | PoseGoal:
    """One goal of ``goal_constraints``: its joint constraints (joint name -> position) or its
    pose goal (:func:`_pose_goal`)."""
    constraints = _mapping(constraints, where)
    goal: dict[str, float] = {}
    joints = f"{where}.joint_constraints"
    for k, jc in enumerate(_list(constraints.get("joint_constraints"), joints)):
        here = f"{joints}[{k}]"
        jc = _mapping(jc, here)
        if "joint_name" not in jc:
            raise SceneError(f"{here}: missing 'joint_name'")
        if str(jc["joint_name"]) in goal:
            raise SceneError(f"{here}: joint '{jc['joint_name']}' is constrained twice in this goal")
        goal[str(jc["joint_name"])] = _number(jc.get("position"), f"{here}.position")
    pose_goal = _pose_goal(constraints, where)
    if not goal and pose_goal is None:
        raise SceneError(f"{where} has no joint_constraints and no position_constraints")
    if goal and pose_goal is not None:
        raise SceneError(f"{where}: joint constraints together with position or orientation constraints are not "
                         "supported; give either")
    return goal or pose_goal


def _pose_goal(constraints: Mapping, where: str) -> PoseGoal | None:
    """The position constraint (one; and at most one orientation constraint, on the same link
    in the same frame) of a goal's ``constraints``, or None if it has neither."""
    positions = _list(constraints.get("position_constraints"), f"{where}.position_constraints")
    orientations = _list(constraints.get("orientation_constraints"), f"{where}.orientation_constraints")
    if not positions and not orientations:
        return None
    if len(positions) != 1 or len(orientations) > 1:
        raise SceneError(f"{where}: one position constraint and at most one orientation constraint are supported, "
                         f"got {len(positions)} and {len(orientations)}")
    here = f"{where}.position_constraints[0]"
    position = _mapping(positions[0], here)
    link, frame = _constrained_link(position, here)
    region = _mapping(position.get("constraint_region") or {}, f"{here}.constraint_region")
    if region.get("meshes"):
        raise SceneError(f"{here}.constraint_region.meshes: mesh regions are not supported; valid: box, sphere, "
                         "cylinder primitives")
    shapes, poses = (_list(region.get(key), f"{here}.constraint_region.{key}") for key in ("primitives",
                                                                                           "primitive_poses"))
    if not shapes or len(shapes) != len(poses):
        raise SceneError(f"{here}.constraint_region: expected primitives and as many primitive_poses (at least one), "
                         f"got {len(shapes)} and {len(poses)}")
    regions = []
    for k, (shape, pose) in enumerate(zip(shapes, poses)):
        w = f"{here}.constraint_region.primitives[{k}]"
        if _primitive_kind(_mapping(shape, w)) == "cone":
            raise SceneError(f"{w}: cone regions are not supported; valid: box, sphere, cylinder")
        regions.append((_primitive(shape, w), _pose(pose, f"{here}.constraint_region.primitive_poses[{k}]")))
    goal = dict(link=link, frame=frame, regions=tuple(regions),
                offset=_vector(position.get("target_point_offset") or [0, 0, 0], "xyz", f"{here}.target_point_offset"))
    if orientations:
        here = f"{where}.orientation_constraints[0]"
        orientation = _mapping(orientations[0], here)
        if _constrained_link(orientation, here) != (link, frame):
            raise SceneError(f"{here}: link_name and header.frame_id must be those of the position constraint "
                             f"({link!r}, {frame!r})")
        tolerances = np.array([_number(orientation.get(f"absolute_{axis}_axis_tolerance"),
                                       f"{here}.absolute_{axis}_axis_tolerance") for axis in "xyz"])
        if np.any(tolerances < 0):
            raise SceneError(f"{here}: the axis tolerances must be >= 0, got {tolerances.tolist()}")
        parameterization = orientation.get("parameterization", 0)
        if type(parameterization) is not int or parameterization not in (0, 1):  # not a bool, not a float
            raise SceneError(f"{here}.parameterization: expected 0 (XYZ Euler angles) or 1 (rotation vector), got "
                             f"{parameterization!r}")
        goal.update(orientation=_rigid([0, 0, 0], orientation.get("orientation"), here)[:3, :3],
                    tolerances=tolerances, rotation_vector=parameterization == 1)
    return PoseGoal(**goal)


def _constrained_link(constraint: Mapping, where: str) -> tuple[str, str]:
    """(link_name, header.frame_id with the world's names as "") of a constraint."""
    link = str(constraint.get("link_name") or "")
    if not link:
        raise SceneError(f"{where}: missing 'link_name'")
    frame = str(_mapping(constraint.get("header") or {}, f"{where}.header").get("frame_id", "") or "").lstrip("/")
    return link, "" if frame in _WORLD_FRAMES else frame


def _collision_object(obj: Any, frames: Mapping[str, np.ndarray], where: str) -> Body:
    obj = _mapping(obj, where)
    name = str(obj.get("id", "")) or where.rsplit(": ", 1)[-1]
    operation = obj.get("operation", 0)
    if operation not in (0, "0", "ADD", "add", None):
        raise SceneError(f"{where}: operation {operation!r} is not supported; valid: ADD (0)")
    frame = str(_mapping(obj.get("header") or {}, f"{where}.header").get("frame_id", "") or "")
    if frame in _WORLD_FRAMES:
        T_world_frame = np.eye(4)
    elif frame in frames:
        T_world_frame = frames[frame]
    else:
        valid = ", ".join(dict.fromkeys(["world", *frames]))
        raise SceneError(f"{where}.header.frame_id: frame '{frame}' is not supported; valid: {valid}")
    T_world_object = T_world_frame @ (_pose(obj["pose"], f"{where}.pose") if obj.get("pose") else np.eye(4))
    geometries = []
    for kind, shapes_key, poses_key in (("primitive", "primitives", "primitive_poses"), ("mesh", "meshes", "mesh_poses")):
        shapes, poses = (_list(obj.get(key), f"{where}.{key}") for key in (shapes_key, poses_key))
        if len(poses) != len(shapes):
            raise SceneError(f"{where}: {len(shapes)} {shapes_key} but {len(poses)} {poses_key}")
        for k, (shape, pose) in enumerate(zip(shapes, poses)):
            w = f"{where}.{shapes_key}[{k}]"
            T_object_shape = _pose(pose, f"{where}.{poses_key}[{k}]")
            if kind == "primitive":
                geometries.append(Geometry(_primitive(shape, w), T_object_shape, f"{name}/{k}"))
            else:
                geometries.append(Geometry(_mesh(shape, w), T_object_shape, f"{name}/mesh{k}"))
    if obj.get("planes"):
        raise SceneError(f"{where}: planes are not supported (infinite); model the floor as a thin box")
    if not geometries:
        raise SceneError(f"{where}: collision object '{name}' has no primitives or meshes")
    return Body(name, tuple(geometries), T_world_object)


def _primitive_kind(shape: Mapping) -> str:
    """A SolidPrimitive's ``type`` (its number or name, any case) as a lower-case name."""
    kind = shape.get("type")
    return _PRIMITIVE_IDS.get(kind, str(kind)) if isinstance(kind, int) and not isinstance(kind, bool) \
        else str(kind).lower()


def _primitive(shape: Any, where: str):
    shape = _mapping(shape, where)
    kind = _primitive_kind(shape)
    dims = shape.get("dimensions")
    expected = {"box": 3, "sphere": 1, "cylinder": 2, "cone": 2}
    if kind not in expected:
        raise SceneError(f"{where}: unsupported primitive type {shape.get('type')!r}; valid: box, sphere, cylinder, cone")
    if not isinstance(dims, (list, tuple)) or len(dims) != expected[kind]:
        raise SceneError(f"{where}: {kind} needs {expected[kind]} dimensions, got {dims!r}")
    values = [_number(v, f"{where}.dimensions[{i}]") for i, v in enumerate(dims)]
    if any(v <= 0 for v in values):
        raise SceneError(f"{where}: {kind} dimensions must be positive, got {values}")
    if kind == "box":
        return Box(tuple(values))
    if kind == "sphere":
        return Sphere(values[0])
    height, radius = values  # SolidPrimitive: CYLINDER_HEIGHT = 0, CYLINDER_RADIUS = 1 (cone alike)
    if kind == "cone":
        log.warning("%s: cone replaced by its enclosing cylinder (height %g m, radius %g m)", where, height, radius)
    return Cylinder(radius=radius, length=height)


def _mesh(shape: Any, where: str) -> Mesh:
    shape = _mapping(shape, where)
    try:
        vertices = np.array([[v["x"], v["y"], v["z"]] if isinstance(v, Mapping) else v
                             for v in shape.get("vertices") or []], dtype=float)
        faces = np.array([t["vertex_indices"] if isinstance(t, Mapping) else t
                          for t in shape.get("triangles") or []], dtype=np.int64)
    except (KeyError, TypeError, ValueError) as err:
        raise SceneError(f"{where}: malformed vertices or triangles ({err})") from None
    if vertices.ndim != 2 or vertices.shape[1:] != (3,) or faces.ndim != 2 or faces.shape[1:] != (3,) or not len(faces):
        raise SceneError(f"{where}: expected vertices (n, 3) and triangles (m, 3), got {vertices.shape}, {faces.shape}")
    if not np.all(np.isfinite(vertices)) or faces.min() < 0 or faces.max() >= len(vertices):
        raise SceneError(f"{where}: non-finite vertices or triangle indices out of range")
    return Mesh.from_arrays(vertices, faces)


def _placed_robot(state: Any, model: RobotModel, where: str) -> tuple[PlacedRobot, np.ndarray]:
    """(the robot placed by the state, its joint values clipped into the limits; the joint
    values (dof,) as the state gives them)."""
    state = _mapping(state, where)
    values = _joint_state(state.get("joint_state") or {}, f"{where}.joint_state")
    q = model.neutral_configuration()
    for joint, value in values.items():
        if joint in model.joint_names:
            q[model.joint_index(joint)] = value
    outside = np.flatnonzero((q < model.lower) | (q > model.upper))
    if len(outside):  # MBM's scenes hold panda_joint4 = 0, outside [-3.07, -0.07]
        log.warning("%s: %s outside the joint limits, clipped into them", where,
                    ", ".join(f"{model.joint_names[i]} = {q[i]:.6g}" for i in outside))
    T_world_base = np.eye(4)
    multi = _mapping(state.get("multi_dof_joint_state") or {}, f"{where}.multi_dof_joint_state")
    transforms = _list(multi.get("transforms"), f"{where}.multi_dof_joint_state.transforms")
    if transforms:
        T_world_base = _transform(transforms[0], f"{where}.multi_dof_joint_state.transforms[0]")
    return PlacedRobot(model.name, model, T_world_base, np.clip(q, model.lower, model.upper), model.source), q


def _configuration(model: RobotModel, values: Mapping[str, float], base, where: str, strict: bool) -> np.ndarray:
    """q (dof,): ``base`` (None: neutral) with the joints of ``values`` set. A mimic joint's
    value must agree with the joint it follows (:func:`~prehensile.scene.schema.check_mimic_values`)."""
    mimics = model.mimic_joints
    unknown = [joint for joint in values if joint not in model.joint_names and joint not in mimics]
    if (strict and unknown) or (values and len(unknown) == len(values)):
        raise SceneError(
            f"{where}: robot '{model.name}' has no joint '{unknown[0]}'; joints: {', '.join(model.joint_names)}"
        )
    q = model.configuration_from_dict({j: v for j, v in values.items() if j in model.joint_names}, base)
    check_mimic_values(model, {j: v for j, v in values.items() if j in mimics}, q, where)
    return q


def _joint_state(state: Any, where: str) -> dict[str, float]:
    state = _mapping(state, where)
    names, positions = (_list(state.get(key), f"{where}.{key}") for key in ("name", "position"))
    if len(names) != len(positions):
        raise SceneError(f"{where}: {len(names)} names but {len(positions)} positions")
    repeated = sorted({str(n) for n in names if names.count(n) > 1})
    if repeated:
        raise SceneError(f"{where}.name: {', '.join(repeated)} given twice")
    return {str(n): _number(p, f"{where}.position[{i}]") for i, (n, p) in enumerate(zip(names, positions))}


def _pose(pose: Any, where: str) -> np.ndarray:
    pose = _mapping(pose, where)
    return _rigid(pose.get("position", [0, 0, 0]), pose.get("orientation", [0, 0, 0, 1]), where)


def _transform(transform: Any, where: str) -> np.ndarray:
    transform = _mapping(transform, where)
    return _rigid(transform.get("translation", [0, 0, 0]), transform.get("rotation", [0, 0, 0, 1]), where)


def _rigid(position: Any, orientation: Any, where: str) -> np.ndarray:
    xyz = _vector(position, "xyz", f"{where}.position")
    x, y, z, w = _vector(orientation, "xyzw", f"{where}.orientation (x, y, z, w)")
    norm = float(np.linalg.norm([w, x, y, z]))
    if norm == 0.0:  # the message default, read by MoveIt as no rotation
        log.warning("%s.orientation: all-zero quaternion, taken as the identity (as MoveIt does)", where)
        x, y, z, w, norm = 0.0, 0.0, 0.0, 1.0, 1.0
    elif abs(norm - 1.0) > 1e-3:
        log.warning("%s.orientation: quaternion (x, y, z, w) = %s has norm %.6g; normalised (as MoveIt does)",
                    where, [float(v) for v in (x, y, z, w)], norm)
    return make_pose(quaternion_to_matrix(np.array([w, x, y, z]) / norm), xyz)


def _vector(value: Any, keys: str, where: str) -> np.ndarray:
    if isinstance(value, Mapping):
        value = [value.get(k, 0.0 if k != "w" else 1.0) for k in keys]
    if not isinstance(value, (list, tuple)) or len(value) != len(keys):
        raise SceneError(f"{where}: expected {len(keys)} numbers ({', '.join(keys)}), got {value!r}")
    return np.array([_number(v, f"{where}[{i}]") for i, v in enumerate(value)], dtype=float)


def _number(value: Any, where: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{where}: expected a number, got {value!r}")
    if not np.isfinite(value):
        raise SceneError(f"{where}: must be finite, got {value}")
    return float(value)


def _mapping(value: Any, where: str) -> Mapping:
    if not isinstance(value, Mapping):
        raise SceneError(f"{where}: expected a mapping, got {type(value).__name__}")
    return value


def _list(value: Any, where: str) -> list:
    """``value`` as a list (None or empty: []); a SceneError naming ``where`` otherwise."""
    value = value or []
    if not isinstance(value, list):
        raise SceneError(f"{where}: expected a list, got {type(value).__name__}")
    return value


def _count(value: Any, where: str) -> int:
    if isinstance(value, bool) or not isinstance(value, int) or value < 1:
        raise SceneError(f"{where}: expected a whole number >= 1, got {value!r}")
    return value


def _label(obj: Any) -> str:
    return f" '{obj['id']}'" if isinstance(obj, Mapping) and obj.get("id") else ""


def _read_yaml_file(path: Path) -> Any:
    if not path.is_file():
        raise SceneError(f"{path}: {missing_file(path)}")
    return _parse(_read_text(path), str(path))


def _decode(data: bytes, source: str) -> str:
    try:
        return data.decode("utf-8")
    except UnicodeDecodeError as err:
        raise SceneError(f"{source}: not UTF-8 text ({err.reason} at byte {err.start})") from None


def _parse(text: str, source: str) -> Any:
    try:
        return yaml.load(text, Loader=YamlLoader)
    except yaml.YAMLError as err:
        raise SceneError(f"{source}: not valid YAML ({err})") from None


def _problem_files(path: Path):
    """(name for messages, path inside the folder or archive with '/' separators, reader of its
    text) for each ``sceneNNNN`` / ``requestNNNN`` YAML file of a folder or tar archive."""
    if path.is_dir():
        for file in sorted(path.rglob("*.y*ml")):
            if _PROBLEM_FILE.match(file.name):
                yield str(file), file.relative_to(path).as_posix(), (lambda f=file: _read_text(f))
        return
    if not path.exists():
        raise SceneError(f"{path}: no such folder or archive of MoveIt problems")
    try:
        with tarfile.open(path, "r:*") as archive:
            for member in archive:
                if member.isfile() and _PROBLEM_FILE.match(PurePosixPath(member.name).name):
                    name = f"{path}:{member.name}"
                    data = _decode(archive.extractfile(member).read(), name)
                    yield name, member.name, (lambda d=data: d)
    except tarfile.ReadError:
        raise SceneError(f"{path}: not a folder or a tar archive of MoveIt problems (or a damaged one)") from None
    except (EOFError, OSError, tarfile.TarError) as err:
        raise SceneError(f"{path}: damaged or truncated archive ({err})") from None


def _read_text(file: Path) -> str:
    return _decode(file.read_bytes(), str(file))


def _scenario_labels(folders: set[str], root: Path) -> dict[str, str]:
    """Scenario name of each folder holding problems (paths inside ``root``, '.' for its top):
    the folder's own name, or its path where two folders share a name; the top is named after
    ``root`` (a folder, or an archive without its suffixes)."""
    def name(folder: str) -> str:
        if folder != ".":
            return PurePosixPath(folder).name
        return root.name if root.is_dir() else root.name.split(".")[0]

    taken: dict[str, int] = {}
    for folder in folders:
        taken[name(folder)] = taken.get(name(folder), 0) + 1
    return {folder: name(folder) if taken[name(folder)] == 1 else folder for folder in folders}
