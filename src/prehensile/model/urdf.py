"""URDF loader (standard library XML parser), with optional SRDF.

Reads links with visual and collision geometry (box, sphere, cylinder, capsule of length >= 0
(0: a ball), mesh with scale (a negative factor mirrors)), joints (revolute, continuous,
prismatic, fixed, planar; mimic), limits. Floating joints are rejected: place a free-flying
robot with a scene base pose instead.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from prehensile.errors import ModelError
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.resources import resolve_uri
from prehensile.model.robot_model import RobotModel
from prehensile.model.xml_utils import floats, number, parse_xml, required
from prehensile.spatial import make_pose, rpy_to_matrix

log = logging.getLogger(__name__)


def _origin(element: ET.Element | None, where: str) -> np.ndarray:
    if element is None:
        return np.eye(4)
    xyz = floats(element.get("xyz"), 3, f"{where} <origin xyz>", [0.0, 0.0, 0.0])
    rpy = floats(element.get("rpy"), 3, f"{where} <origin rpy>", [0.0, 0.0, 0.0])
    return make_pose(rpy_to_matrix(rpy), xyz)


def _size(value: float, where: str, zero: bool = False) -> float:
    """``value`` (m) if finite and > 0 (>= 0 with ``zero``); ModelError naming ``where`` otherwise."""
    if not ((value >= 0 if zero else value > 0) and value < np.inf):
        raise ModelError(f"{where}: must be {'>= 0' if zero else 'positive'} and finite, got {value}")
    return value


def _geometry(element: ET.Element, base_dir: Path, where: str, visual: bool = False) -> Geometry | None:
    """The shape of a <visual> or <collision> element; None for a visual whose mesh file is
    missing (with a warning: only pictures use visuals)."""
    geometry = element.find("geometry")
    if geometry is None or len(geometry) == 0:
        raise ModelError(f"{where}: missing <geometry>")
    shape_el = geometry[0]
    tag = shape_el.tag
    w = f"{where} <{tag}>"
    if tag == "box":
        size = floats(shape_el.get("size"), 3, w)
        shape = Box(tuple(_size(float(s), w) for s in size))
    elif tag == "sphere":
        shape = Sphere(_size(number(shape_el, "radius", w), w))
    elif tag in ("cylinder", "capsule"):
        radius = _size(number(shape_el, "radius", w), w)
        length = _size(number(shape_el, "length", w), f"{w} length", zero=tag == "capsule")  # 0: a ball
        shape = Cylinder(radius, length) if tag == "cylinder" else Capsule(radius, length)
    elif tag == "mesh":
        try:
            path = resolve_uri(required(shape_el, "filename", w), base_dir, w)
        except ModelError as error:
            if not visual:
                raise
            log.warning("%s; the visual is left out", error)
            return None
        scale = floats(shape_el.get("scale"), 3, f"{w} scale", [1.0, 1.0, 1.0])
        if not np.all(np.asarray(scale) != 0.0):  # negative mirrors; zero flattens the mesh
            raise ModelError(f"{w} scale: every factor must be non-zero, got {' '.join(map(str, scale))}")
        shape = Mesh(path, tuple(float(s) for s in scale))
    else:
        raise ModelError(f"{w}: unknown geometry; valid: box, sphere, cylinder, capsule, mesh")
    return Geometry(shape, _origin(element.find("origin"), where), element.get("name", ""))


def _link(element: ET.Element, base_dir: Path, source: str) -> LinkSpec:
    name = required(element, "name", f"{source}: <link>")
    where = f"{source}: link '{name}'"
    link = LinkSpec(name)
    for kind, target in (("visual", link.visuals), ("collision", link.collisions)):
        for i, el in enumerate(element.findall(kind)):
            geometry = _geometry(el, base_dir, f"{where} <{kind}> #{i}", visual=kind == "visual")
            if geometry is not None:
                target.append(geometry)
    return link


def _joint(element: ET.Element, source: str) -> JointSpec:
    name = required(element, "name", f"{source}: <joint>")
    where = f"{source}: joint '{name}'"
    jtype = required(element, "type", where)
    if jtype == "floating":
        raise ModelError(f"{where}: floating joints are not supported; give the base pose in the scene instead")
    parent = element.find("parent")
    child = element.find("child")
    if parent is None or child is None:
        raise ModelError(f"{where}: needs <parent link=...> and <child link=...>")
    axis_el = element.find("axis")
    axis = floats(None if axis_el is None else axis_el.get("xyz"), 3, f"{where} <axis>", [1.0, 0.0, 0.0])
    spec = JointSpec(
        name=name,
        type=jtype,
        parent=required(parent, "link", f"{where} <parent>"),
        child=required(child, "link", f"{where} <child>"),
        T_parent_joint=_origin(element.find("origin"), where),
        axis=axis,
        where=f"joint '{name}'",
    )
    limit = element.find("limit")
    if limit is not None:
        spec.velocity = number(limit, "velocity", f"{where} <limit>", np.inf)
        if not spec.velocity >= 0:
            raise ModelError(f"{where} <limit>: velocity must be >= 0 (rad/s or m/s), got {spec.velocity}")
        if jtype in ("revolute", "prismatic"):
            spec.lower = number(limit, "lower", f"{where} <limit>", 0.0)
            spec.upper = number(limit, "upper", f"{where} <limit>", 0.0)
    elif jtype in ("revolute", "prismatic"):
        raise ModelError(f"{where}: a {jtype} joint needs a <limit> element")
    mimic = element.find("mimic")
    if mimic is not None:
        spec.mimic = (
            required(mimic, "joint", f"{where} <mimic>"),
            number(mimic, "multiplier", f"{where} <mimic>", 1.0),
            number(mimic, "offset", f"{where} <mimic>", 0.0),
        )
    return spec


def load_urdf(path: str | Path, srdf: str | Path | None = None) -> RobotModel:
    """Load a URDF file, and its SRDF if given (groups, end effectors, disabled collisions).

    Raises:
        ModelError: malformed XML, missing meshes, unknown joint types or links, cycles.
    """
    path = Path(path)
    root = parse_xml(path)
    source = str(path)
    if root.tag != "robot":
        raise ModelError(f"{source}: root element is <{root.tag}>, expected <robot>")
    links = [_link(el, path.parent, source) for el in root.findall("link")]
    joints = [_joint(el, source) for el in root.findall("joint")]
    name = root.get("name", path.stem)
    model = build_model(name, source, links, joints)
    if srdf is not None:
        from prehensile.model.srdf import apply_srdf

        model = apply_srdf(model, srdf)
    return model
