"""Turn loader output (links and joints by name) into a validated :class:`RobotModel`.

Every loader (URDF, MJCF, Simox XML) produces :class:`LinkSpec` and :class:`JointSpec` lists
and calls :func:`build_model`, so tree validation and ordering live in one place.
"""

from __future__ import annotations

import dataclasses
import logging

from dataclasses import dataclass, field
from typing import Iterable

import numpy as np

from prehensile.errors import ModelError
from prehensile.model.geometry import Geometry
from prehensile.model.robot_model import PRISMATIC, REVOLUTE, Chain, EndEffector, RobotModel

JOINT_TYPES = ("revolute", "continuous", "prismatic", "fixed", "planar")

log = logging.getLogger(__name__)


@dataclass
class LinkSpec:
    name: str
    visuals: list[Geometry] = field(default_factory=list)
    collisions: list[Geometry] = field(default_factory=list)


@dataclass
class JointSpec:
    """One joint as read from a file; ``where`` names file and element for error messages.

    Limits are in rad or m (``None`` for unlimited); ``mimic`` is (joint, multiplier, offset).
    A planar joint moves in the plane normal to ``axis``: it becomes two prismatic joints
    ``<name>_x``, ``<name>_y`` and a revolute ``<name>_theta`` about ``axis``.
    """

    name: str
    type: str
    parent: str
    child: str
    T_parent_joint: np.ndarray
    axis: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0]))
    lower: float | None = None
    upper: float | None = None
    velocity: float = np.inf
    mimic: tuple[str, float, float] | None = None
    where: str = ""


def _expand_planar(joint: JointSpec) -> list[JointSpec]:
    normal = joint.axis
    if abs(normal[2]) > 0.9:  # the usual case: motion in the x-y plane
        ax, ay = np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    else:
        ax = np.cross(normal, [0.0, 0.0, 1.0])
        ax /= np.linalg.norm(ax)
        ay = np.cross(normal, ax)
    x_link, y_link = f"{joint.child}__{joint.name}_x", f"{joint.child}__{joint.name}_y"
    common = dict(velocity=joint.velocity, where=joint.where)
    return [
        JointSpec(f"{joint.name}_x", "prismatic", joint.parent, x_link, joint.T_parent_joint, ax, **common),
        JointSpec(f"{joint.name}_y", "prismatic", x_link, y_link, np.eye(4), ay, **common),
        JointSpec(f"{joint.name}_theta", "continuous", y_link, joint.child, np.eye(4), normal, **common),
    ]


def build_model(
    name: str,
    source: str,
    links: Iterable[LinkSpec],
    joints: Iterable[JointSpec],
    chains: Iterable[Chain] = (),
    end_effectors: Iterable[EndEffector] = (),
    disabled_collision_pairs: Iterable[tuple[str, str]] = (),
) -> RobotModel:
    """Validate the tree and build the model.

    Raises:
        ModelError: duplicate names, unknown parent or child links, a link with two parents,
            a cycle, several roots, an unknown joint type, a zero axis, a mimic of an unknown
            joint, or bad limits; the message names ``source`` and the element.
    """
    links = list(links)
    link_specs: dict[str, LinkSpec] = {}
    for link in links:
        if link.name in link_specs:
            raise ModelError(f"{source}: link '{link.name}' is defined twice")
        link_specs[link.name] = link

    expanded: list[JointSpec] = []
    for joint in joints:
        if joint.type not in JOINT_TYPES:
            raise ModelError(
                f"{source}: {joint.where or 'joint ' + repr(joint.name)} has unknown type '{joint.type}'; "
                f"valid types: {', '.join(JOINT_TYPES)}"
            )
        axis = np.asarray(joint.axis, dtype=float)
        if joint.type != "fixed":
            norm = np.linalg.norm(axis)
            if not np.isfinite(norm) or norm < 1e-9:
                raise ModelError(f"{source}: joint '{joint.name}' has a zero or invalid axis {axis.tolist()}")
            joint.axis = axis / norm
        if joint.type == "planar":
            expanded.extend(_expand_planar(joint))
            for extra in expanded[-3:-1]:
                link_specs[extra.child] = LinkSpec(extra.child)
        else:
            expanded.append(joint)

    by_child: dict[str, JointSpec] = {}
    children: dict[str, list[JointSpec]] = {n: [] for n in link_specs}
    joint_names: set[str] = set()
    for joint in expanded:
        if joint.name in joint_names:
            raise ModelError(f"{source}: joint '{joint.name}' is defined twice")
        joint_names.add(joint.name)
        for role, link in (("parent", joint.parent), ("child", joint.child)):
            if link not in link_specs:
                raise ModelError(
                    f"{source}: {joint.where or 'joint ' + repr(joint.name)} names unknown {role} link '{link}'"
                )
        if joint.child in by_child:
            raise ModelError(
                f"{source}: link '{joint.child}' has two parent joints ('{by_child[joint.child].name}' and "
                f"'{joint.name}'); a robot model must be a tree"
            )
        by_child[joint.child] = joint
        children[joint.parent].append(joint)

    roots = [n for n in link_specs if n not in by_child]
    if not link_specs:
        raise ModelError(f"{source}: the robot has no links")
    if not roots:
        raise ModelError(f"{source}: the joints form a cycle (every link has a parent)")
    if len(roots) > 1:
        raise ModelError(f"{source}: several root links ({', '.join(roots)}); the links must form one tree")

    order: list[str] = []
    stack = [roots[0]]
    while stack:
        link = stack.pop()
        order.append(link)
        stack.extend(j.child for j in reversed(children[link]))
    if len(order) != len(link_specs):
        cyclic = sorted(set(link_specs) - set(order))
        raise ModelError(f"{source}: links {', '.join(cyclic)} form a cycle not connected to root '{roots[0]}'")

    actuated = [by_child[n] for n in order[1:] if by_child[n].type != "fixed" and by_child[n].mimic is None]
    q_index = {j.name: i for i, j in enumerate(actuated)}
    for joint in expanded:
        if joint.type == "fixed":
            joint.mimic = None  # a mimic tag on a fixed joint has no effect
        elif joint.mimic is not None and joint.mimic[0] not in q_index:
            raise ModelError(
                f"{source}: joint '{joint.name}' mimics '{joint.mimic[0]}', which is not an actuated joint"
            )

    lower, upper, velocity = [], [], []
    for joint in actuated:
        if joint.type == "continuous":
            lo, hi = -np.inf, np.inf
        else:
            lo = -np.inf if joint.lower is None else float(joint.lower)
            hi = np.inf if joint.upper is None else float(joint.upper)
        if not lo <= hi:
            raise ModelError(f"{source}: joint '{joint.name}' has lower limit {lo} above upper limit {hi}")
        lower.append(lo)
        upper.append(hi)
        velocity.append(float(joint.velocity))

    _warn_mimic_limits(source, expanded, q_index, lower, upper)
    n = len(order)
    link_index = {name: i for i, name in enumerate(order)}
    parent = np.full(n, -1)
    jtype = np.zeros(n, dtype=np.int64)
    origin = np.tile(np.eye(4), (n, 1, 1))
    axis = np.zeros((n, 3))
    qidx = np.full(n, -1)
    mult = np.ones(n)
    offset = np.zeros(n)
    link_joint_names = [""] * n
    for i, link in enumerate(order[1:], start=1):
        joint = by_child[link]
        parent[i] = link_index[joint.parent]
        origin[i] = joint.T_parent_joint
        link_joint_names[i] = joint.name
        if joint.type == "fixed":
            continue
        jtype[i] = PRISMATIC if joint.type == "prismatic" else REVOLUTE
        axis[i] = joint.axis
        if joint.mimic is None:
            qidx[i] = q_index[joint.name]
        else:
            qidx[i] = q_index[joint.mimic[0]]
            mult[i], offset[i] = joint.mimic[1], joint.mimic[2]

    disabled = frozenset(frozenset(pair) for pair in disabled_collision_pairs if pair[0] != pair[1])
    model = RobotModel(
        name=name,
        source=source,
        link_names=tuple(order),
        link_joint_names=tuple(link_joint_names),
        link_parent=parent,
        joint_type=jtype,
        joint_origin=origin,
        joint_axis=axis,
        joint_q_index=qidx,
        joint_multiplier=mult,
        joint_offset=offset,
        joint_names=tuple(j.name for j in actuated),
        lower=np.array(lower),
        upper=np.array(upper),
        velocity_limit=np.array(velocity),
        visuals=tuple(tuple(link_specs[n].visuals) for n in order),
        collisions=tuple(tuple(link_specs[n].collisions) for n in order),
        end_effectors={e.name: e for e in end_effectors},
        disabled_collision_pairs=disabled,
    )
    resolved = {c.name: resolve_chain(model, c) for c in chains}
    return dataclasses.replace(model, chains=resolved)


def resolve_chain(model: RobotModel, chain: Chain, where: str | None = None) -> Chain:
    """Check ``chain`` against the model; an empty ``joint_names`` is filled with the actuated
    joints on the path from ``base_link`` to ``tip_link`` (mimic joints follow their leader).
    ``where`` names the chain's definition in errors (default: the model's file and the chain)."""
    where = where or f"{model.source}: chain '{chain.name}'"
    for link in (chain.base_link, chain.tip_link):
        if link not in model.link_names:
            raise ModelError(f"{where} names unknown link '{link}'; links: {', '.join(model.link_names)}")
    path = model.path_to_root(chain.tip_link)
    base = model.link_index(chain.base_link)
    if base not in path:
        raise ModelError(f"{where}: base link '{chain.base_link}' is not an ancestor of tip '{chain.tip_link}'")
    if chain.joint_names:
        for joint in chain.joint_names:
            model.joint_index(joint)
        return chain
    joints: list[str] = []
    for link in reversed(path[: path.index(base)]):
        q = int(model.joint_q_index[link])
        if q >= 0 and model.joint_names[q] not in joints:
            joints.append(model.joint_names[q])
    return dataclasses.replace(chain, joint_names=tuple(joints))


def _warn_mimic_limits(source: str, joints: Iterable[JointSpec], q_index: dict[str, int], lower: list[float],
                       upper: list[float]) -> None:
    """Warn about each mimic joint whose leader's limits take it past its own: a mimic joint
    is bounded through its leader only (as MoveIt's passive mimic joints are)."""
    for joint in joints:
        if joint.mimic is None or joint.type == "continuous":
            continue
        leader, multiplier, offset = joint.mimic
        ends = sorted(multiplier * x + offset for x in (lower[q_index[leader]], upper[q_index[leader]]))
        lo = -np.inf if joint.lower is None else joint.lower
        hi = np.inf if joint.upper is None else joint.upper
        if ends[0] < lo - 1e-9 or ends[1] > hi + 1e-9:
            log.warning("%s: mimic joint '%s' (limits %g .. %g) reaches %g .. %g within the limits of '%s'; it is "
                        "bounded through '%s' only", source, joint.name, lo, hi, *ends, leader, leader)
