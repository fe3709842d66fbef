"""The bundled NAO V5 (H25) model against the Bischoff digest §1.5-1.7 and pinocchio."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from prehensile.collision import ExactChecker
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model import load_urdf

ROOT = Path(__file__).resolve().parents[1]
NAO_DIR = ROOT / "src" / "prehensile" / "robots" / "nao"
URDF, SRDF = NAO_DIR / "nao.urdf", NAO_DIR / "nao.srdf"


@pytest.fixture(scope="module")
def nao():
    return load_urdf(URDF, SRDF)


def rot(axis: str, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = {"x": (1, 2), "y": (2, 0), "z": (0, 1)}[axis]
    T = np.eye(4)
    T[i, i], T[i, j], T[j, i], T[j, j] = c, -s, s, c
    return T


def tr(x: float, y: float, z: float) -> np.ndarray:
    T = np.eye(4)
    T[:3, 3] = np.array([x, y, z]) * 1e-3  # mm -> m
    return T


def mdh(a_mm: float, alpha: float, d_mm: float, theta: float) -> np.ndarray:
    """Modified (Craig) DH: Rx(alpha) Tx(a) Rz(theta) Tz(d)."""
    return rot("x", alpha) @ tr(a_mm, 0, 0) @ rot("z", theta) @ tr(0, 0, d_mm)


def exact_dh_hand(q4: np.ndarray, s: float) -> np.ndarray:
    """§1.5(5): exact 4-DoF arm DH (Kofinas 2013), hand point pose (4, 4) in m."""
    t1, t2, t3, t4 = q4
    T = tr(0, s * 98, 100)
    T = T @ mdh(0, -np.pi / 2, 0, t1) @ mdh(0, np.pi / 2, 0, t2 + np.pi / 2)
    T = T @ mdh(s * 15, np.pi / 2, 105, t3) @ mdh(0, -np.pi / 2, 0, t4)
    return T @ rot("z", -np.pi / 2) @ tr(113.70, 0, -12.31)


def test_builder_is_deterministic(tmp_path):
    subprocess.run([sys.executable, str(ROOT / "tools" / "build_nao.py"), "--out", str(tmp_path)], check=True)
    for name in ("nao.urdf", "nao.srdf"):
        assert (tmp_path / name).read_text() == (NAO_DIR / name).read_text()


def test_joints_and_dof(nao):
    assert nao.dof == 25
    expected = {"HeadYaw", "HeadPitch"}
    for side in "LR":
        expected |= {side + j for j in ("ShoulderPitch", "ShoulderRoll", "ElbowYaw", "ElbowRoll", "WristYaw", "Hand",
                                        "HipRoll", "HipPitch", "KneePitch", "AnklePitch", "AnkleRoll")}
    assert set(nao.joint_names) == expected | {"LHipYawPitch"}
    r = nao.link_index("RPelvis")
    assert nao.link_joint_names[r] == "RHipYawPitch"
    assert nao.joint_names[nao.joint_q_index[r]] == "LHipYawPitch" and nao.joint_multiplier[r] == 1.0


def test_zero_pose_hand_point(nao):
    poses = forward_kinematics(nao, np.zeros(nao.dof))
    # §1.6 at q = 0: Tr(0,98,100) Tr(105,15,0) Tr(55.95,0,0) Tr(57.75,0,-12.31)
    x = (105 + 55.95 + 57.75) * 1e-3
    for side, s in (("l", 1), ("r", -1)):
        for link in (f"{side}_gripper", f"{side}_arm_tip"):
            np.testing.assert_allclose(poses[nao.link_index(link), :3, 3], [x, s * 0.113, 0.1 - 0.01231], atol=1e-12)
    # the thesis model (no HandOffsetZ) puts the hand at (218.7, 113, 100) mm
    assert x == pytest.approx(0.2187)
    sole = poses[nao.link_index("l_sole"), :3, 3]
    np.testing.assert_allclose(sole, [0, 0.05, -(85 + 100 + 102.9 + 45.11) * 1e-3], atol=1e-12)
    cam = poses[nao.link_index("CameraBottom_frame")]
    np.testing.assert_allclose(cam[:3, 3], np.array([50.71, 0, 126.5 + 17.74]) * 1e-3, atol=1e-12)
    np.testing.assert_allclose(cam[:3, :3], rot("y", 0.6929)[:3, :3], atol=1e-12)


@pytest.mark.parametrize("side,s", [("l", 1.0), ("r", -1.0)])
def test_exact_dh_table_matches_fk(nao, side, s):
    rng = np.random.default_rng(7)
    q = nao.random_configurations(rng, 1000)
    chain = nao.chain(f"{'left' if s > 0 else 'right'}_arm")
    idx = nao.chain_q_indices(chain.name)
    ours = forward_kinematics(nao, q)[:, nao.link_index(chain.tip_link)]
    ref = np.array([exact_dh_hand(row, s) for row in q[:, idx]])
    np.testing.assert_allclose(ours[:, :3, 3], ref[:, :3, 3], atol=1e-9)
    np.testing.assert_allclose(ours[:, :3, :3], ref[:, :3, :3], atol=1e-9)
    # with WristYaw = 0 the 5-DoF TCP is the same frame
    q[:, nao.joint_index(f"{side.upper()}WristYaw")] = 0.0
    tcp = forward_kinematics(nao, q)[:, nao.link_index(f"{side}_gripper")]
    np.testing.assert_allclose(tcp, ref, atol=1e-9)


def test_mirror(nao):
    rng = np.random.default_rng(3)
    q = nao.random_configurations(rng, 200)
    left = nao.chain_q_indices("left_arm")
    right = nao.chain_q_indices("right_arm")
    q[:, right] = q[:, left] * np.array([1, -1, -1, -1])
    poses = forward_kinematics(nao, q)
    p_left = poses[:, nao.link_index("l_arm_tip"), :3, 3]
    p_right = poses[:, nao.link_index("r_arm_tip"), :3, 3]
    np.testing.assert_allclose(p_right, p_left * np.array([1, -1, 1]), atol=1e-12)


@pytest.mark.parametrize("joint,lower,upper", [
    ("HeadYaw", -2.0857, 2.0857), ("HeadPitch", -0.6720, 0.5149),
    ("LShoulderRoll", -0.3142, 1.3265), ("RShoulderRoll", -1.3265, 0.3142),
    ("LElbowRoll", -1.5446, -0.0349), ("RElbowRoll", 0.0349, 1.5446),
    ("LWristYaw", -1.8238, 1.8238), ("RHand", 0.0, 1.0),
    ("LHipYawPitch", -1.14529, 0.740718), ("RHipRoll", -0.79046, 0.379435),
    ("LKneePitch", -0.0923279, 2.11255), ("RAnklePitch", -1.1863, 0.932006),
    ("LAnkleRoll", -0.397761, 0.768992),
])
def test_limits(nao, joint, lower, upper):
    i = nao.joint_index(joint)
    assert nao.lower[i] == pytest.approx(lower, abs=1e-9)
    assert nao.upper[i] == pytest.approx(upper, abs=1e-9)


def test_pinocchio_agrees_on_all_links(nao):
    pin = pytest.importorskip("pinocchio")
    pmodel = pin.buildModelFromUrdf(str(URDF))
    pdata = pmodel.createData()
    rng = np.random.default_rng(11)
    q = nao.random_configurations(rng, 1000)
    ours = forward_kinematics(nao, q)
    frames = [pmodel.getFrameId(name, pin.FrameType.BODY) for name in nao.link_names]
    assert all(f < len(pmodel.frames) for f in frames)
    # pinocchio's q order by joint name; RHipYawPitch is set from its leader by hand
    source = []
    for name in pmodel.names[1:]:
        source.append(nao.joint_index("LHipYawPitch" if name == "RHipYawPitch" else name))
    for k in range(q.shape[0]):
        pin.framesForwardKinematics(pmodel, pdata, q[k, source])
        for i, f in enumerate(frames):
            np.testing.assert_allclose(ours[k, i], pdata.oMf[f].homogeneous, atol=1e-9)


def test_no_self_collision_at_rest(nao):
    checker = ExactChecker(nao, [])
    open_hands = nao.configuration_from_dict({"LHand": 1.0, "RHand": 1.0})
    for q in (np.zeros(nao.dof), nao.neutral_configuration(), open_hands):
        assert checker.collisions(q) == []


def test_size_like_the_real_robot(nao):
    poses = forward_kinematics(nao, np.zeros(nao.dof))
    top = poses[nao.link_index("Head"), 2, 3] + 0.055 + 0.060
    bottom = poses[nao.link_index("l_sole"), 2, 3]
    assert top - bottom == pytest.approx(0.574, abs=0.01)


def test_srdf_semantics(nao):
    assert nao.chain("left_arm").joint_names == ("LShoulderPitch", "LShoulderRoll", "LElbowYaw", "LElbowRoll")
    assert nao.chain("right_arm_wrist").joint_names[-1] == "RWristYaw"
    assert nao.chain("head").joint_names == ("HeadYaw", "HeadPitch")
    assert len(nao.chain("left_leg").joint_names) == 6
    hand = nao.end_effector("left_hand")
    assert hand.tcp_link == "l_gripper" and hand.finger_joints == ("LHand",)
    assert hand.preshapes["open"] == {"LHand": 1.0} and hand.preshapes["closed"] == {"LHand": 0.0}
    assert frozenset(("LBicep", "LForeArm")) in nao.disabled_collision_pairs
