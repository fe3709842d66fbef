"""YAML scene files: :func:`load_scene` and :func:`save_scene`.

Schema (format version 1; lengths in m, angles in rad)::

    version: 1                       # optional
    robots:
      - name: arm                    # unique in the scene; default: the robot's name
        robot: panda                 # a bundled robot (prehensile.robots.available()) or a
                                     # model file (URDF, ...) relative to this scene file
        pose:                        # base pose T_world_base, optional (identity)
          position: [0.0, 0.0, 0.75]
          rpy: [0.0, 0.0, 1.57]      # or quaternion: [w, x, y, z] (scalar first, unit norm)
        joints: {panda_joint1: 0.3}  # optional; joints not named stay at neutral (rad or m)
        goal: {panda_joint1: -0.3}   # optional planning goal (see robot_goals); not part of Scene
    obstacles:                       # static bodies
      - name: table                  # unique among obstacles and objects
        pose: {position: [0.5, 0, 0.37]}
        shape: {type: box, size: [1.0, 0.8, 0.74]}
    objects:                         # movable bodies (same keys as obstacles, and held_by)
      - name: mug
        pose: {position: [0.4, 0.1, 0.79]}
        shapes:                      # several shapes: use 'shapes' (a list) instead of 'shape'
          - {type: cylinder, radius: 0.04, length: 0.1}
          - {type: box, size: [0.01, 0.03, 0.06], pose: {position: [0.05, 0, 0]}}
        held_by:                     # optional: a robot link carries it (pose: where it is now)
          robot: arm
          link: panda_hand
          touch_links: [panda_leftfinger, panda_rightfinger]   # optional: may touch these too

Shape types and pose keys are listed in :mod:`prehensile.scene.schema`. Every problem is a
:class:`~prehensile.errors.SceneError` naming the file, the entry (``obstacles[2] 'shelf'``)
and the valid choices: unknown keys, robots, joints or shape types, missing mesh files, poses
of the wrong length, non-unit quaternions, NaN, and zero or negative sizes.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from prehensile.errors import PrehensileError, SceneError, missing_file
from prehensile.model.robot_model import RobotModel
from prehensile.scene.scene import Body, Hold, PlacedRobot, Scene, check_hold
from prehensile.storage import atomic_write_text
from prehensile.scene.schema import (
    YamlLoader, check_keys, check_mimic_values, number, read_pose, read_shape, relative_path, write_pose, write_shape,
)

FORMAT_VERSION = 1
SCENE_KEYS = ("version", "robots", "obstacles", "objects")
ROBOT_KEYS = ("name", "robot", "pose", "joints", "goal")
BODY_KEYS = ("name", "pose", "shape", "shapes")
OBJECT_KEYS = BODY_KEYS + ("held_by",)
HOLD_KEYS = ("robot", "link", "touch_links")
_MODEL_SUFFIXES = (".urdf", ".xml", ".mjcf", ".srdf")


def load_scene(path: str | os.PathLike) -> Scene:
    """Read a YAML scene file (schema in the module docstring).

    Args:
        path: the scene file; robot model files and meshes are relative to its folder.

    Returns:
        The :class:`Scene` with ``source`` set to the file path.

    Raises:
        SceneError: the file is missing, not YAML, or breaks the schema.
    """
    path = Path(path)
    if not path.is_file():
        raise SceneError(f"{path}: {missing_file(path, 'scene file')}")
    try:
        with path.open(encoding="utf-8") as stream:  # yaml's messages then name the file
            data = yaml.load(stream, Loader=YamlLoader)
    except yaml.YAMLError as err:
        raise SceneError(f"{path}: not valid YAML ({err})") from None
    except UnicodeDecodeError:
        raise SceneError(f"{path}: not a text file") from None
    return scene_from_dict({} if data is None else data, path.parent, str(path))


def scene_from_dict(data: Any, base_dir: Path, source: str = "<scene>") -> Scene:
    """Build a :class:`Scene` from the parsed YAML ``data``; ``source`` prefixes error messages."""
    if isinstance(data, Mapping) and {"world", "robot_state"} & set(data):
        raise SceneError(f"{source}: a MoveIt PlanningScene, not a prehensile scene file; read it with "
                         "prehensile.scene.load_moveit_scene (see docs/scenes.md)")
    check_keys(data, SCENE_KEYS, source)
    if "version" in data and data["version"] != FORMAT_VERSION:
        raise SceneError(f"{source}: version: unsupported scene format {data['version']!r}; valid: {FORMAT_VERSION}")
    models: dict[str, RobotModel] = {}
    robots = tuple(
        _read_robot(entry, base_dir, f"{source}: robots[{i}]{_label(entry)}", models)
        for i, entry in enumerate(_list(data, "robots", source))
    )
    _unique([r.name for r in robots], f"{source}: robots")
    placed = {robot.name: robot.model for robot in robots}
    bodies = {
        key: tuple(
            _read_body(entry, base_dir, f"{source}: {key}[{i}]{_label(entry)}", placed if key == "objects" else None)
            for i, entry in enumerate(_list(data, key, source))
        )
        for key in ("obstacles", "objects")
    }
    _unique([b.name for b in bodies["obstacles"] + bodies["objects"]], f"{source}: obstacles and objects")
    return Scene(robots, bodies["obstacles"], bodies["objects"], source)


def robot_goals(path: str | os.PathLike, scene: Scene) -> dict[str, dict[str, float]]:
    """The ``goal:`` entries of a scene file's robots: robot name -> {joint: value (rad or m)}.

    Goals are planning inputs (``prehensile plan``), not part of :class:`Scene`;
    :func:`save_scene` does not write them. ``scene`` is :func:`load_scene` of the same file.

    Raises:
        SceneError: a goal that is not a mapping or is empty, names a joint the robot does not
            have, holds a value outside the joint's limits, or gives a mimic joint a value its
            leader's does not imply (a mimic joint that agrees is accepted and not planned).
    """
    data = yaml.load(Path(path).read_text(encoding="utf-8"), Loader=YamlLoader) or {}
    goals = {}
    for i, (entry, robot) in enumerate(zip(_list(data, "robots", str(path)), scene.robots)):
        if isinstance(entry, Mapping) and entry.get("goal") is not None:
            where = f"{path}: robots[{i}]{_label(entry)}.goal"
            q = _read_joints(entry["goal"], robot.model, where, robot.configuration)
            planned = [joint for joint in entry["goal"] if joint in robot.model.joint_names]  # mimic joints follow
            if not planned:
                raise SceneError(f"{where}: empty; name the planned joints and their goal values (rad or m), "
                                 f"joints: {', '.join(robot.model.joint_names)}")
            goals[robot.name] = {joint: float(q[robot.model.joint_index(joint)]) for joint in planned}
    return goals


def save_scene(scene: Scene, path: str | os.PathLike) -> None:
    """Write ``scene`` as a YAML scene file, atomically (temp file in the same folder + rename).

    Robot model files and meshes are written relative to the new file's folder. Base and body
    poses are written as position + rpy; robot joints only where they differ from neutral.

    Raises:
        SceneError: a robot has no reference (bundled name or model file) to write.
    """
    path = Path(path)
    atomic_write_text(path, yaml.dump(scene_to_dict(scene, path.parent), Dumper=_FlowListDumper, sort_keys=False))


def scene_to_dict(scene: Scene, base_dir: Path) -> dict:
    """The YAML mapping of ``scene`` with file paths relative to ``base_dir``."""
    out: dict[str, Any] = {"version": FORMAT_VERSION}
    if scene.robots:
        out["robots"] = [_write_robot(robot, base_dir) for robot in scene.robots]
    for key, bodies in (("obstacles", scene.obstacles), ("objects", scene.objects)):
        if bodies:
            out[key] = [_write_body(body, base_dir) for body in bodies]
    return out


def load_robot_reference(reference: str, base_dir: Path, where: str) -> RobotModel:
    """Load a robot named in a scene: a bundled name or a model file relative to ``base_dir``.

    Raises:
        SceneError: unknown bundled name (lists the bundled robots), missing file, or a model
            that fails to load (the loader's message is kept).
    """
    from prehensile import robots as bundled  # the bundled-robot registry (model layer data)

    if not isinstance(reference, str) or not reference:
        raise SceneError(f"{where}.robot: expected a bundled robot name or a model file path, got {reference!r}")
    looks_like_path = "/" in reference or "\\" in reference or reference.lower().endswith(_MODEL_SUFFIXES)
    try:
        if looks_like_path:
            file = (Path(reference) if Path(reference).is_absolute() else base_dir / reference).resolve()
            if not file.is_file():
                raise SceneError(f"{where}.robot: '{reference}': {missing_file(file, 'model file')} (looked for {file})")
            return bundled.load(str(file))
        available = list(bundled.available())
        if reference not in available:
            raise SceneError(
                f"{where}.robot: unknown robot '{reference}'; bundled robots: {', '.join(available)} "
                "(or give a model file path relative to the scene file)"
            )
        return bundled.load(reference)
    except SceneError:
        raise
    except PrehensileError as err:
        raise SceneError(f"{where}.robot: cannot load '{reference}': {err}") from None


def _read_robot(entry: Any, base_dir: Path, where: str, models: dict[str, RobotModel]) -> PlacedRobot:
    check_keys(entry, ROBOT_KEYS, where, required=("robot",))
    reference = entry["robot"]
    if not isinstance(reference, str) or not reference:
        raise SceneError(f"{where}.robot: expected a bundled robot name or a robot file path, got {reference!r}")
    if reference not in models:
        models[reference] = load_robot_reference(reference, base_dir, where)
    model = models[reference]
    name = entry.get("name", model.name)
    if not isinstance(name, str) or not name:
        raise SceneError(f"{where}.name: expected a non-empty string, got {name!r}")
    q = None
    if entry.get("joints") is not None:
        q = _read_joints(entry["joints"], model, f"{where}.joints")
    return PlacedRobot(name, model, read_pose(entry.get("pose"), where), q, reference)


def _read_joints(values: Any, model: RobotModel, where: str, base: np.ndarray | None = None) -> np.ndarray:
    """q (dof,): ``base`` (default neutral) with the joints of ``values`` set; a mimic joint's
    value must agree with the one its leader gets (it follows it)."""
    if not isinstance(values, Mapping):
        raise SceneError(f"{where}: expected a mapping joint name -> value (rad or m), got {values!r}")
    q = model.neutral_configuration() if base is None else base.copy()
    mimics = {joint: number(value, f"{where}.{joint}") for joint, value in values.items()
              if joint in model.mimic_joints}
    for joint, value in values.items():
        if joint in mimics:
            continue
        if joint not in model.joint_names:
            raise SceneError(
                f"{where}: robot '{model.name}' has no joint '{joint}'; joints: {', '.join(model.joint_names)}"
            )
        index = model.joint_index(joint)
        q[index] = number(value, f"{where}.{joint}")
        lo, hi = model.lower[index], model.upper[index]
        if not lo - 1e-9 <= q[index] <= hi + 1e-9:
            raise SceneError(f"{where}.{joint}: value {q[index]:.6g} outside the limits [{lo:.6g}, {hi:.6g}]")
    check_mimic_values(model, mimics, q, where)
    return q


def _read_body(entry: Any, base_dir: Path, where: str, robots: Mapping[str, RobotModel] | None) -> Body:
    """An obstacle (``robots`` None) or an object, which a robot of ``robots`` (name -> model) may hold."""
    if robots is None and isinstance(entry, Mapping) and "held_by" in entry:
        raise SceneError(f"{where}.held_by: an obstacle cannot be held; list the body under 'objects'")
    check_keys(entry, BODY_KEYS if robots is None else OBJECT_KEYS, where, required=("name",))
    name = entry["name"]
    if not isinstance(name, str) or not name:
        raise SceneError(f"{where}.name: expected a non-empty string, got {name!r}")
    if ("shape" in entry) == ("shapes" in entry):
        raise SceneError(f"{where}: give exactly one of 'shape' (one mapping) or 'shapes' (a list)")
    if "shape" in entry:
        geometries = (read_shape(entry["shape"], base_dir, f"{where}.shape"),)
    else:
        shapes = entry["shapes"]
        if not isinstance(shapes, list) or not shapes:
            raise SceneError(f"{where}.shapes: expected a non-empty list of shapes")
        geometries = tuple(read_shape(s, base_dir, f"{where}.shapes[{i}]") for i, s in enumerate(shapes))
    hold = None if entry.get("held_by") is None else _read_hold(entry["held_by"], robots, f"{where}.held_by")
    return Body(name, geometries, read_pose(entry.get("pose"), where), hold)


def _read_hold(entry: Any, robots: Mapping[str, RobotModel], where: str) -> Hold:
    check_keys(entry, HOLD_KEYS, where, required=("robot", "link"))
    robot = entry["robot"]
    if not isinstance(robot, str) or robot not in robots:
        raise SceneError(f"{where}.robot: no robot {robot!r} in the scene; robots: {', '.join(robots) or '(none)'}")
    model = robots[robot]
    touch = [] if entry.get("touch_links") is None else entry["touch_links"]
    if not isinstance(touch, list):
        raise SceneError(f"{where}.touch_links: expected a list of link names, got {touch!r}")
    hold = Hold(robot, entry["link"], tuple(touch))
    check_hold(model, hold, where)
    return hold


def _write_robot(robot: PlacedRobot, base_dir: Path) -> dict:
    from prehensile.robots import bundled_name

    # a bundled robot loaded any other way (e.g. for a MoveIt scene) is written by name too: its SRDF comes along
    written = robot.reference if robot.reference and _is_bundled_name(robot.reference) else bundled_name(robot.model)
    if written is None:
        if not robot.model.source:
            raise SceneError(f"robot '{robot.name}': no bundled name or model file to write")
        # A file reference was relative to the old scene file: rewrite it from the model's source.
        written = relative_path(Path(robot.model.source), base_dir)
    out: dict[str, Any] = {"name": robot.name, "robot": written, "pose": write_pose(robot.T_world_base)}
    if robot.q is not None:
        neutral = robot.model.neutral_configuration()
        out["joints"] = {
            joint: float(value)
            for joint, value, zero in zip(robot.model.joint_names, robot.q, neutral)
            if value != zero
        }
    return out


def _is_bundled_name(reference: str) -> bool:
    return "/" not in reference and "\\" not in reference and not reference.lower().endswith(_MODEL_SUFFIXES)


def _write_body(body: Body, base_dir: Path) -> dict:
    out: dict[str, Any] = {"name": body.name, "pose": write_pose(body.T_world_body)}
    shapes = [write_shape(g, base_dir) for g in body.geometries]
    if len(shapes) == 1:
        out["shape"] = shapes[0]
    else:
        out["shapes"] = shapes
    if body.held_by is not None:
        hold = body.held_by
        out["held_by"] = {"robot": hold.robot, "link": hold.link, **({"touch_links": list(hold.touch_links)}
                                                                      if hold.touch_links else {})}
    return out


def _list(data: Mapping, key: str, source: str) -> list:
    value = data.get(key)
    if value is None:
        return []
    if not isinstance(value, list):
        raise SceneError(f"{source}: {key}: expected a list, got {type(value).__name__}")
    return value


def _label(entry: Any) -> str:
    if isinstance(entry, Mapping) and isinstance(entry.get("name"), str):
        return f" '{entry['name']}'"
    return ""


def _unique(names: list[str], where: str) -> None:
    seen: set[str] = set()
    for name in names:
        if name in seen:
            raise SceneError(f"{where}: name '{name}' is used twice; names must be unique")
        seen.add(name)


class _FlowListDumper(yaml.SafeDumper):
    """Writes lists of numbers inline (``[0.1, 0.2, 0.3]``), everything else in block style."""


def _represent_list(dumper: yaml.SafeDumper, data: list):
    flow = all(isinstance(v, (int, float)) for v in data)
    return dumper.represent_sequence("tag:yaml.org,2002:seq", data, flow_style=flow)


_FlowListDumper.add_representer(list, _represent_list)


def bundled_scenes() -> list[str]:
    """Names of the scene files shipped with prehensile (``prehensile/scenes/*.yaml``)."""
    from importlib.resources import files

    folder = files("prehensile") / "scenes"
    return sorted(p.name[: -len(".yaml")] for p in folder.iterdir() if p.name.endswith(".yaml"))


def bundled_scene_path(name: str = "demo") -> Path:
    """Path of the bundled scene ``name`` (e.g. "demo").

    Raises:
        SceneError: no bundled scene of that name (lists the available ones).
    """
    from importlib.resources import files

    path = Path(str(files("prehensile") / "scenes" / f"{name}.yaml"))
    if not path.is_file():
        raise SceneError(f"no bundled scene '{name}'; bundled scenes: {', '.join(bundled_scenes()) or '(none)'}")
    return path
