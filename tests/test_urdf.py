"""URDF and SRDF loading: structure, joint types, and clear errors on bad input."""

from __future__ import annotations

import logging
import re

import numpy as np
import pytest

from conftest import MBM, WEDGE, require_shared
from prehensile.errors import ModelError
from prehensile.kinematics import forward_kinematics
from prehensile.model import Box, Capsule, Cylinder, Mesh, Sphere, load_urdf

ARM = """<robot name="arm">
  <link name="base"><collision><geometry><box size="0.2 0.2 0.1"/></geometry></collision></link>
  <link name="upper"><collision><origin xyz="0 0 0.15"/><geometry><cylinder radius="0.04" length="0.3"/></geometry></collision></link>
  <link name="lower"><collision><geometry><capsule radius="0.03" length="0.2"/></geometry></collision></link>
  <link name="slider"><visual><geometry><sphere radius="0.02"/></geometry></visual></link>
  <link name="finger_a"/><link name="finger_b"/><link name="wheel"/>
  <joint name="shoulder" type="revolute"><parent link="base"/><child link="upper"/>
    <origin xyz="0 0 0.1" rpy="0 0 0.5"/><axis xyz="0 1 0"/><limit lower="-1.5" upper="1.5" velocity="2"/></joint>
  <joint name="elbow" type="revolute"><parent link="upper"/><child link="lower"/>
    <origin xyz="0 0 0.3"/><axis xyz="0 1 0"/><limit lower="-2" upper="2" velocity="3"/></joint>
  <joint name="slide" type="prismatic"><parent link="lower"/><child link="slider"/>
    <origin xyz="0 0 0.2"/><axis xyz="0 0 1"/><limit lower="0" upper="0.1" velocity="0.5"/></joint>
  <joint name="finger_a" type="prismatic"><parent link="slider"/><child link="finger_a"/>
    <axis xyz="0 1 0"/><limit lower="0" upper="0.04"/></joint>
  <joint name="finger_b" type="prismatic"><parent link="slider"/><child link="finger_b"/>
    <axis xyz="0 -1 0"/><limit lower="0" upper="0.04"/><mimic joint="finger_a" multiplier="1" offset="0"/></joint>
  <joint name="wheel" type="continuous"><parent link="base"/><child link="wheel"/><axis xyz="1 0 0"/></joint>
</robot>"""


def write(tmp_path, text, name="robot.urdf"):
    path = tmp_path / name
    path.write_text(text)
    return path


def test_structure_joint_types_and_geometry(tmp_path):
    model = load_urdf(write(tmp_path, ARM))
    assert model.joint_names == ("shoulder", "elbow", "slide", "finger_a", "wheel")
    assert model.link_names[0] == "base" and set(model.link_names) == {
        "base", "upper", "lower", "slider", "finger_a", "finger_b", "wheel"}
    assert model.continuous.tolist() == [False, False, False, False, True]
    assert model.velocity_limit[1] == 3.0
    shapes = [type(g.shape) for geoms in model.collisions for g in geoms]
    assert shapes == [Box, Cylinder, Capsule]
    assert isinstance(model.visuals[model.link_index("slider")][0].shape, Sphere)


def test_a_capsule_of_length_0_is_a_ball_as_in_scene_files(tmp_path):
    model = load_urdf(write(tmp_path, ARM.replace('radius="0.03" length="0.2"', 'radius="0.03" length="0"')))
    assert model.collisions[model.link_index("lower")][0].shape == Capsule(0.03, 0.0)


def test_mimic_finger_moves_opposite(tmp_path):
    model = load_urdf(write(tmp_path, ARM))
    q = model.neutral_configuration()
    q[model.joint_index("finger_a")] = 0.03
    poses = forward_kinematics(model, q)
    a, b, s = (poses[model.link_index(n), :3, 3] for n in ("finger_a", "finger_b", "slider"))
    assert np.allclose(a - s, -(b - s)) and np.isclose(np.linalg.norm(a - s), 0.03)
    assert model.mimic_of("finger_b") == "finger_a"
    assert model.mimic_of("finger_a") is None and model.mimic_of("base") is None


def test_a_mimic_joint_driven_past_its_own_limits_is_reported(tmp_path, caplog):
    """A mimic joint is bounded through its leader only (as in MoveIt); a leader whose range
    takes it past its own limits gets a warning naming both, the model loads as before."""
    with caplog.at_level(logging.WARNING, logger="prehensile.model.builder"):
        load_urdf(write(tmp_path, ARM))
        assert not caplog.records
        model = load_urdf(write(tmp_path, ARM.replace('multiplier="1" offset="0"', 'multiplier="1.5" offset="0"')))
    assert model.upper[model.joint_index("finger_a")] == 0.04
    assert re.search(r"robot.urdf: mimic joint 'finger_b' \(limits 0 .. 0.04\) reaches 0 .. 0.06 within the limits of "
                     r"'finger_a'", caplog.text)


def test_planar_joint_expands_to_x_y_theta(tmp_path):
    text = """<robot name="base"><link name="world"/><link name="body"/>
      <joint name="base" type="planar"><parent link="world"/><child link="body"/><axis xyz="0 0 1"/></joint></robot>"""
    model = load_urdf(write(tmp_path, text))
    assert model.joint_names == ("base_x", "base_y", "base_theta")
    pose = forward_kinematics(model, np.array([1.0, 2.0, np.pi / 2]))[model.link_index("body")]
    assert np.allclose(pose[:3, 3], [1, 2, 0]) and np.allclose(pose[:3, 0], [0, 1, 0])


def test_chain_from_srdf_and_disabled_pairs(tmp_path):
    write(tmp_path, ARM)
    srdf = write(tmp_path, """<robot name="arm">
      <group name="arm"><chain base_link="base" tip_link="slider"/></group>
      <group name="gripper"><joint name="finger_a"/><joint name="finger_b"/></group>
      <group name="arm_gripper"><group name="arm"/><group name="gripper"/></group>
      <group_state name="open" group="gripper"><joint name="finger_a" value="0.04"/></group_state>
      <end_effector name="hand" parent_link="slider" group="gripper" parent_group="arm" tcp_link="finger_a"/>
      <disable_collisions link1="base" link2="upper" reason="Adjacent"/></robot>""", "robot.srdf")
    model = load_urdf(tmp_path / "robot.urdf", srdf)
    assert model.chain("arm").joint_names == ("shoulder", "elbow", "slide")
    assert model.chain_q_indices("arm").tolist() == [0, 1, 2]
    both = model.chain("arm_gripper")  # the arm's chain, with the gripper's joints too
    assert (both.base_link, both.tip_link) == ("base", "slider")
    assert both.joint_names == ("shoulder", "elbow", "slide", "finger_a")  # finger_b mimics finger_a
    hand = model.end_effector("hand")
    assert hand.finger_joints == ("finger_a",) and hand.tcp_link == "finger_a" and hand.chain == "arm"
    assert hand.preshapes["open"] == {"finger_a": 0.04}
    assert frozenset(("base", "upper")) in model.disabled_collision_pairs


@pytest.mark.parametrize(
    "edit, message",
    [
        (lambda t: t.replace('type="continuous"', 'type="screw"'), "unknown type 'screw'; valid types: revolute"),
        (lambda t: t.replace('<parent link="upper"/>', '<parent link="nowhere"/>'), "unknown parent link 'nowhere'"),
        (lambda t: t.replace('<child link="wheel"/>', '<child link="upper"/>'), "link 'upper' has two parent joints"),
        (lambda t: t.replace("</robot>", '<joint name="loop" type="fixed"><parent link="lower"/><child link="base"/></joint></robot>'), "cycle"),
        (lambda t: t.replace('type="continuous"', 'type="floating"'), "floating joints are not supported"),
        (lambda t: t.replace('<limit lower="-2" upper="2" velocity="3"/>', ""), "joint 'elbow': a revolute joint needs a <limit>"),
        (lambda t: t.replace('lower="-2" upper="2"', 'lower="2" upper="-2"'), "lower limit 2.0 above upper limit -2.0"),
        (lambda t: t.replace('xyz="0 1 0"/><limit lower="-2"', 'xyz="0 0 0"/><limit lower="-2"'), "zero or invalid axis"),
        (lambda t: t.replace('radius="0.04" length="0.3"', 'radius="-0.04" length="0.3"'), "link 'upper' <collision> #0 <cylinder>: must be positive"),
        (lambda t: t.replace('radius="0.04" length="0.3"', 'radius="inf" length="0.3"'),
         "link 'upper' <collision> #0 <cylinder>: must be positive and finite, got inf"),
        (lambda t: t.replace('radius="0.04" length="0.3"', 'radius="0.04" length="0"'),
         "link 'upper' <collision> #0 <cylinder> length: must be positive and finite, got 0.0"),
        (lambda t: t.replace('radius="0.03" length="0.2"', 'radius="0.03" length="-0.2"'),
         "link 'lower' <collision> #0 <capsule> length: must be >= 0 and finite, got -0.2"),
        (lambda t: t.replace('radius="0.03" length="0.2"', 'radius="0.03" length="inf"'),
         "link 'lower' <collision> #0 <capsule> length: must be >= 0 and finite, got inf"),
        (lambda t: t.replace('<box size="0.2 0.2 0.1"/>', '<mesh filename="meshes/missing.stl"/>'), "link 'base' <collision> #0 <mesh>: file 'meshes/missing.stl' not found"),
        (lambda t: t.replace('<box size="0.2 0.2 0.1"/>', f'<mesh filename="{WEDGE}" scale="0 1 1"/>'),
         "link 'base' <collision> #0 <mesh> scale: every factor must be non-zero"),
        (lambda t: t.replace('mimic joint="finger_a"', 'mimic joint="ghost"'), "mimics 'ghost'"),
        (lambda t: t.replace("</robot>", "<joint"), "malformed XML"),
        (lambda t: t.replace('<origin xyz="0 0 0.3"/>', '<origin xyz="0 0 nan"/>'), "joint 'elbow' <origin xyz>"),
        (lambda t: t.replace('velocity="3"', 'velocity="-3"'), "joint 'elbow' <limit>: velocity must be >= 0"),
        (lambda t: '<robot name="empty"></robot>', "the robot has no links"),
    ],
)
def test_malformed_urdf_names_file_element_and_problem(tmp_path, edit, message):
    path = write(tmp_path, edit(ARM))
    with pytest.raises(ModelError) as error:
        load_urdf(path)
    assert str(path) in str(error.value) and message in str(error.value)


def test_missing_file_and_srdf_slips_that_moveit_tolerates(tmp_path, caplog):
    with pytest.raises(ModelError, match="file not found"):
        load_urdf(tmp_path / "absent.urdf")
    write(tmp_path, ARM)
    srdf = write(tmp_path, '<robot><disable_collisions link1="base" link2="ghost"/>'
                           '<disable_collisions link1="base" link2="slider"/>'
                           '<group name="g"><joint name="finger_a"/></group><group_state name="open" group="g">'
                           '<joint name="finger_a" value="9"/></group_state>'
                           '<end_effector name="e" parent_link="slider" group="g"/></robot>', "slips.srdf")
    with caplog.at_level(logging.WARNING, logger="prehensile.model.srdf"):
        model = load_urdf(tmp_path / "robot.urdf", srdf)
    assert model.disabled_collision_pairs == {frozenset(("base", "slider"))}
    index = model.joint_index("finger_a")
    assert model.end_effectors["e"].preshapes["open"] == {"finger_a": model.upper[index]}
    assert "slips.srdf: disable_collisions of base and ghost skipped: robot 'arm' has no link 'ghost'" in caplog.text
    assert (f"slips.srdf: group_state 'open': joint 'finger_a' = 9 is outside its limits [{model.lower[index]:g}, "
            f"{model.upper[index]:g}], clipped into them") in caplog.text


@pytest.mark.parametrize("body, message", [
    ('<group name="m"><chain base_link="base" tip_link="nope"/></group>',
     "group 'm' <chain> names unknown link 'nope'"),
    ('<group name="m"><chain tip_link="slider"/></group>', "group 'm' <chain>: missing attribute 'base_link'"),
    ('<group name="m"><chain base_link="slider" tip_link="base"/></group>', "is not an ancestor of tip 'base'"),
    ('<group name="g"><joint name="finger_a"/></group><group_state name="open" group="g">'
     '<joint name="thumb" value="0"/></group_state>', "group_state 'open': unknown joint 'thumb'; joints: shoulder"),
    ('<group_state name="open" group="hand"/>', "group_state 'open': unknown group 'hand'; groups: (none)"),
    ('<group name="g"><joint name="finger_a"/></group><end_effector name="e" parent_link="slider" group="g" '
     'parent_group="arms"/>', "end_effector 'e': unknown group 'arms'; groups: g"),
])
def test_srdf_errors_name_the_srdf_element_and_choices(tmp_path, body, message):
    write(tmp_path, ARM)
    srdf = write(tmp_path, f"<robot>{body}</robot>", "bad.srdf")
    with pytest.raises(ModelError) as error:
        load_urdf(tmp_path / "robot.urdf", srdf)
    assert str(error.value).startswith(str(srdf)) and message in str(error.value)


def test_mbm_panda_meshes_resolve():
    panda = require_shared(MBM / "panda")
    model = load_urdf(panda / "panda.urdf", panda / "panda.srdf")
    meshes = [g.shape for geoms in model.collisions for g in geoms]
    assert meshes and all(isinstance(m, Mesh) and m.path.is_file() for m in meshes)
    assert model.dof == 7 and model.chain("panda_arm").tip_link == "panda_link8"


def test_packages_are_found_by_their_manifest_and_missing_visual_meshes_left_out(tmp_path, caplog):
    """A package checked out under another folder name is found by its package.xml; a visual
    mesh that is missing only costs the picture, a missing collision mesh is an error."""
    import shutil

    package = tmp_path / "arm_description-main"
    (package / "meshes").mkdir(parents=True)
    (package / "urdf").mkdir()
    (package / "package.xml").write_text('<?xml version="1.0"?><package format="3">\n  <name> arm_description </name>'
                                         "\n  <version>1.0.0</version></package>")
    shutil.copy(WEDGE, package / "meshes" / "wedge.obj")
    link = ('<link name="tool"><visual><geometry><mesh filename="package://arm_description/meshes/{visual}"/>'
            '</geometry></visual><collision><geometry><mesh filename="package://arm_description/meshes/{collision}"/>'
            '</geometry></collision></link><joint name="tool" type="fixed"><parent link="slider"/>'
            '<child link="tool"/></joint></robot>')
    path = write(package / "urdf", ARM.replace("</robot>", link.format(visual="gone.dae", collision="wedge.obj")))
    with caplog.at_level(logging.WARNING, logger="prehensile.model.urdf"):
        model = load_urdf(path)
    tool = model.link_index("tool")
    assert model.collisions[tool][0].shape.path == package / "meshes" / "wedge.obj" and not model.visuals[tool]
    assert "link 'tool' <visual> #0 <mesh>: file 'package://arm_description/meshes/gone.dae' not found" in caplog.text
    missing = write(package / "urdf", ARM.replace("</robot>", link.format(visual="wedge.obj", collision="gone.stl")))
    with pytest.raises(ModelError, match="link 'tool' <collision> #0 <mesh>: file .*gone.stl' not found"):
        load_urdf(missing)
