"""Write the bundled NAO V5 (H25) model: ``src/prehensile/robots/nao/nao.urdf`` and ``nao.srdf``.

Usage::

    .venv/bin/python tools/build_nao.py [--out DIR]

Kinematics follow the URDF-style transform sequence of the Bischoff digest §1.6 with the
official H25 V4/V5 link lengths and joint limits of §1.7 (converted mm -> m). All joint frames
are aligned with the torso frame at the zero pose (+x forward, +y left, +z up), exactly as in
the ROS ``naoV50`` URDF, so the right side is the y-mirror of the left.

Choices the digest leaves open (documented here and in the generated files):

* **RHipYawPitch** is a ``<mimic>`` of LHipYawPitch (multiplier 1): the two share one motor.
  With the axes (0, 1/√2, -1/√2) left and (0, 1/√2, 1/√2) right, equal angles give a
  mirror-symmetric pelvis. The model thus has 25 DoF on 26 joint names.
* **Hand** (``LHand``/``RHand``, 0 = closed, 1 = open, as in NAOqi): the three tendon-driven
  fingers are lumped into one finger link hinged at the knuckle about -y of the wrist frame.
  The joint value is the finger's opening angle in rad, so 1 (open) leaves the finger straight
  along the hand and 0 (closed) curls it 1 rad (57°) towards the palm (-z).
* **FootHeight** is 45.11 mm (V5 URDF / Kofinas) rather than the doc's 45.19 mm.
* The 4-DoF arm chains of the thesis end at ``l_arm_tip``/``r_arm_tip``, a frame fixed to the
  forearm at the hand point with WristYaw = 0: (LowerArmLength + HandOffsetX, 0, -HandOffsetZ).
  The 5-DoF chains end at ``l_gripper``/``r_gripper``, the same point behind WristYaw.
  The URDF's RHand z of -12.13 mm is treated as the typo it is (-12.31 mm on both sides).
* Velocity limits (rad/s) are the motor maxima of the ROS naoV50 URDF; they are not in the
  digest and only bound time parameterisation.
* Collision geometry uses cylinders capped by spheres (pinocchio's URDF parser rejects
  ``<capsule>``), boxes and spheres sized like the 0.574 m tall robot. Collisions are
  disabled between links joined by a joint, where links without geometry (the small
  intermediate links of two-axis joints) are merged into their parent first.
"""

from __future__ import annotations

import argparse
import math

from pathlib import Path

from prehensile.storage import atomic_write_text

MM = 1e-3
# §1.7 link lengths (mm)
NECK_OFFSET_Z = 126.50
SHOULDER_OFFSET_Y, SHOULDER_OFFSET_Z = 98.00, 100.00
ELBOW_OFFSET_Y, UPPER_ARM_LENGTH, LOWER_ARM_LENGTH = 15.00, 105.00, 55.95
HAND_OFFSET_X, HAND_OFFSET_Z = 57.75, 12.31
HIP_OFFSET_Y, HIP_OFFSET_Z = 50.00, 85.00
THIGH_LENGTH, TIBIA_LENGTH, FOOT_HEIGHT = 100.00, 102.90, 45.11
CAMERA_TOP = ((58.71, 0.0, 63.64), 0.0209)
CAMERA_BOTTOM = ((50.71, 0.0, 17.74), 0.6929)
KNUCKLE = (68.0, 0.0, -12.31)  # finger hinge in the wrist frame (mm), just past the hand point

# §1.7 limits (rad), left side; the right side mirrors the roll/yaw ones. (lower, upper, velocity)
LIMITS = {
    "HeadYaw": (-2.0857, 2.0857, 8.26797),
    "HeadPitch": (-0.6720, 0.5149, 7.19407),
    "LShoulderPitch": (-2.0857, 2.0857, 8.26797),
    "LShoulderRoll": (-0.3142, 1.3265, 7.19407),
    "LElbowYaw": (-2.0857, 2.0857, 8.26797),
    "LElbowRoll": (-1.5446, -0.0349, 7.19407),
    "LWristYaw": (-1.8238, 1.8238, 24.6229),
    "LHand": (0.0, 1.0, 8.33),
    "LHipYawPitch": (-1.14529, 0.740718, 4.16174),
    "LHipRoll": (-0.379435, 0.79046, 4.16174),
    "LHipPitch": (-1.53589, 0.48398, 6.40239),
    "LKneePitch": (-0.0923279, 2.11255, 6.40239),
    "LAnklePitch": (-1.18944, 0.922581, 6.40239),
    "LAnkleRoll": (-0.397761, 0.768992, 4.16174),
    "RShoulderPitch": (-2.0857, 2.0857, 8.26797),
    "RShoulderRoll": (-1.3265, 0.3142, 7.19407),
    "RElbowYaw": (-2.0857, 2.0857, 8.26797),
    "RElbowRoll": (0.0349, 1.5446, 7.19407),
    "RWristYaw": (-1.8238, 1.8238, 24.6229),
    "RHand": (0.0, 1.0, 8.33),
    "RHipRoll": (-0.79046, 0.379435, 4.16174),
    "RHipPitch": (-1.53589, 0.48398, 6.40239),
    "RKneePitch": (-0.0923279, 2.11255, 6.40239),
    "RAnklePitch": (-1.1863, 0.932006, 6.40239),
    "RAnkleRoll": (-0.768992, 0.397761, 4.16174),
}

X, Y, Z = (1.0, 0.0, 0.0), (0.0, 1.0, 0.0), (0.0, 0.0, 1.0)
R2 = 1.0 / math.sqrt(2.0)

def _fmt(values) -> str:
    return " ".join(f"{float(v) + 0.0:.10g}" for v in values)

def _mm(xyz) -> tuple[float, ...]:
    return tuple(v * MM for v in xyz)

def _joint(name, jtype, parent, child, xyz_mm=(0, 0, 0), rpy=(0, 0, 0), axis=None, mimic=None):
    return dict(name=name, type=jtype, parent=parent, child=child, xyz=_mm(xyz_mm), rpy=rpy,
                axis=axis, mimic=mimic)

def _kinematics() -> tuple[list[str], list[dict]]:
    """Links and joints of §1.6, parents first."""
    links = ["torso", "Neck", "Head", "CameraTop_frame", "CameraBottom_frame",
             "CameraTop_optical_frame", "CameraBottom_optical_frame"]
    joints = [
        _joint("HeadYaw", "revolute", "torso", "Neck", (0, 0, NECK_OFFSET_Z), axis=Z),
        _joint("HeadPitch", "revolute", "Neck", "Head", axis=Y),
        _joint("CameraTop_joint", "fixed", "Head", "CameraTop_frame", CAMERA_TOP[0], (0, CAMERA_TOP[1], 0)),
        _joint("CameraBottom_joint", "fixed", "Head", "CameraBottom_frame", CAMERA_BOTTOM[0],
               (0, CAMERA_BOTTOM[1], 0)),
        # optical frames: z along the view direction, x to the image right (ROS REP 103)
        _joint("CameraTop_optical_joint", "fixed", "CameraTop_frame", "CameraTop_optical_frame",
               rpy=(-math.pi / 2, 0, -math.pi / 2)),
        _joint("CameraBottom_optical_joint", "fixed", "CameraBottom_frame", "CameraBottom_optical_frame",
               rpy=(-math.pi / 2, 0, -math.pi / 2)),
    ]
    for side, s in (("L", 1.0), ("R", -1.0)):
        low = side.lower()
        arm = [f"{side}Shoulder", f"{side}Bicep", f"{side}Elbow", f"{side}ForeArm", f"{low}_wrist",
               f"{low}_gripper", f"{low}_arm_tip", f"{low}_finger"]
        links += arm
        joints += [
            _joint(f"{side}ShoulderPitch", "revolute", "torso", arm[0], (0, s * SHOULDER_OFFSET_Y, SHOULDER_OFFSET_Z),
                   axis=Y),
            _joint(f"{side}ShoulderRoll", "revolute", arm[0], arm[1], axis=Z),
            _joint(f"{side}ElbowYaw", "revolute", arm[1], arm[2], (UPPER_ARM_LENGTH, s * ELBOW_OFFSET_Y, 0), axis=X),
            _joint(f"{side}ElbowRoll", "revolute", arm[2], arm[3], axis=Z),
            _joint(f"{side}WristYaw", "revolute", arm[3], arm[4], (LOWER_ARM_LENGTH, 0, 0), axis=X),
            _joint(f"{side}Hand_tcp_joint", "fixed", arm[4], arm[5], (HAND_OFFSET_X, 0, -HAND_OFFSET_Z)),
            _joint(f"{side}Arm_tip_joint", "fixed", arm[3], arm[6],
                   (LOWER_ARM_LENGTH + HAND_OFFSET_X, 0, -HAND_OFFSET_Z)),
            _joint(f"{side}Hand", "revolute", arm[4], arm[7], KNUCKLE, axis=(0.0, -1.0, 0.0)),
        ]
    for side, s in (("L", 1.0), ("R", -1.0)):
        low = side.lower()
        leg = [f"{side}Pelvis", f"{side}Hip", f"{side}Thigh", f"{side}Tibia", f"{side}AnklePitch",
               f"{low}_ankle", f"{low}_sole"]
        links += leg
        mimic = None if side == "L" else "LHipYawPitch"
        joints += [
            _joint(f"{side}HipYawPitch", "revolute", "torso", leg[0], (0, s * HIP_OFFSET_Y, -HIP_OFFSET_Z),
                   axis=(0.0, R2, -s * R2), mimic=mimic),
            _joint(f"{side}HipRoll", "revolute", leg[0], leg[1], axis=X),
            _joint(f"{side}HipPitch", "revolute", leg[1], leg[2], axis=Y),
            _joint(f"{side}KneePitch", "revolute", leg[2], leg[3], (0, 0, -THIGH_LENGTH), axis=Y),
            _joint(f"{side}AnklePitch", "revolute", leg[3], leg[4], (0, 0, -TIBIA_LENGTH), axis=Y),
            _joint(f"{side}AnkleRoll", "revolute", leg[4], leg[5], axis=X),
            _joint(f"{side}Sole_joint", "fixed", leg[5], leg[6], (0, 0, -FOOT_HEIGHT)),
        ]
    return links, joints

def _capsule(a_mm, b_mm, radius_mm) -> list[tuple]:
    """A capsule between points a and b (mm, along one axis) as cylinder + two spheres."""
    a, b = _mm(a_mm), _mm(b_mm)
    d = [bi - ai for ai, bi in zip(a, b)]
    length = math.sqrt(sum(v * v for v in d))
    centre = tuple((ai + bi) / 2 for ai, bi in zip(a, b))
    axis = max(range(3), key=lambda i: abs(d[i]))
    rpy = {0: (0.0, math.pi / 2, 0.0), 1: (math.pi / 2, 0.0, 0.0), 2: (0.0, 0.0, 0.0)}[axis]
    r = radius_mm * MM
    return [("cylinder", centre, rpy, (r, length)), ("sphere", a, (0, 0, 0), (r,)), ("sphere", b, (0, 0, 0), (r,))]

def _collision() -> dict[str, list[tuple]]:
    """Primitive collision shapes per link: (kind, xyz m, rpy, params m)."""
    shapes: dict[str, list[tuple]] = {
        "torso": [("box", _mm((-5, 0, 22.5)), (0, 0, 0), _mm((100, 150, 175)))],
        "Head": [("sphere", _mm((0, 0, 55)), (0, 0, 0), _mm((60,)))],
    }
    finger_dir = (math.cos(1.0), 0.0, -math.sin(1.0))  # straight when LHand = 1 (open)
    finger_centre = tuple(20.0 * c for c in finger_dir)
    for side, s in (("L", 1.0), ("R", -1.0)):
        low = side.lower()
        shapes[f"{side}Shoulder"] = [("sphere", (0.0, 0.0, 0.0), (0, 0, 0), _mm((30,)))]
        shapes[f"{side}Bicep"] = _capsule((25, s * 12, 0), (85, s * 12, 0), 25)
        shapes[f"{side}ForeArm"] = _capsule((15, 0, 0), (40, 0, 0), 22)
        shapes[f"{low}_wrist"] = [("box", _mm((35, 0, -12)), (0, 0, 0), _mm((60, 45, 40)))]
        shapes[f"{low}_finger"] = [("box", _mm(finger_centre), (0, 1.0, 0), _mm((40, 40, 14)))]
        shapes[f"{side}Thigh"] = _capsule((0, 0, -30), (0, 0, -75), 33)
        shapes[f"{side}Tibia"] = _capsule((0, 0, -25), (0, 0, -75), 30)
        shapes[f"{low}_ankle"] = [("box", _mm((20, s * 5, -30)), (0, 0, 0), _mm((160, 80, 30)))]
    return shapes

def _disabled_pairs(links: list[str], joints: list[dict], shapes: dict) -> list[tuple[str, str, str]]:
    """Pairs joined by a joint once links without geometry are merged into their parents."""
    parent = {j["child"]: j["parent"] for j in joints}

    def body(link):  # nearest ancestor-or-self with geometry
        while link not in shapes and link in parent:
            link = parent[link]
        return link

    pairs = set()
    for link in links:
        if link in shapes and link in parent:
            other = body(parent[link])
            if other in shapes:
                pairs.add(tuple(sorted((link, other))))
    return [(a, b, "Adjacent") for a, b in sorted(pairs)]

def urdf_text() -> str:
    links, joints = _kinematics()
    shapes = _collision()
    out = ['<?xml version="1.0"?>',
           "<!-- NAO V5 (H25), generated by tools/build_nao.py from the official link lengths and",
           "     limits (Bischoff 2016 digest, sections 1.6-1.7). SI units. Do not edit by hand. -->",
           '<robot name="nao">']
    for link in links:
        items = shapes.get(link, [])
        if not items:
            out.append(f'  <link name="{link}"/>')
            continue
        out.append(f'  <link name="{link}">')
        for kind in ("visual", "collision"):
            for shape, xyz, rpy, params in items:
                attr = {"box": f'size="{_fmt(params)}"', "sphere": f'radius="{_fmt(params)}"',
                        "cylinder": f'radius="{_fmt(params[:1])}" length="{_fmt(params[1:])}"'}[shape]
                out += [f"    <{kind}>", f'      <origin xyz="{_fmt(xyz)}" rpy="{_fmt(rpy)}"/>',
                        f"      <geometry><{shape} {attr}/></geometry>", f"    </{kind}>"]
        out.append("  </link>")
    for j in joints:
        out.append(f'  <joint name="{j["name"]}" type="{j["type"]}">')
        out += [f'    <parent link="{j["parent"]}"/>', f'    <child link="{j["child"]}"/>',
                f'    <origin xyz="{_fmt(j["xyz"])}" rpy="{_fmt(j["rpy"])}"/>']
        if j["type"] != "fixed":
            lo, hi, vel = LIMITS[j["mimic"] or j["name"]]
            out.append(f'    <axis xyz="{_fmt(j["axis"])}"/>')
            out.append(f'    <limit lower="{_fmt([lo])}" upper="{_fmt([hi])}" velocity="{_fmt([vel])}" effort="1"/>')
            if j["mimic"]:
                out.append(f'    <mimic joint="{j["mimic"]}" multiplier="1" offset="0"/>')
        out.append("  </joint>")
    out.append("</robot>")
    return "\n".join(out) + "\n"

def srdf_text() -> str:
    links, joints = _kinematics()
    out = ['<?xml version="1.0"?>', "<!-- NAO V5 (H25) semantics, generated by tools/build_nao.py. -->",
           '<robot name="nao">']
    groups = [("head", "torso", "Head")]
    for side, word in (("L", "left"), ("R", "right")):
        low = side.lower()
        groups += [(f"{word}_arm", "torso", f"{low}_arm_tip"), (f"{word}_arm_wrist", "torso", f"{low}_gripper"),
                   (f"{word}_leg", "torso", f"{low}_sole")]
    for name, base, tip in groups:
        out += [f'  <group name="{name}">', f'    <chain base_link="{base}" tip_link="{tip}"/>', "  </group>"]
    for side, word in (("L", "left"), ("R", "right")):
        out += [f'  <group name="{word}_hand">', f'    <joint name="{side}Hand"/>', "  </group>"]
    for side, word in (("L", "left"), ("R", "right")):
        for state, value in (("open", 1.0), ("closed", 0.0)):
            out += [f'  <group_state name="{state}" group="{word}_hand">',
                    f'    <joint name="{side}Hand" value="{_fmt([value])}"/>', "  </group_state>"]
    for side, word in (("L", "left"), ("R", "right")):
        low = side.lower()
        out.append(f'  <end_effector name="{word}_hand" parent_link="{low}_wrist" group="{word}_hand" '
                   f'parent_group="{word}_arm_wrist" tcp_link="{low}_gripper" gcp_link="{low}_gripper"/>')
    for a, b, reason in _disabled_pairs(links, joints, _collision()):
        out.append(f'  <disable_collisions link1="{a}" link2="{b}" reason="{reason}"/>')
    out.append("</robot>")
    return "\n".join(out) + "\n"

def main(argv: list[str] | None = None) -> None:
    default = Path(__file__).resolve().parents[1] / "src" / "prehensile" / "robots" / "nao"
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--out", type=Path, default=default, help="output folder (default: the bundled one)")
    args = parser.parse_args(argv)
    atomic_write_text(args.out / "nao.urdf", urdf_text())
    atomic_write_text(args.out / "nao.srdf", srdf_text())

if __name__ == "__main__":
    main()
