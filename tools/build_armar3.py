"""Build the bundled ARMAR-III URDF and SRDF from the published Simox XML model.

Usage::

    python tools/build_armar3.py [SIMOX_DIR]   # default /work/shared/assets/armar3-simox

Reads ``ArmarIII_withPlatformJoints.xml`` with :func:`prehensile.model.simox.load_simox` and
writes ``src/prehensile/robots/armar3/armar3.urdf`` and ``armar3.srdf`` (atomically). The
output is deterministic: running the script twice gives identical files.

Choices (see also ``src/prehensile/robots/armar3/README.md``):

* Names: Simox node names with spaces replaced by underscores (``"Hip Pitch"`` ->
  ``Hip_Pitch``); a node's link and joint share that name.
* 43 DoF: platform x, y (prismatic, +-10 m) and yaw (revolute, +-2 pi); hip 3; arms 2 x 7;
  hands 2 x 8 (thumb 2, index 2, middle 2, ring 1, pinky 1: ring and pinky J1 mimic their
  J0 with multiplier 1); head 7 (neck pitch, roll, yaw, head tilt; common eye tilt
  ``Cameras``; two eye pans). The Simox "Hand Palm 2" joint (a palm flexion the real hand
  does not actuate separately), the jaw, the four eye lids and the virtual gaze joint are
  fixed at 0; their frames are kept as links.
* Collision and visual geometry: primitives authored here (boxes, cylinders, spheres; a
  capsule is written as a cylinder with two end spheres because urdfdom cannot parse
  ``<capsule>``), placed at the home configuration in world coordinates and moved into
  the link frames.
"""

from __future__ import annotations

import sys

import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.robot_model import FIXED, PRISMATIC
from prehensile.model.simox import load_simox
from prehensile.spatial import matrix_to_rpy
from prehensile.storage import atomic_write_text

ROOT = Path(__file__).resolve().parents[1]
OUT = ROOT / "src" / "prehensile" / "robots" / "armar3"
DEFAULT_SIMOX = Path("/work/shared/assets/armar3-simox")

FIXED_NODES = {"Jaw", "VirtualCentralGaze", "Hand Palm 2 L", "Hand Palm 2 R"} | {
    f"Lid {s} {p}" for s in ("Left", "Right") for p in ("Bottom", "Top")}
MIMIC = {f"{f} {s} J1": f"{f} {s} J0" for f in ("Ring", "Pinky") for s in "LR"}
LIMITS = {"X_Platform": (-10.0, 10.0, 1.0), "Y_Platform": (-10.0, 10.0, 1.0),
          "Yaw_Platform": (-2 * np.pi, 2 * np.pi, 1.0)}
# pairs whose primitives touch or lie a few millimetres apart by design (their covering balls
# overlap at rest): co-located joints, eyes in the head, shoulder balls against the torso box,
# neighbouring fingers, forearm and wrist flange
TOUCHING = [("Neck_1_Pitch", "Neck_3_Yaw"), ("Eye_Left", "Head_Tilt"), ("Eye_Right", "Head_Tilt")] + [
    pair for side in "LR" for pair in (("Hip_Yaw", f"Shoulder_2_{side}"), (f"Pinky_{side}_J0", f"Ring_{side}_J0"),
                                       (f"Ring_{side}_J0", f"Middle_{side}_J0"), (f"Underarm_{side}", f"Wrist_2_{side}"))]

def safe(name: str) -> str:
    """URDF-safe name of a Simox node: spaces become underscores."""
    return name.replace(" ", "_")

def _fmt(values) -> str:
    return " ".join("0" if abs(v) < 1e-14 else repr(float(v)) for v in np.ravel(values))

def _pose(center, z_dir=None) -> np.ndarray:
    """World pose with origin ``center`` and z axis along ``z_dir`` (default world z)."""
    T = np.eye(4)
    T[:3, 3] = center
    if z_dir is not None:
        z = np.asarray(z_dir, float) / np.linalg.norm(z_dir)
        helper = np.array([1.0, 0, 0]) if abs(z[0]) < 0.9 else np.array([0, 1.0, 0])
        x = np.cross(helper, z)
        x /= np.linalg.norm(x)
        T[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    return T

def _capsule(p0, p1, r) -> list:
    p0, p1 = np.asarray(p0, float), np.asarray(p1, float)
    return [("cylinder", (r, np.linalg.norm(p1 - p0)), _pose((p0 + p1) / 2, p1 - p0)),
            ("sphere", (r,), _pose(p0)), ("sphere", (r,), _pose(p1))]

def _box(center, size, z_dir=None) -> list:
    return [("box", tuple(size), _pose(center, z_dir))]

def _shapes_world(pos, R) -> dict[str, list]:
    """Primitive shapes per Simox node in world coordinates at the home pose.

    ``pos[name]`` (3,) and ``R[name]`` (3, 3) are the home poses of the Simox nodes.
    """
    s = {
        "Platform": [("cylinder", (0.35, 0.34), _pose([0, 0.05, 0.17]))]
        + _box([0, 0.08, 0.585], [0.44, 0.36, 0.49]),
        "Hip Pitch": _box(pos["Hip Pitch"] - [0, 0, 0.02], [0.20, 0.14, 0.05]),
        "Hip Roll": [("cylinder", (0.045, 0.14), _pose(pos["Hip Roll"] + [0, 0, 0.015], [0, 1, 0]))],
        "Hip Yaw": _box([0, 0.12, 1.195], [0.34, 0.24, 0.51]),
        "Neck_1_Pitch": [("cylinder", (0.04, 0.04), _pose(pos["Neck_1_Pitch"] - [0, 0, 0.01]))],
        "Neck_3_Yaw": _capsule(pos["Neck_3_Yaw"] + [0, 0, 0.015], pos["Head_Tilt"] - [0, 0, 0.02], 0.03),
        "Head_Tilt": _box(pos["Head Center"] + [0, 0.02, 0.015], [0.20, 0.17, 0.15]),
    }
    for side in ("L", "R"):
        eye = "Eye_Left" if side == "L" else "Eye_Right"
        s[eye] = [("sphere", (0.018,), _pose(pos[eye] + [0, 0.005, 0]))]
        S, E = pos[f"Shoulder 1 {side}"], pos[f"Elbow {side}"]
        W, U = pos[f"Wrist 1 {side}"], pos[f"Underarm {side}"]
        d_upper = (E - S) / np.linalg.norm(E - S)
        d_fore = (W - U) / np.linalg.norm(W - U)
        s[f"Shoulder 1 {side}"] = [("sphere", (0.06,), _pose(S))]
        s[f"Shoulder 2 {side}"] = [("sphere", (0.05,), _pose(S + d_upper * 0.03))]
        s[f"Upperarm {side}"] = _capsule(S + d_upper * 0.10, E - d_upper * 0.075, 0.045)
        s[f"Elbow {side}"] = [("sphere", (0.05,), _pose(E))]
        s[f"Underarm {side}"] = _capsule(U + d_fore * 0.085, W - d_fore * 0.07, 0.04)
        s[f"Wrist 1 {side}"] = [("sphere", (0.035,), _pose(W))]
        s[f"Wrist 2 {side}"] = [("cylinder", (0.04, 0.02), _pose(W + d_fore * 0.01, d_fore))]
        # hand: geometry in the palm / finger frames (palm normal along -x, fingers along +z)
        P1 = f"Hand Palm 1 {side}"
        Rp, pp = R[P1], pos[P1]
        ys = -1.0 if side == "L" else 1.0  # the fingers lie along -y (left) or +y (right) of the palm
        s[P1] = [("box", (0.03, 0.092, 0.066), _local(Rp, pp, [-0.006, ys * 0.023, 0.028]))]
        s[f"Thumb {side}"] = [("box", (0.03, 0.028, 0.028), _local(R[f"Thumb {side}"], pos[f"Thumb {side}"], [0.017, 0, 0]))]
        for finger in ("Pinky", "Ring", "Middle", "Index"):
            for j, (r, length) in enumerate(((0.0095, 0.04), (0.0085, 0.03))):
                n = f"{finger} {side} J{j}"
                a = pos[n] + R[n][:, 2] * (r + 0.002)
                b = pos[n] + R[n][:, 2] * (length - r - 0.002)
                s[n] = _capsule(a, b, r)
        for j, (r, length) in enumerate(((0.011, 0.04), (0.0095, 0.032))):
            n = f"Thumb {side} J{j}"
            a = pos[n] - R[n][:, 0] * (r + 0.002)
            b = pos[n] - R[n][:, 0] * (length - r - 0.002)
            s[n] = _capsule(a, b, r)
    return s

def _local(R, p, offset) -> np.ndarray:
    T = np.eye(4)
    T[:3, :3] = R
    T[:3, 3] = p + R @ np.asarray(offset, float)
    return T

def _geometry_xml(parent: ET.Element, kind: str, shape: str, params, T_link: np.ndarray) -> None:
    el = ET.SubElement(parent, kind)
    ET.SubElement(el, "origin", xyz=_fmt(T_link[:3, 3]), rpy=_fmt(matrix_to_rpy(T_link[:3, :3])))
    geometry = ET.SubElement(el, "geometry")
    if shape == "box":
        ET.SubElement(geometry, "box", size=_fmt(params))
    elif shape == "sphere":
        ET.SubElement(geometry, "sphere", radius=_fmt(params))
    else:
        ET.SubElement(geometry, "cylinder", radius=_fmt(params[:1]), length=_fmt(params[1:]))
    if kind == "visual":
        ET.SubElement(el, "material", name="armar3_grey")

def build_urdf(model) -> tuple[ET.Element, dict[str, list]]:
    """The URDF tree and the shapes (in link frames) per URDF link."""
    home = forward_kinematics(model, np.zeros(model.dof))
    pos = {n: home[i, :3, 3] for i, n in enumerate(model.link_names)}
    rot = {n: home[i, :3, :3] for i, n in enumerate(model.link_names)}
    world = _shapes_world(pos, rot)
    robot = ET.Element("robot", name="armar3")
    material = ET.SubElement(robot, "material", name="armar3_grey")
    ET.SubElement(material, "color", rgba="0.75 0.75 0.78 1")
    shapes: dict[str, list] = {}
    for i, name in enumerate(model.link_names):
        link = ET.SubElement(robot, "link", name=safe(name))
        T_link_world = np.linalg.inv(home[i])
        shapes[safe(name)] = [(shape, params, T_link_world @ T) for shape, params, T in world.get(name, [])]
        for kind in ("visual", "collision"):
            for shape, params, T in shapes[safe(name)]:
                _geometry_xml(link, kind, shape, params, T)
    for i, name in enumerate(model.link_names[1:], start=1):
        q_index, parent = int(model.joint_q_index[i]), model.link_names[model.link_parent[i]]
        actuated = model.joint_type[i] != FIXED and name not in FIXED_NODES
        jtype = "fixed" if not actuated else ("prismatic" if model.joint_type[i] == PRISMATIC else "revolute")
        joint = ET.SubElement(robot, "joint", name=safe(name), type=jtype)
        T = model.joint_origin[i]
        ET.SubElement(joint, "origin", xyz=_fmt(T[:3, 3]), rpy=_fmt(matrix_to_rpy(T[:3, :3])))
        ET.SubElement(joint, "parent", link=safe(parent))
        ET.SubElement(joint, "child", link=safe(name))
        if not actuated:
            continue
        ET.SubElement(joint, "axis", xyz=_fmt(model.joint_axis[i]))
        lo, hi, vel = LIMITS.get(name, (model.lower[q_index], model.upper[q_index], model.velocity_limit[q_index]))
        ET.SubElement(joint, "limit", lower=_fmt([lo]), upper=_fmt([hi]), effort="100",
                      velocity=_fmt([vel if np.isfinite(vel) else 1.0]))
        if name in MIMIC:
            ET.SubElement(joint, "mimic", joint=safe(MIMIC[name]), multiplier="1", offset="0")
    return robot, shapes

def _rigid_groups(model) -> dict[str, str]:
    """Each URDF link -> the URDF link heading its rigid body (links joined by fixed joints)."""
    head: dict[str, str] = {}
    for i, name in enumerate(model.link_names):
        fixed = model.joint_type[i] == FIXED or name in FIXED_NODES
        parent = model.link_parent[i]
        head[safe(name)] = head[safe(model.link_names[parent])] if i > 0 and fixed else safe(name)
    return head

def disabled_pairs(model, shapes: dict[str, list]) -> list[tuple[str, str, str]]:
    """(link1, link2, reason) for links with geometry: rigidly attached or adjacent bodies,
    Simox IgnoreCollision pairs and pairs touching by design."""
    head = _rigid_groups(model)
    parent_head = {}
    for i, name in enumerate(model.link_names[1:], start=1):
        if head[safe(name)] == safe(name):
            parent_head[safe(name)] = head[safe(model.link_names[model.link_parent[i]])]
    ignore = {frozenset(map(safe, p)) for p in model.disabled_collision_pairs} | {frozenset(p) for p in TOUCHING}
    links = [safe(n) for n in model.link_names if shapes[safe(n)]]
    out = []
    for a_i, a in enumerate(links):
        for b in links[a_i + 1:]:
            ha, hb = head[a], head[b]
            if ha == hb or parent_head.get(ha) == hb or parent_head.get(hb) == ha:
                out.append((a, b, "Adjacent"))
            elif frozenset((a, b)) in ignore:
                out.append((a, b, "User"))
    return out

def build_srdf(model, pairs) -> ET.Element:
    robot = ET.Element("robot", name="armar3")

    def group(name, chain=None, joints=()):
        el = ET.SubElement(robot, "group", name=name)
        if chain:
            ET.SubElement(el, "chain", base_link=safe(chain[0]), tip_link=safe(chain[1]))
        for j in joints:
            ET.SubElement(el, "joint", name=safe(j))

    arm = ["Shoulder 1 {}", "Shoulder 2 {}", "Upperarm {}", "Elbow {}", "Underarm {}", "Wrist 1 {}", "Wrist 2 {}"]
    group("Platform", ("Armar3_Base", "Platform"))
    group("Torso", ("Platform", "Hip Yaw"))
    for side, word in (("L", "Left"), ("R", "Right")):
        group(f"{word}Arm", (f"{word} Arm Base", f"TCP {side}"))
        group(f"Torso{word}Arm", ("Platform", f"TCP {side}"))
        group(f"PlatformYawTorso{word}Arm", ("Y_Platform", f"TCP {side}"))
    group("TorsoBothArms", joints=["Hip Pitch", "Hip Roll", "Hip Yaw"] + [a.format(s) for s in "LR" for a in arm])
    group("Neck", ("Head Base", "Head_Tilt"))
    group("Head", joints=["Neck_1_Pitch", "Neck_2_Roll", "Neck_3_Yaw", "Head_Tilt", "Cameras", "Eye_Left", "Eye_Right"])
    group("IKVirtualGaze", ("Head Base", "VirtualCentralGaze"))
    for eef in sorted(model.end_effectors.values(), key=lambda e: e.name):
        side = eef.name[-1]
        word = "Left" if side == "L" else "Right"
        fingers = [j for j in eef.finger_joints if j not in MIMIC and j not in FIXED_NODES]
        group(f"{word}Hand", joints=fingers)
        for pre_name, values in sorted(eef.preshapes.items()):
            state = ET.SubElement(robot, "group_state", name=safe(pre_name), group=f"{word}Hand")
            for j in fingers:
                ET.SubElement(state, "joint", name=safe(j), value=_fmt([values.get(j, 0.0)]))
        ET.SubElement(robot, "end_effector", name=safe(eef.name), parent_link=safe(eef.base_link),
                      group=f"{word}Hand", parent_group=f"{word}Arm", tcp_link=safe(eef.tcp_link),
                      gcp_link=safe(eef.gcp_link))
    for a, b, reason in pairs:
        ET.SubElement(robot, "disable_collisions", link1=a, link2=b, reason=reason)
    return robot

HEADER = ("ARMAR-III, generated by tools/build_armar3.py from the Simox model "
          "(H2T, KIT; LGPL-2.1). Do not edit by hand.")

def render(simox_dir: Path) -> dict[str, str]:
    """File name -> text of the URDF and SRDF built from the Simox files in ``simox_dir``."""
    model = load_simox(Path(simox_dir) / "ArmarIII_withPlatformJoints.xml", meshes=False)
    urdf, shapes = build_urdf(model)
    srdf = build_srdf(model, disabled_pairs(model, shapes))
    out = {}
    for name, tree in (("armar3.urdf", urdf), ("armar3.srdf", srdf)):
        ET.indent(tree, space="  ")
        out[name] = f'<?xml version="1.0"?>\n<!-- {HEADER} -->\n' + ET.tostring(tree, encoding="unicode") + "\n"
    return out

def main(argv: list[str]) -> int:
    simox_dir = Path(argv[1]) if len(argv) > 1 else DEFAULT_SIMOX
    for name, text in render(simox_dir).items():
        atomic_write_text(OUT / name, text)
    return 0

if __name__ == "__main__":
    sys.exit(main(sys.argv))
