"""Tests for the bundled ARMAR-III model (src/prehensile/robots/armar3), built by
tools/build_armar3.py from the Simox XML files."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import numpy as np
import pytest

from conftest import SHARED
from prehensile.collision import ExactChecker
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model import Box, load_urdf
from prehensile.model.simox import load_simox

ROOT = Path(__file__).resolve().parents[1]
BUNDLED = ROOT / "src" / "prehensile" / "robots" / "armar3"
URDF, SRDF = BUNDLED / "armar3.urdf", BUNDLED / "armar3.srdf"
SIMOX = SHARED / "assets" / "armar3-simox"
MIMIC = {f"{f}_{s}_J1": f"{f}_{s}_J0" for f in ("Ring", "Pinky") for s in "LR"}


@pytest.fixture(scope="module")
def model():
    return load_urdf(URDF, SRDF)


@pytest.fixture(scope="module")
def simox():
    if not (SIMOX / "ArmarIII_withPlatformJoints.xml").is_file():
        pytest.skip(f"Simox ARMAR-III model not available at {SIMOX}")
    return load_simox(SIMOX / "ArmarIII_withPlatformJoints.xml", meshes=False)


@pytest.fixture(scope="module")
def samples(model):
    return model.random_configurations(np.random.default_rng(2024), 1000)


def test_degrees_of_freedom(model):
    assert model.dof == 43
    names = set(model.joint_names)
    assert {"X_Platform", "Y_Platform", "Yaw_Platform", "Hip_Pitch", "Hip_Roll", "Hip_Yaw"} <= names
    for side in "LR":
        assert sum(n.endswith(f"_{side}") or f"_{side}_" in n for n in names) == 15  # arm 7 + hand 8
        assert f"Hand_Palm_2_{side}" not in names
    assert {"Neck_1_Pitch", "Neck_2_Roll", "Neck_3_Yaw", "Head_Tilt", "Cameras", "Eye_Left", "Eye_Right"} <= names
    for mimic, leader in MIMIC.items():
        i = model.link_index(mimic)
        assert model.joint_names[model.joint_q_index[i]] == leader


def test_srdf_groups_and_end_effectors(model):
    for name in ("TorsoLeftArm", "TorsoRightArm", "LeftArm", "RightArm", "TorsoBothArms", "Head", "Neck",
                 "PlatformYawTorsoLeftArm", "PlatformYawTorsoRightArm", "LeftHand", "RightHand"):
        assert name in model.chains
    assert len(model.chain("LeftArm").joint_names) == 7
    assert model.chain("TorsoRightArm").joint_names[:3] == ("Hip_Pitch", "Hip_Roll", "Hip_Yaw")
    assert model.chain("PlatformYawTorsoLeftArm").joint_names[0] == "Yaw_Platform"
    assert len(model.chain("TorsoBothArms").joint_names) == 17
    assert len(model.chain("Head").joint_names) == 7
    for side, word in (("L", "Left"), ("R", "Right")):
        eef = model.end_effector(f"Hand_{side}")
        assert (eef.tcp_link, eef.gcp_link, eef.chain) == (f"TCP_{side}", f"GCP_{side}", f"{word}Arm")
        assert len(eef.finger_joints) == 8
        assert set(eef.preshapes) == {"Power_Preshape", "Precision_Preshape"}
        assert eef.preshapes["Precision_Preshape"][f"Ring_{side}_J0"] == 1.0
        model.configuration_from_dict(eef.preshapes["Precision_Preshape"])
    assert frozenset(("Hip_Yaw", "Platform")) in model.disabled_collision_pairs  # Simox IgnoreCollision


def _simox_q(simox, model, q):
    """Simox configurations (N, simox.dof) equivalent to bundled-model configurations q (N, 43)."""
    out = np.zeros((q.shape[0], simox.dof))
    for j, name in enumerate(simox.joint_names):
        urdf_name = MIMIC.get(name.replace(" ", "_"), name.replace(" ", "_"))
        if urdf_name in model.joint_names:
            out[:, j] = q[:, model.joint_index(urdf_name)]
    return out


def test_fk_matches_simox_model(model, simox, samples):
    ours = forward_kinematics(model, samples)
    theirs = forward_kinematics(simox, _simox_q(simox, model, samples))
    assert len(simox.link_names) == len(model.link_names)
    for i, name in enumerate(simox.link_names):
        np.testing.assert_allclose(ours[:, model.link_index(name.replace(" ", "_"))], theirs[:, i], atol=1e-9,
                                   err_msg=name)


def test_fk_matches_pinocchio(model, samples):
    pin = pytest.importorskip("pinocchio")
    pmodel = pin.buildModelFromUrdf(str(URDF))
    data = pmodel.createData()
    assert pmodel.nq == pmodel.nv
    columns = []
    for jid in range(1, pmodel.njoints):
        name = pmodel.names[jid]
        columns.append((pmodel.joints[jid].idx_q, model.joint_index(MIMIC.get(name, name))))
    frames = [(pmodel.getFrameId(n, pin.BODY), model.link_index(n)) for n in model.link_names]
    ours = forward_kinematics(model, samples)[:, [link for _, link in frames]]
    theirs = np.empty_like(ours)
    for k, q in enumerate(samples):
        pq = np.zeros(pmodel.nq)
        for idx_q, ours_index in columns:
            pq[idx_q] = q[ours_index]
        pin.framesForwardKinematics(pmodel, data, pq)
        theirs[k] = [data.oMf[fid].homogeneous for fid, _ in frames]
    np.testing.assert_allclose(theirs, ours, atol=1e-9)


def test_home_configuration_is_collision_free(model):
    links = {model.link_names[i] for i, geoms in enumerate(model.collisions) if geoms}
    assert {"Platform", "Hip_Yaw", "Head_Tilt", "Upperarm_L", "Underarm_R", "Hand_Palm_1_L", "Index_R_J1"} <= links
    assert ExactChecker(model, []).collisions(model.neutral_configuration()) == []


def test_robot_dimensions(model):
    poses = forward_kinematics(model, model.neutral_configuration())
    top = max(
        (poses[i] @ g.T_link_geom)[2, 3] + (g.shape.size[2] / 2 if isinstance(g.shape, Box) else 0.0)
        for i in range(model.n_links) for g in model.collisions[i]
    )
    assert 1.7 < top < 1.8  # ARMAR-III is about 1.75 m tall
    assert poses[model.link_index("Hip_Pitch"), 2, 3] == pytest.approx(0.89)


def test_bundled_files_are_up_to_date():
    if not SIMOX.is_dir():
        pytest.skip(f"Simox ARMAR-III model not available at {SIMOX}")
    spec = importlib.util.spec_from_file_location("build_armar3", ROOT / "tools" / "build_armar3.py")
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    texts = build.render(SIMOX)
    assert texts["armar3.urdf"] == URDF.read_text(encoding="utf-8")
    assert texts["armar3.srdf"] == SRDF.read_text(encoding="utf-8")
