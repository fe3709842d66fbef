"""Tests for the Simox XML loader (prehensile.model.simox)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED
from prehensile.errors import ModelError
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.simox import load_simox

ROOT = Path(__file__).resolve().parents[1]
DATA = ROOT / "tests" / "data" / "simox"
ARMAR3 = SHARED / "assets" / "armar3-simox"


def _armar3(name: str):
    if not (ARMAR3 / name).is_file():
        pytest.skip(f"Simox ARMAR-III model not available at {ARMAR3}")
    return load_simox(ARMAR3 / name)


def _rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    T = np.eye(4)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def _trans(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = [x, y, z]
    return T


def test_hand_computed_forward_kinematics():
    model = load_simox(DATA / "hand_computed.xml")
    assert model.joint_names == ("Link A", "Link B", "Link C", "Finger")
    deg = np.pi / 180
    np.testing.assert_allclose(model.lower, [-90 * deg, 0.0, -1.0, 0.0])
    np.testing.assert_allclose(model.upper, [45 * deg, 0.2, 1.0, 1.5])
    assert model.velocity_limit[0] == pytest.approx(np.pi / 2)

    rng = np.random.default_rng(3)
    q = model.random_configurations(rng, 20)
    poses = forward_kinematics(model, q)
    for qi, P in zip(q, poses):
        # DH: Rz(theta) Tz(d) Tx(a) Rx(alpha), then translation, then rpy = Rz(yaw) Ry(pitch) Rx(roll)
        dh = _rot("z", 30 * deg) @ _trans(0, 0, 0.05) @ _trans(0.1, 0, 0) @ _rot("x", 90 * deg)
        rpy = _rot("z", 30 * deg) @ _rot("y", 20 * deg) @ _rot("x", 10 * deg)
        T_a = dh @ _trans(0.01, 0.02, 0.03) @ rpy @ _rot("y", qi[0])
        T_b = T_a @ _trans(0.1, 0, 0) @ _trans(0, 0, qi[1])
        matrix = np.array([[0, -1, 0, 0.05], [1, 0, 0, 0], [0, 0, 1, 0], [0, 0, 0, 1.0]])
        T_c = T_b @ matrix @ _rot("z", qi[2])  # revolute without <Axis>: z
        T_grip = T_c @ _trans(0, 0, 0.02)
        T_tcp = T_grip @ _trans(0, 0, 0.08)
        T_finger = T_grip @ _rot("x", qi[3] + 0.5)  # joint offset 0.5 rad
        for name, expected in [("Link A", T_a), ("Link B", T_b), ("Link C", T_c), ("Gripper TCP", T_tcp),
                               ("Finger", T_finger)]:
            np.testing.assert_allclose(P[model.link_index(name)], expected, atol=1e-12)


def test_included_file_chains_and_end_effectors():
    model = load_simox(DATA / "hand_computed.xml")
    assert model.link_parent[model.link_index("Gripper Base")] == model.link_index("Link C")
    arm = model.chain("Arm")
    assert (arm.base_link, arm.tip_link, arm.joint_names) == ("Base", "Gripper TCP", ("Link A", "Link B", "Link C"))
    eef = model.end_effector("Gripper")
    assert eef.tcp_link == eef.gcp_link == "Gripper TCP"
    assert eef.finger_joints == ("Finger",)
    assert eef.preshapes["Open"]["Finger"] == pytest.approx(np.pi / 6)
    assert frozenset(("Link A", "Base")) in model.disabled_collision_pairs


@pytest.mark.parametrize(
    "filename, node, problem",
    [
        ("unknown_child.xml", "Arm Link", "unknown child node 'Missing Link'"),
        ("cycle.xml", "Link B", "tree"),
        ("unknown_joint_type.xml", "Arm Link", "unknown joint type 'spherical'; valid types: revolute, prismatic"),
        ("missing_include.xml", "Arm Mount", "does_not_exist.xml"),
        ("bad_units.xml", "Arm Link", "unknown unit 'furlong'"),
        ("missing_mesh.xml", "Arm Link", "meshes/missing_link.stl"),
        ("unknown_element.xml", "Arm Link", "unknown element <Wheel>"),
    ],
)
def test_bad_input_names_file_and_node(filename, node, problem):
    with pytest.raises(ModelError) as info:
        load_simox(DATA / filename)
    message = str(info.value)
    assert filename in message and f"'{node}'" in message and problem in message


def test_malformed_xml_names_file():
    with pytest.raises(ModelError, match="malformed.xml: malformed XML"):
        load_simox(DATA / "malformed.xml")


def test_meshes_flag_skips_missing_mesh():
    model = load_simox(DATA / "missing_mesh.xml", meshes=False)
    assert model.collisions[model.link_index("Arm Link")] == ()


def test_armar3_without_platform_joints():
    model = _armar3("ArmarIII.xml")
    # yaw 1 + hip 3 + head 13 (neck 4, jaw, eye tilt, gaze, 2 eyes, 4 lids) + arms 14 + hands 22
    assert model.dof == 53
    assert "Hip Pitch" in model.joint_names and "X_Platform" not in model.joint_names
    i = model.joint_index("Shoulder 1 L")
    assert model.lower[i] == pytest.approx(np.deg2rad(-106.91))
    assert model.upper[i] == pytest.approx(np.deg2rad(80.0))
    lid = model.joint_index("Lid Left Top")  # no <Limits>: Simox default -pi..pi
    assert (model.lower[lid], model.upper[lid]) == (-np.pi, np.pi)


def test_armar3_with_platform_joints():
    model = _armar3("ArmarIII_withPlatformJoints.xml")
    assert model.dof == 55
    x = model.joint_index("X_Platform")
    assert (model.lower[x], model.upper[x]) == pytest.approx((0.0, 5.0))
    chain = model.chain("TorsoLeftArm")
    assert chain.base_link == "Platform" and chain.tip_link == "TCP L" and len(chain.joint_names) == 10
    assert model.chain("PlatformYawTorsoRightArm").joint_names[0] == "Yaw_Platform"
    assert len(model.chain("LeftArm").joint_names) == 7
    for side in "LR":
        eef = model.end_effector(f"Hand {side}")
        assert (eef.base_link, eef.tcp_link, eef.gcp_link) == (f"Hand {side} Base", f"TCP {side}", f"GCP {side}")
        assert set(eef.preshapes) == {"Power Preshape", "Precision Preshape"}
        assert eef.preshapes["Precision Preshape"][f"Ring {side} J1"] == 2.0
        assert len(eef.finger_joints) == 10
    assert frozenset(("Hip Yaw", "Platform")) in model.disabled_collision_pairs
    # home pose: hip 0.89 m above the base, TCPs in front of the robot (+y)
    poses = forward_kinematics(model, model.neutral_configuration())
    assert poses[model.link_index("Hip Pitch"), 2, 3] == pytest.approx(0.89)
    assert poses[model.link_index("TCP L"), 1, 3] == pytest.approx(0.513, abs=1e-3)
    # the right arm has no <Axis>: revolute joints turn about z, so both arms mirror each other
    q = model.random_configurations(np.random.default_rng(0), 50)
    assert np.isfinite(forward_kinematics(model, q)).all()


def test_root_transform_propagation_and_limitless_joint():
    model = load_simox(DATA / "root_offset_mimic.xml")
    assert model.name == "Coupled"
    assert model.joint_names == ("Driver",)  # Follower mimics Driver with factor -2
    assert model.continuous.tolist() == [True]
    poses = forward_kinematics(model, np.array([0.3]))
    np.testing.assert_allclose(poses[model.link_index("Root")], _trans(0, 0, 1.0), atol=1e-12)
    expected = _trans(0, 0, 1.0) @ _rot("x", 0.3) @ _trans(0, 0.1, 0) @ _rot("z", -0.6)
    np.testing.assert_allclose(poses[model.link_index("Follower")], expected, atol=1e-12)


def test_a_part_file_loads_alone_and_skips_collision_names_of_its_parent(caplog):
    """ArmarIII-Head.xml's <IgnoreCollision> names the hip, a node of ArmarIII.xml that includes it."""
    head = _armar3("ArmarIII-Head.xml")
    assert head.n_links > 5 and "Hip Yaw" not in head.link_names
    assert "<IgnoreCollision> names node 'Hip Yaw', which this file does not have; ignored" in caplog.text
