"""The robot registry: bundled robots by name, robot files by path, helpful errors."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest

from prehensile import robots
from prehensile.errors import ModelError
from prehensile.kinematics.forward import forward_kinematics

HERE = Path(__file__).resolve().parent
ROBOTS = HERE.parent / "src" / "prehensile" / "robots"
SIMOX_ARMAR3 = Path("/work/shared/assets/armar3-simox/ArmarIII.xml")

EXPECTED_DOF = {"nao": 25, "panda": 8, "armar3": 43}


def _require(name: str) -> None:
    if name not in robots.available():
        pytest.skip(f"robot '{name}' is not present yet")


@pytest.mark.parametrize("name", sorted(EXPECTED_DOF))
def test_bundled_robot_loads(name):
    _require(name)
    model = robots.load(name)
    assert model.dof == EXPECTED_DOF[name]
    assert len(model.joint_names) == len(set(model.joint_names)) == model.dof
    assert len(model.link_names) == len(set(model.link_names)) == model.n_links
    assert len(model.link_joint_names) == model.n_links
    assert model.lower.shape == model.upper.shape == (model.dof,)
    assert np.all(model.lower <= model.upper)
    # every actuated joint moves at least one link, and every q index is in range
    assert set(model.joint_q_index[model.joint_q_index >= 0]) == set(range(model.dof))
    assert model.chains and model.end_effectors
    for eef in model.end_effectors.values():
        model.link_index(eef.tcp_link)
    poses = forward_kinematics(model, model.neutral_configuration())
    assert poses.shape == (model.n_links, 4, 4) and np.all(np.isfinite(poses))


def test_bundled_models_are_cached():
    assert robots.load("nao") is robots.load("nao")


def test_available_lists_the_bundled_names():
    names = robots.available()
    assert names == sorted(names)
    assert {"nao", "panda"} <= set(names)
    assert set(names) <= set(EXPECTED_DOF)


def test_panda_semantics():
    _require("panda")
    panda = robots.load("panda")
    assert panda.chain("arm").tip_link == "panda_hand_tcp"
    assert len(panda.chain("arm").joint_names) == 7
    hand = panda.end_effector("hand")
    assert hand.tcp_link == "panda_hand_tcp" and hand.finger_joints == ("panda_finger_joint1",)
    assert hand.preshapes["open"]["panda_finger_joint1"] == pytest.approx(0.04)
    assert hand.preshapes["closed"]["panda_finger_joint1"] == 0.0
    assert frozenset(("panda_link6", "panda_link7")) in panda.disabled_collision_pairs
    # the second finger follows the first (URDF mimic), so the hand adds one DoF
    right = panda.link_index("panda_rightfinger")
    assert panda.joint_names[panda.joint_q_index[right]] == "panda_finger_joint1"


def test_unknown_name_lists_valid_names():
    with pytest.raises(ModelError) as err:
        robots.load("nau")
    message = str(err.value)
    assert "unknown robot 'nau'" in message
    for name in ("nao", "panda", "armar3"):
        assert name in message
    assert "path" in message


def test_missing_path_and_bad_suffix(tmp_path):
    with pytest.raises(ModelError, match="missing.urdf.*not found"):
        robots.load(tmp_path / "missing.urdf")
    odd = tmp_path / "robot.yaml"
    odd.write_text("name: x\n")
    with pytest.raises(ModelError, match="robot.yaml.*valid: .urdf, .xml"):
        robots.load(odd)
    other = tmp_path / "scene.xml"
    other.write_text("<scene/>")
    with pytest.raises(ModelError, match="scene.xml.*<scene>.*<mujoco>"):
        robots.load(other)


def test_load_urdf_by_path_picks_up_the_srdf(tmp_path):
    for suffix in (".urdf", ".srdf"):
        shutil.copy(ROBOTS / "nao" / f"nao{suffix}", tmp_path / f"copy{suffix}")
    model = robots.load(tmp_path / "copy.urdf")
    assert model.dof == 25 and "left_arm" in model.chains
    assert model.srdf_source == str(tmp_path / "copy.srdf")
    (tmp_path / "copy.srdf").unlink()
    bare = robots.load(str(tmp_path / "copy.urdf"))
    assert not bare.chains and bare.srdf_source is None


def test_load_with_explicit_srdf(tmp_path):
    srdf = tmp_path / "mine.srdf"
    srdf.write_text('<robot name="nao"><group name="only_head"><chain base_link="torso" tip_link="Head"/>'
                    "</group></robot>")
    model = robots.load("nao", srdf=srdf)
    assert set(model.chains) == {"only_head"} and model.srdf_source == str(srdf)
    assert model is not robots.load("nao")


def test_load_mjcf_by_path():
    model = robots.load(HERE / "data" / "mjcf" / "arm7.xml")
    assert model.name == "arm7" and model.dof == 8


def test_load_simox_by_path():
    if not SIMOX_ARMAR3.is_file():
        pytest.skip("the ARMAR-III Simox files are not available")
    pytest.importorskip("prehensile.model.simox")
    model = robots.load(SIMOX_ARMAR3)
    assert model.dof > 0
