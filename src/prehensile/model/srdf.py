"""SRDF reader: planning groups become chains, end effectors with their group states as
preshapes, and disabled collision pairs.

Like MoveIt, it tolerates two slips common in published SRDFs with a warning: a disabled pair
naming a link the robot lacks is skipped, and a group state's value outside its joint's limits
is clipped into them. Everything else it does not understand is an error.
"""

from __future__ import annotations

import dataclasses
import logging
from pathlib import Path

from prehensile.errors import ModelError
from prehensile.model.builder import resolve_chain
from prehensile.model.robot_model import Chain, EndEffector, RobotModel
from prehensile.model.xml_utils import number, parse_xml, required

log = logging.getLogger(__name__)


def _group_joints(model: RobotModel, groups: dict, name: str, source: str, seen: tuple = ()) -> list[str]:
    if name in seen:
        raise ModelError(f"{source}: group '{name}' contains itself")
    if name not in groups:
        raise ModelError(f"{source}: unknown group '{name}'; groups: {', '.join(groups)}")
    joints: list[str] = []
    for el in groups[name]:
        where = f"{source}: group '{name}' <{el.tag}>"
        if el.tag == "chain":
            joints += _chain(model, name, el, where).joint_names
        elif el.tag == "joint":
            joint = required(el, "name", where)
            if joint in model.joint_names:
                joints.append(joint)
            elif joint not in model.link_joint_names:
                raise ModelError(f"{where}: unknown joint '{joint}'")
        elif el.tag == "group":
            joints += _group_joints(model, groups, required(el, "name", where), source, seen + (name,))
    return list(dict.fromkeys(joints))


def _chain(model: RobotModel, name: str, el, where: str) -> Chain:
    """The chain of group ``name``'s <chain> element ``el``, checked against the model."""
    return resolve_chain(model, Chain(name, required(el, "base_link", where), required(el, "tip_link", where), ()),
                         where)


def _group_chain(model: RobotModel, groups: dict, name: str, source: str, effectors: set[str]) -> Chain | None:
    """A chain for the group: its <chain> if it has one; for a group of subgroups of which all
    but one are end-effector groups (MoveIt's arm-and-hand group), the other one's chain with
    all the group's joints; else the span of its joints, up to the deepest link they move."""
    for el in groups[name]:
        if el.tag == "chain":
            return _chain(model, name, el, f"{source}: group '{name}' <chain>")
    joints = _group_joints(model, groups, name, source)
    if not joints:
        return None
    subgroups = [required(el, "name", f"{source}: group '{name}' <group>") for el in groups[name] if el.tag == "group"]
    arms = [sub for sub in subgroups if sub not in effectors]
    arm = _group_chain(model, groups, arms[0], source, effectors) if subgroups and len(arms) == 1 else None
    if arm is not None:
        return Chain(name, arm.base_link, arm.tip_link, tuple(joints))
    links = [i for i, j in enumerate(model.link_joint_names) if j in joints]
    tip = max(links, key=lambda i: len(model.path_to_root(i)))
    base = model.link_names[int(model.link_parent[min(links, key=lambda i: len(model.path_to_root(i)))])]
    return Chain(name, base, model.link_names[tip], tuple(joints))


def _group_name(groups: dict, name: str, where: str) -> str:
    """``name`` if it is a group of the SRDF; ModelError otherwise."""
    if name not in groups:
        raise ModelError(f"{where}: unknown group '{name}'; groups: {', '.join(groups) or '(none)'}")
    return name


def _state_value(model: RobotModel, joint: str, value: float, where: str) -> float:
    """A group state's value of ``joint``, which must be a joint of the model; an actuated
    one's value is clipped into its limits (with a warning)."""
    if joint not in model.joint_names:
        if joint not in model.link_joint_names:
            raise ModelError(f"{where}: unknown joint '{joint}'; joints: {', '.join(model.joint_names)}")
        return value  # a mimic or fixed joint, as in a group's <joint>: its value follows
    i = model.joint_index(joint)
    if not model.lower[i] - 1e-9 <= value <= model.upper[i] + 1e-9:
        log.warning("%s: joint '%s' = %g is outside its limits [%g, %g], clipped into them", where, joint, value,
                    model.lower[i], model.upper[i])
    return min(max(value, float(model.lower[i])), float(model.upper[i]))


def apply_srdf(model: RobotModel, path: str | Path) -> RobotModel:
    """Return ``model`` with the chains, end effectors and disabled pairs of the SRDF at ``path``."""
    path = Path(path)
    root = parse_xml(path)
    source = str(path)
    groups = {required(g, "name", f"{source}: <group>"): list(g) for g in root.findall("group")}
    chains = dict(model.chains)
    effectors = {el.get("group") for el in root.findall("end_effector")}
    for name in groups:
        chain = _group_chain(model, groups, name, source, effectors)
        if chain is not None:
            chains[name] = chain

    states: dict[str, dict[str, dict[str, float]]] = {}
    for el in root.findall("group_state"):
        where = f"{source}: group_state '{el.get('name')}'"
        values = {required(j, "name", where): number(j, "value", where) for j in el.findall("joint")}
        values = {joint: _state_value(model, joint, value, where) for joint, value in values.items()}
        states.setdefault(_group_name(groups, required(el, "group", where), where), {})[
            required(el, "name", where)] = values

    end_effectors = dict(model.end_effectors)
    for el in root.findall("end_effector"):
        where = f"{source}: end_effector '{el.get('name')}'"
        name = required(el, "name", where)
        parent_link = required(el, "parent_link", where)
        # tcp_link / gcp_link are prehensile's additions to the SRDF element (MoveIt ignores them)
        tcp_link = el.get("tcp_link", parent_link)
        for link in (parent_link, tcp_link, el.get("gcp_link", tcp_link)):
            if link not in model.link_names:
                raise ModelError(f"{where} names unknown link '{link}'")
        group = _group_name(groups, required(el, "group", where), where)
        parent_group = el.get("parent_group", "")
        if parent_group:
            _group_name(groups, parent_group, where)
        end_effectors[name] = EndEffector(
            name=name,
            base_link=parent_link,
            tcp_link=tcp_link,
            gcp_link=el.get("gcp_link", tcp_link),
            finger_joints=tuple(_group_joints(model, groups, group, source)),
            preshapes=states.get(group, {}),
            chain=parent_group,
        )

    disabled = set(model.disabled_collision_pairs)
    for el in root.findall("disable_collisions"):
        where = f"{source}: disable_collisions"
        a, b = required(el, "link1", where), required(el, "link2", where)
        unknown = [link for link in (a, b) if link not in model.link_names]
        if unknown:
            log.warning("%s of %s and %s skipped: robot '%s' has no link '%s'", where, a, b, model.name, unknown[0])
        elif a != b:
            disabled.add(frozenset((a, b)))
    return dataclasses.replace(
        model, chains=chains, end_effectors=end_effectors, disabled_collision_pairs=frozenset(disabled),
        srdf_source=source,
    )
