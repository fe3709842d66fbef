"""Reading and writing the pieces of a scene file: numbers, poses and shapes.

Every reader takes ``where``, a prefix such as ``"demo.yaml: obstacles[2] 'shelf'"`` that
starts each :class:`~prehensile.errors.SceneError` message, so an error names the file and the
entry. Writers produce plain Python values (lists, dicts, floats) for YAML.

Pose mapping (all keys optional)::

    position: [x, y, z]          # m, default [0, 0, 0]
    rpy: [roll, pitch, yaw]      # rad, R = Rz(yaw) Ry(pitch) Rx(roll) (URDF convention)
    quaternion: [w, x, y, z]     # unit quaternion, scalar first; give rpy or quaternion, not both

Shape mapping (``type`` plus the fields of that type, sizes in m, all > 0)::

    {type: box, size: [x, y, z]}                  # full side lengths
    {type: sphere, radius: r}
    {type: cylinder, radius: r, length: l}        # axis along z, centred
    {type: capsule, radius: r, length: l}         # l = length of the cylindrical part (0: a ball)
    {type: mesh, file: path, scale: s or [sx, sy, sz]}   # path relative to the scene file; scale
                                                         # factors non-zero, a negative one mirrors
    pose: {...}                                   # optional: shape pose in the body frame
    name: "..."                                   # optional
"""

from __future__ import annotations

import difflib
import math
import os
import re
from pathlib import Path
from typing import Any, Mapping

import numpy as np
import yaml

from prehensile.errors import ModelError, SceneError
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Shape, Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.spatial import make_pose, matrix_to_rpy, quaternion_to_matrix, rpy_to_matrix

SHAPE_TYPES = ("box", "sphere", "cylinder", "capsule", "mesh")
POSE_KEYS = ("position", "rpy", "quaternion")
_SHAPE_FIELDS = {
    "box": ("size",),
    "sphere": ("radius",),
    "cylinder": ("radius", "length"),
    "capsule": ("radius", "length"),
    "mesh": ("file", "scale"),
}
_QUATERNION_TOLERANCE = 1e-3
MIMIC_TOLERANCE = 1e-6  # rad or m: how far a mimic joint's given value may be from the one it follows


def check_keys(entry: Any, allowed: tuple[str, ...], where: str, required: tuple[str, ...] = ()) -> Mapping:
    """``entry`` must be a mapping whose keys are among ``allowed`` and include ``required``.

    Raises:
        SceneError: not a mapping, an unknown key (with the closest valid key as a hint and the
            list of valid keys) or a missing required key.
    """
    if not isinstance(entry, Mapping):
        raise SceneError(f"{where}: expected a mapping with keys {', '.join(allowed)}, got {_show(entry)}")
    for key in entry:
        if key not in allowed:
            close = difflib.get_close_matches(str(key), allowed, n=1)
            hint = f" (did you mean '{close[0]}'?)" if close else ""
            raise SceneError(f"{where}: unknown key '{key}'{hint}; valid keys: {', '.join(allowed)}")
    for key in required:
        if key not in entry:
            raise SceneError(f"{where}: missing key '{key}'")
    return entry


class YamlLoader(getattr(yaml, "CSafeLoader", yaml.SafeLoader)):
    """PyYAML's safe loader (the C one where built) that reads exponents without a decimal
    point, ``1e-05`` as Python and JSON write them, as numbers (YAML 1.2) instead of strings."""


YamlLoader.add_implicit_resolver("tag:yaml.org,2002:float", re.compile(r"^[-+]?(?:\d+\.?\d*|\.\d+)[eE][-+]?\d+$"),
                                 list("-+0123456789."))


def number(value: Any, where: str, positive: bool = False) -> float:
    """A finite float (> 0 if ``positive``); YAML booleans and strings are rejected."""
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise SceneError(f"{where}: expected a number, got {_show(value)}")
    result = float(value)
    if not math.isfinite(result):
        raise SceneError(f"{where}: must be finite, got {result}")
    if positive and not result > 0:
        raise SceneError(f"{where}: must be positive, got {result}")
    return result


def check_mimic_values(model: RobotModel, values: Mapping[str, float], q: np.ndarray, where: str) -> None:
    """Raise SceneError naming ``where`` unless each mimic joint of ``values`` (name -> rad or m)
    agrees within :data:`MIMIC_TOLERANCE` with the value the joint it follows has in q (dof,)."""
    for joint, value in values.items():
        leader, multiplier, offset = model.mimic_joints[joint]
        follows = multiplier * q[leader] + offset
        if abs(value - follows) > MIMIC_TOLERANCE:
            raise SceneError(f"{where}: mimic joint '{joint}' = {value:.6g} disagrees with the joint it follows: "
                             f"{multiplier:g} * {model.joint_names[leader]} + {offset:g} = {follows:.6g}")


def numbers(value: Any, count: int, where: str, positive: bool = False) -> np.ndarray:
    """Exactly ``count`` finite numbers as a float64 array of shape (count,)."""
    if not isinstance(value, (list, tuple)) or len(value) != count:
        raise SceneError(f"{where}: expected a list of {count} numbers, got {_show(value)}")
    return np.array([number(v, f"{where}[{i}]", positive) for i, v in enumerate(value)], dtype=float)


def read_pose(entry: Any, where: str) -> np.ndarray:
    """A pose mapping (see module docstring) as a (4, 4) transform; None gives identity."""
    if entry is None:
        return np.eye(4)
    where = f"{where}: pose"
    check_keys(entry, POSE_KEYS, where)
    position = numbers(entry["position"], 3, f"{where}.position") if "position" in entry else np.zeros(3)
    if "rpy" in entry and "quaternion" in entry:
        raise SceneError(f"{where}: give either 'rpy' or 'quaternion', not both")
    if "quaternion" in entry:
        quat = numbers(entry["quaternion"], 4, f"{where}.quaternion (w, x, y, z)")
        norm = float(np.linalg.norm(quat))
        if abs(norm - 1.0) > _QUATERNION_TOLERANCE:
            raise SceneError(
                f"{where}.quaternion: not a rotation: (w, x, y, z) = {quat.tolist()} has norm {norm:.6g}, "
                "expected a unit quaternion"
            )
        rotation = quaternion_to_matrix(quat)
    elif "rpy" in entry:
        rotation = rpy_to_matrix(numbers(entry["rpy"], 3, f"{where}.rpy"))
    else:
        rotation = np.eye(3)
    return make_pose(rotation, position)


def write_pose(T: np.ndarray) -> dict:
    """A (4, 4) transform as ``{position, rpy}`` (m, rad) with plain floats."""
    T = np.asarray(T, dtype=float)
    return {"position": _floats(T[:3, 3]), "rpy": _floats(matrix_to_rpy(T[:3, :3]))}


def read_shape(entry: Any, base_dir: Path, where: str) -> Geometry:
    """A shape mapping (see module docstring) as a :class:`Geometry` in the body frame.

    Args:
        entry: the parsed YAML mapping.
        base_dir: folder of the scene file; mesh paths are relative to it.
        where: error-message prefix naming the file and entry.
    """
    if not isinstance(entry, Mapping) or "type" not in entry:
        raise SceneError(f"{where}: expected a mapping with 'type' (one of {', '.join(SHAPE_TYPES)}), got {_show(entry)}")
    kind = entry["type"]
    if kind not in SHAPE_TYPES:
        raise SceneError(f"{where}: unknown shape type '{kind}'; valid types: {', '.join(SHAPE_TYPES)}")
    fields = _SHAPE_FIELDS[kind]
    required = tuple(f for f in fields if f != "scale")
    check_keys(entry, ("type", *fields, "pose", "name"), f"{where} ({kind})", required)
    w = f"{where} ({kind})"
    shape: Shape
    if kind == "box":
        shape = Box(tuple(float(s) for s in numbers(entry["size"], 3, f"{w}.size", positive=True)))
    elif kind == "sphere":
        shape = Sphere(number(entry["radius"], f"{w}.radius", positive=True))
    elif kind in ("cylinder", "capsule"):
        radius = number(entry["radius"], f"{w}.radius", positive=True)
        length = number(entry["length"], f"{w}.length", positive=kind == "cylinder")
        if length < 0:  # a capsule of length 0 is a ball
            raise SceneError(f"{w}.length: must be >= 0, got {length}")
        shape = Cylinder(radius, length) if kind == "cylinder" else Capsule(radius, length)
    else:
        shape = _read_mesh(entry, base_dir, w)
    name = entry.get("name", "")
    if not isinstance(name, str):
        raise SceneError(f"{w}.name: expected a string, got {_show(name)}")
    return Geometry(shape, read_pose(entry.get("pose"), w), name)


def _read_mesh(entry: Mapping, base_dir: Path, where: str) -> Mesh:
    file = entry["file"]
    if not isinstance(file, str) or not file:
        raise SceneError(f"{where}.file: expected a file path, got {_show(file)}")
    path = Path(file) if Path(file).is_absolute() else base_dir / file
    if not path.is_file():
        raise SceneError(f"{where}.file: mesh file '{file}' not found (looked for {path})")
    scale = entry.get("scale", 1.0)
    if isinstance(scale, (list, tuple)):
        scale3 = numbers(scale, 3, f"{where}.scale")
    else:
        scale3 = np.full(3, number(scale, f"{where}.scale"))
    if not np.all(scale3 != 0.0):  # as in URDF: a negative factor mirrors, zero flattens the mesh
        raise SceneError(f"{where}.scale: every factor must be non-zero (a negative one mirrors), got {_show(scale)}")
    mesh = Mesh(path.resolve(), tuple(float(s) for s in scale3))
    try:
        mesh.trimesh  # read now (it is kept), so that a file without triangles names its entry
    except ModelError as error:
        raise SceneError(f"{where}.file: {error}") from None
    return mesh


def write_shape(geometry: Geometry, base_dir: Path) -> dict:
    """A :class:`Geometry` as a shape mapping; mesh paths relative to ``base_dir`` if possible."""
    shape = geometry.shape
    out: dict[str, Any]
    if isinstance(shape, Box):
        out = {"type": "box", "size": _floats(shape.size)}
    elif isinstance(shape, Sphere):
        out = {"type": "sphere", "radius": float(shape.radius)}
    elif isinstance(shape, (Cylinder, Capsule)):
        kind = "cylinder" if isinstance(shape, Cylinder) else "capsule"
        out = {"type": kind, "radius": float(shape.radius), "length": float(shape.length)}
    elif isinstance(shape, Mesh):
        if shape.path is None:
            raise SceneError(f"shape '{geometry.name}': an in-memory mesh has no file to write; export it first")
        out = {"type": "mesh", "file": relative_path(Path(shape.path), base_dir), "scale": _floats(shape.scale)}
    else:
        raise SceneError(f"cannot write shape of type {type(shape).__name__}; valid: {', '.join(SHAPE_TYPES)}")
    if geometry.name:
        out["name"] = geometry.name
    if not np.allclose(geometry.T_link_geom, np.eye(4)):
        out["pose"] = write_pose(geometry.T_link_geom)
    return out


def relative_path(path: Path, base_dir: Path) -> str:
    """``path`` relative to ``base_dir`` (POSIX separators), or absolute if on another drive."""
    try:
        return Path(os.path.relpath(Path(path).resolve(), Path(base_dir).resolve())).as_posix()
    except ValueError:
        return Path(path).resolve().as_posix()


def _floats(values) -> list[float]:
    return [float(v) for v in np.asarray(values, dtype=float).ravel()]


def _show(value: Any) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."
