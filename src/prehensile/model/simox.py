"""Loader for Simox (VirtualRobot) robot XML files, converted to SI units.

Semantics follow VirtualRobot's ``RobotIO`` / ``BaseIO`` (tags and attributes match
case-insensitively; node names such as ``"Hip Pitch"`` are kept, and a node's link and joint
share its name):

* A ``<RobotNode>`` is a link plus the joint moving it: ``T_parent_node = T_transform @
  motion(axis, q + offset)``, i.e. the ``<Transform>`` comes first and the axis is expressed in
  the transformed frame. ``<Transform>`` children multiply left to right: ``DH`` (standard,
  ``Rz(theta) Tz(d) Tx(a) Rx(alpha)``; rad and mm by default), ``Translation`` (mm unless
  ``units="m"``), ``RollPitchYaw``/``rpy`` (``Rz(yaw) Ry(pitch) Rx(roll)``, rad by default),
  ``Quaternion`` (x y z w), ``Matrix3x3`` and ``Matrix4x4`` (``rowI`` / ``cJ``; mm).
* ``<Joint type="revolute|prismatic|fixed">`` (none: fixed). A revolute joint without
  ``<Axis>`` turns about z; a prismatic one needs ``<TranslationDirection>``. ``<Limits>``
  without a unit are rad or mm; without ``<Limits>`` Simox uses -pi..pi in those units;
  ``limitless="true"`` gives a continuous joint. ``offset`` is folded into the joint origin;
  ``<PropagateJointValue name factor>`` makes the named joint a mimic of this one.
* ``<ChildFromRobot><File>`` loads another robot file (relative to the including file): its
  root node becomes a child of the node, and its node sets and end effectors are imported.
* ``<RobotNodeSet>`` -> :class:`Chain` (base ``kinematicRoot``, default the robot root; tip
  ``tcp``, default the last node; joints: the listed actuated nodes). ``<Endeffector>`` ->
  :class:`EndEffector` (preshapes in rad / m, finger joints: actuated ``<Actor>`` nodes).
  ``<Physics><IgnoreCollision>`` -> disabled collision pairs.

Geometry: Open Inventor (``.iv``) files, which most Simox models use, cannot be read and are
skipped (logged at debug level). Readable meshes (stl, obj, off, ply, wrl, dae, glb, gltf)
become :class:`Mesh` with scale 0.001 (Simox geometry is in mm); a missing one is a
:class:`ModelError`. ``meshes=False`` skips all geometry.
"""

from __future__ import annotations

import logging
import xml.etree.ElementTree as ET
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from prehensile.errors import ModelError
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.model.geometry import Geometry, Mesh
from prehensile.model.robot_model import Chain, EndEffector, RobotModel
from prehensile.model.xml_utils import parse_xml
from prehensile.spatial import axis_angle_to_matrix, quaternion_to_matrix, rpy_to_matrix

log = logging.getLogger(__name__)

MESH_FORMATS = ("stl", "obj", "off", "ply", "wrl", "dae", "glb", "gltf")
JOINT_TYPES = ("revolute", "prismatic", "fixed")
NODE_TAGS = ("transform", "joint", "visualization", "collisionmodel", "physics", "child",
             "childfromrobot", "sensor")
JOINT_TAGS = ("limits", "axis", "translationdirection", "maxvelocity", "maxacceleration",
              "maxtorque", "propagatejointvalue", "scalevisualization")
LENGTH = {"mm": 1e-3, "millimeter": 1e-3, "cm": 1e-2, "centimeter": 1e-2, "m": 1.0, "meter": 1.0}
ANGLE = {"radian": 1.0, "rad": 1.0, "radians": 1.0, "degree": np.pi / 180, "deg": np.pi / 180,
         "degrees": np.pi / 180}
TIME = {"sec": 1.0, "s": 1.0, "second": 1.0, "seconds": 1.0, "min": 60.0, "minute": 60.0,
        "minutes": 60.0, "h": 3600.0, "hour": 3600.0, "hours": 3600.0}
WEIGHT = {"kg": 1.0, "kilogram": 1.0, "g": 1e-3, "gram": 1e-3, "t": 1e3, "ton": 1e3}
UNIT_ATTRS = ("unit", "units", "unitslength", "unitsangle", "unitstime", "unitsweight")


@dataclass
class _Node:
    name: str
    where: str
    T: np.ndarray
    jtype: str = "fixed"
    axis: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    lower: float | None = None
    upper: float | None = None
    velocity: float = np.inf
    children: list[str] = field(default_factory=list)
    propagate: list[tuple[str, float]] = field(default_factory=list)
    link: LinkSpec | None = None


@dataclass
class _Robot:
    nodes: dict[str, _Node] = field(default_factory=dict)
    sets: list[tuple[ET.Element, str]] = field(default_factory=list)
    eefs: list[tuple[ET.Element, str]] = field(default_factory=list)
    ignore: list[tuple[str, str, str]] = field(default_factory=list)
    name: str = ""


def _tag(el: ET.Element) -> str:
    return el.tag.lower() if isinstance(el.tag, str) else ""


def _elements(el: ET.Element, *tags: str) -> list[ET.Element]:
    return [c for c in el if _tag(c) in tags]


def _attr(el: ET.Element, name: str, default: str | None = None) -> str | None:
    for key, value in el.attrib.items():
        if key.lower() == name:
            return value
    return default


def _float(el: ET.Element, name: str, where: str, default: float | None = None) -> float:
    text = _attr(el, name)
    if text is None:
        if default is None:
            raise ModelError(f"{where}: <{el.tag}> is missing attribute '{name}'")
        return default
    try:
        value = float(text)
    except ValueError:
        raise ModelError(f"{where}: <{el.tag}> attribute '{name}'='{text}' is not a number") from None
    if not np.isfinite(value):
        raise ModelError(f"{where}: <{el.tag}> attribute '{name}' is not finite")
    return value


def _units(el: ET.Element, where: str) -> dict[str, float]:
    """Unit factors to SI found on ``el``, keyed by kind: length, angle, time, weight."""
    found: dict[str, float] = {}
    for key, text in el.attrib.items():
        if key.lower() not in UNIT_ATTRS:
            continue
        value = text.strip().lower()
        for kind, table in (("length", LENGTH), ("angle", ANGLE), ("time", TIME), ("weight", WEIGHT)):
            if value in table:
                found[kind] = table[value]
                break
        else:
            valid = ", ".join(list(LENGTH) + list(ANGLE) + list(TIME) + list(WEIGHT))
            raise ModelError(f"{where}: <{el.tag}> has unknown unit '{text}'; valid units: {valid}")
    return found


def _rows(el: ET.Element, n: int, where: str) -> np.ndarray:
    M = np.eye(n)
    for i in range(n):
        for row in _elements(el, f"row{i + 1}"):
            M[i] = [_float(row, f"c{j + 1}", where) for j in range(n)]
    return M


def _transform(el: ET.Element, where: str) -> np.ndarray:
    """Pose (4, 4) in m of a ``<Transform>``; its children are applied left to right."""
    T = np.eye(4)
    for child in el:
        tag, local = _tag(child), np.eye(4)
        units = _units(child, where)
        length, angle = units.get("length", 1e-3), units.get("angle", 1.0)
        if tag == "dh":
            theta, alpha = (_float(child, k, where, 0.0) * angle for k in ("theta", "alpha"))
            a, d = (_float(child, k, where, 0.0) * length for k in ("a", "d"))
            ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
            local = np.array([[ct, -st * ca, st * sa, a * ct], [st, ct * ca, -ct * sa, a * st],
                              [0.0, sa, ca, d], [0.0, 0.0, 0.0, 1.0]])
        elif tag in ("translation", "trans"):
            local[:3, 3] = [_float(child, k, where) * length for k in "xyz"]
        elif tag in ("rollpitchyaw", "rpy"):
            local[:3, :3] = rpy_to_matrix([_float(child, k, where) * angle for k in ("roll", "pitch", "yaw")])
        elif tag in ("quaternion", "quat"):
            local[:3, :3] = quaternion_to_matrix([_float(child, k, where) for k in "wxyz"])
        elif tag == "matrix3x3":
            local[:3, :3] = _rows(child, 3, where)
        elif tag == "matrix4x4":
            local = _rows(child, 4, where)
            local[:3, 3] *= length
        elif isinstance(child.tag, str):
            raise ModelError(f"{where}: unknown <Transform> element <{child.tag}>; valid: DH, Translation, "
                             "RollPitchYaw (rpy), Quaternion, Matrix3x3, Matrix4x4")
        T = T @ local
    return T


def _joint(node: _Node, el: ET.Element, where: str) -> None:
    jtype = (_attr(el, "type") or "fixed").strip().lower()
    if jtype not in JOINT_TYPES:
        raise ModelError(f"{where}: unknown joint type '{jtype}'; valid types: {', '.join(JOINT_TYPES)}")
    node.jtype = jtype
    if jtype == "fixed":
        return
    unit = 1.0 if jtype == "revolute" else 1e-3  # Simox values: rad or mm
    limits = (-np.pi * unit, np.pi * unit)
    direction = None
    for child in el:
        tag = _tag(child)
        units = _units(child, where)
        if tag == "limits":
            scale = units.get("angle", units.get("length", unit))
            lo = _float(child, "lo", where, -np.pi if unit == 1.0 else -1000.0)
            hi = _float(child, "hi", where, np.pi if unit == 1.0 else 1000.0)
            limits = (lo * scale, hi * scale)
            if (_attr(child, "limitless", "false") or "").lower() in ("true", "1", "yes"):
                limits = (None, None)
        elif tag == "axis" and jtype == "revolute" or tag == "translationdirection" and jtype == "prismatic":
            direction = np.array([_float(child, k, where) for k in "xyz"])
        elif tag == "maxvelocity":
            value = _float(child, "value", where)
            factor = units.get("length", 1.0) * units.get("angle", 1.0) / units.get("time", 1.0)
            node.velocity = np.inf if value < 0 else value * factor
        elif tag == "propagatejointvalue":
            name = _attr(child, "name")
            if not name:
                raise ModelError(f"{where}: <PropagateJointValue> is missing attribute 'name'")
            node.propagate.append((name, _float(child, "factor", where, 1.0)))
        elif tag == "dh":
            raise ModelError(f"{where}: <DH> inside <Joint> is deprecated in Simox and not supported; "
                             "put it in the node's <Transform>")
        elif isinstance(child.tag, str) and tag not in JOINT_TAGS:
            raise ModelError(f"{where}: unknown <Joint> element <{child.tag}>; valid: {', '.join(JOINT_TAGS)}")
    if jtype == "prismatic" and direction is None:
        raise ModelError(f"{where}: prismatic joint needs <TranslationDirection x y z>")
    if direction is not None:
        if not np.linalg.norm(direction) > 1e-9:
            raise ModelError(f"{where}: joint axis {direction.tolist()} is zero")
        node.axis = direction / np.linalg.norm(direction)
    node.lower, node.upper = limits
    offset = _float(el, "offset", where, 0.0) * unit
    if offset:
        motion = np.eye(4)
        if jtype == "revolute":
            motion[:3, :3] = axis_angle_to_matrix(node.axis, offset)
        else:
            motion[:3, 3] = node.axis * offset
        node.T = node.T @ motion


def _geometry(node: _Node, el: ET.Element, base_dir: Path, where: str, meshes: bool) -> list[Geometry]:
    if (_attr(el, "enable", "true") or "").lower() in ("false", "0", "no") or not meshes:
        return []
    out = []
    for file_el in _elements(el, "file"):
        text = (file_el.text or "").strip()
        if not text:
            raise ModelError(f"{where}: empty <File> in <{el.tag}>")
        suffix = Path(text).suffix.lower().lstrip(".")
        if suffix not in MESH_FORMATS:
            log.debug("%s: skipping <%s> file '%s' (format '%s' not readable)", where, el.tag, text, suffix)
            continue
        path = Path(text) if Path(text).is_absolute() else base_dir / text
        if not path.is_file():
            raise ModelError(f"{where}: mesh file '{text}' of <{el.tag}> not found (looked for {path})")
        out.append(Geometry(Mesh(path, (1e-3, 1e-3, 1e-3)), np.eye(4), node.name))
    return out


def _read(path: Path, robot: _Robot, stack: tuple[Path, ...], meshes: bool) -> str:
    """Read the robot file at ``path`` into ``robot``; returns the name of its root node."""
    path = path.resolve()
    if path in stack:
        raise ModelError(f"{stack[-1]}: <ChildFromRobot> includes '{path}' recursively")
    root = parse_xml(path)
    source = str(path)
    if _tag(root) != "robot":
        raise ModelError(f"{source}: root element is <{root.tag}>, expected <Robot>")
    root_name = _attr(root, "rootnode")
    robot.name = robot.name or _attr(root, "type") or ""
    if not root_name:
        raise ModelError(f"{source}: <Robot> is missing attribute 'RootNode'")
    local: dict[str, _Node] = {}
    includes: list[tuple[str, str]] = []
    for el in root:
        tag = _tag(el)
        if tag == "robotnodeset":
            robot.sets.append((el, source))
        elif tag == "endeffector":
            robot.eefs.append((el, source))
        elif tag == "robotnode":
            name = _attr(el, "name")
            if not name:
                raise ModelError(f"{source}: <RobotNode> without a 'name' attribute")
            where = f"{source}: RobotNode '{name}'"
            if name in robot.nodes or name in local:
                raise ModelError(f"{where}: a node of this name is already defined")
            node = _Node(name, where, np.eye(4), link=LinkSpec(name))
            for child in _elements(el, "transform"):  # before <Joint>, which may fold in an offset
                node.T = _transform(child, where)
            for child in el:
                ctag = _tag(child)
                if ctag == "joint":
                    _joint(node, child, where)
                elif ctag == "child":
                    child_name = _attr(child, "name")
                    if not child_name:
                        raise ModelError(f"{where}: <Child> is missing attribute 'name'")
                    node.children.append(child_name)
                elif ctag == "childfromrobot":
                    files = _elements(child, "file")
                    if not files:
                        raise ModelError(f"{where}: <ChildFromRobot> has no <File>")
                    includes += [(name, (f.text or "").strip()) for f in files]
                elif ctag in ("visualization", "collisionmodel"):
                    target = node.link.visuals if ctag == "visualization" else node.link.collisions
                    target += _geometry(node, child, path.parent, where, meshes)
                elif ctag == "physics":
                    for ignore in _elements(child, "ignorecollision"):
                        robot.ignore.append((name, _attr(ignore, "name") or "", where))
                elif isinstance(child.tag, str) and ctag not in NODE_TAGS:
                    raise ModelError(f"{where}: unknown element <{child.tag}>; valid: {', '.join(NODE_TAGS)}")
            local[name] = node
        elif isinstance(el.tag, str):
            raise ModelError(f"{source}: unknown element <{el.tag}> in <Robot>; valid: RobotNode, "
                             "RobotNodeSet, Endeffector")
    for node in local.values():
        for child in node.children:
            if child not in local:
                raise ModelError(f"{node.where}: unknown child node '{child}'; nodes in this file: "
                                 f"{', '.join(local)}")
    if root_name not in local:
        raise ModelError(f"{source}: RootNode '{root_name}' is not a RobotNode of this file")
    robot.nodes.update(local)
    for parent, text in includes:
        include = Path(text) if Path(text).is_absolute() else path.parent / text
        if not include.is_file():
            raise ModelError(f"{local[parent].where}: <ChildFromRobot> file '{text}' not found "
                             f"(looked for {include})")
        local[parent].children.append(_read(include, robot, stack + (path,), meshes))
    return root_name


def _check_tree(robot: _Robot, root: str) -> None:
    parent_of: dict[str, str] = {}
    for node in robot.nodes.values():
        for child in node.children:
            if child == root or child in parent_of:
                other = root if child == root else parent_of[child]
                kind = "is the root node" if child == root else f"already has parent '{other}'"
                raise ModelError(f"{node.where}: child '{child}' {kind}; the nodes must form a tree (cycle?)")
            parent_of[child] = node.name
    missing = sorted(set(robot.nodes) - set(parent_of) - {root})
    if missing:
        where = robot.nodes[missing[0]].where
        raise ModelError(f"{where}: node is not connected to root node '{root}' (unreached: {', '.join(missing)})")


def _chains(robot: _Robot, root: str, actuated: set[str]) -> list[Chain]:
    chains = []
    for el, source in robot.sets:
        name = _attr(el, "name")
        where = f"{source}: RobotNodeSet '{name}'"
        if not name:
            raise ModelError(f"{source}: <RobotNodeSet> without a 'name' attribute")
        nodes = [_attr(n, "name") or "" for n in _elements(el, "node")]
        for n in nodes + [_attr(el, "kinematicroot") or root, _attr(el, "tcp") or root]:
            if n not in robot.nodes:
                raise ModelError(f"{where}: unknown node '{n}'")
        tip = _attr(el, "tcp") or (nodes[-1] if nodes else root)
        joints = tuple(n for n in nodes if n in actuated)
        chains.append(Chain(name, _attr(el, "kinematicroot") or root, tip, joints))
    return chains


def _end_effectors(robot: _Robot, actuated: set[str]) -> list[EndEffector]:
    eefs = []
    for el, source in robot.eefs:
        name = _attr(el, "name")
        where = f"{source}: Endeffector '{name}'"
        links = {k: _attr(el, k) for k in ("base", "tcp", "gcp")}
        for key in ("base", "tcp"):
            if not links[key]:
                raise ModelError(f"{where}: missing attribute '{key}'")
        for link in filter(None, links.values()):
            if link not in robot.nodes:
                raise ModelError(f"{where}: unknown node '{link}'")
        preshapes = {}
        for pre in _elements(el, "preshape"):
            values = {}
            for n in _elements(pre, "node"):
                joint = _attr(n, "name") or ""
                if joint not in robot.nodes or robot.nodes[joint].jtype == "fixed":
                    raise ModelError(f"{where}: preshape '{_attr(pre, 'name')}' names unknown joint '{joint}'")
                units = _units(n, where)
                default = 1.0 if robot.nodes[joint].jtype == "revolute" else 1e-3
                values[joint] = _float(n, "value", where) * units.get("angle", units.get("length", default))
            preshapes[_attr(pre, "name") or f"preshape{len(preshapes)}"] = values
        fingers = [_attr(n, "name") for a in _elements(el, "actor") for n in _elements(a, "node")]
        eefs.append(EndEffector(name or links["tcp"], links["base"], links["tcp"], links["gcp"] or links["tcp"],
                                tuple(f for f in fingers if f in actuated), preshapes))
    return eefs


def load_simox(path: str | Path, meshes: bool = True) -> RobotModel:
    """Load a Simox robot XML file (and the files it includes) as a :class:`RobotModel`.

    Args:
        path: the robot file.
        meshes: attach readable mesh files as geometry (``.iv`` files are always skipped).

    Raises:
        ModelError: malformed XML, unknown elements, joint types or units, unknown or
            cyclic child references, missing included or mesh files; the message names the
            file and the RobotNode.
    """
    path = Path(path)
    source = str(path.resolve())
    robot = _Robot()
    root = _read(path, robot, (), meshes)
    _check_tree(robot, root)
    mimics = {}
    for node in robot.nodes.values():
        for target, factor in node.propagate:
            if target not in robot.nodes or robot.nodes[target].jtype == "fixed":
                raise ModelError(f"{node.where}: <PropagateJointValue> names unknown joint '{target}'")
            mimics[target] = (node.name, factor, 0.0)
    links = [node.link for node in robot.nodes.values()]
    joints = []
    root_node = robot.nodes[root]
    base = root
    if root_node.jtype != "fixed" or not np.allclose(root_node.T, np.eye(4), atol=0.0):
        base = "simox_world"  # the root node itself moves or is offset: give it a fixed parent
        links.append(LinkSpec(base))
    parent_of = {c: p.name for p in robot.nodes.values() for c in p.children}
    if base != root:
        parent_of[root] = base
    for node in robot.nodes.values():
        parent = parent_of.get(node.name)
        if parent is None:
            continue
        jtype = "continuous" if node.jtype == "revolute" and node.lower is None else node.jtype
        joints.append(JointSpec(node.name, jtype, parent, node.name, node.T, node.axis, node.lower,
                                node.upper, node.velocity, mimics.get(node.name), f"RobotNode '{node.name}'"))
    actuated = {n.name for n in robot.nodes.values() if n.jtype != "fixed" and n.name not in mimics}
    disabled = []
    for a, b, where in robot.ignore:  # as Simox, which keeps the names unchecked: a part file may name its parent's
        if b in robot.nodes:
            disabled.append((a, b))
        else:
            log.warning("%s: <IgnoreCollision> names node '%s', which this file does not have; ignored", where, b)
    return build_model(robot.name or path.stem, source, links, joints, _chains(robot, root, actuated),
                       _end_effectors(robot, actuated), disabled)
