"""MJCF loader: forward kinematics against MuJoCo's own mj_kinematics, geometry, errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from prehensile.errors import ModelError  # noqa: E402
from prehensile.kinematics.forward import forward_kinematics  # noqa: E402
from prehensile.model.geometry import Box, Capsule, Cylinder, Mesh, Sphere  # noqa: E402
from prehensile.model.mjcf import load_mjcf  # noqa: E402
from prehensile.model.robot_model import PRISMATIC, REVOLUTE  # noqa: E402

DATA = Path(__file__).parent / "data" / "mjcf"


def mujoco_qpos(model, mj, q: np.ndarray) -> np.ndarray:
    """MuJoCo qpos for our q: actuated joints by name, mimic joints from their leader,
    dropped free joints at qpos0."""
    qpos = mj.qpos0.copy()
    for i, joint in enumerate(model.link_joint_names):
        index = model.joint_q_index[i]
        if index < 0:
            continue
        adr = mj.joint(joint).qposadr[0]
        qpos[adr] = model.joint_multiplier[i] * q[index] + model.joint_offset[i]
    return qpos


def assert_matches_mujoco(path: Path, n: int = 1000, seed: int = 0):
    model = load_mjcf(path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(mj)
    q = model.random_configurations(np.random.default_rng(seed), n)
    ours = forward_kinematics(model, q)
    bodies = [(b, model.link_index(mj.body(b).name)) for b in range(1, mj.nbody)]
    for k in range(n):
        data.qpos[:] = mujoco_qpos(model, mj, q[k])
        mujoco.mj_kinematics(mj, data)
        for b, i in bodies:
            np.testing.assert_allclose(ours[k, i, :3, 3], data.xpos[b], atol=1e-9)
            np.testing.assert_allclose(ours[k, i, :3, :3], data.xmat[b].reshape(3, 3), atol=1e-9)
    return model


def test_arm_with_joint_anchors_matches_mujoco():
    model = assert_matches_mujoco(DATA / "arm7.xml")
    assert model.dof == 8
    assert model.joint_names[:7] == tuple(f"j{i}" for i in range(1, 8))
    assert model.continuous[model.joint_index("j3")]
    j4 = model.joint_index("j4")
    assert (model.lower[j4], model.upper[j4]) == pytest.approx(np.radians([-150, -5]))
    # j5 has its anchor at the body origin: the body is the joint's own link
    assert model.link_joint_names[model.link_index("link5")] == "j5"
    assert model.link_joint_names[model.link_index("link1")] == "link1__anchor"


def test_sites_become_frames():
    path = DATA / "arm7.xml"
    model = load_mjcf(path)
    mj = mujoco.MjModel.from_xml_path(str(path))
    data = mujoco.MjData(mj)
    q = model.random_configurations(np.random.default_rng(5))
    data.qpos[:] = mujoco_qpos(model, mj, q)
    mujoco.mj_kinematics(mj, data)
    T = forward_kinematics(model, q)[model.link_index("tcp")]
    np.testing.assert_allclose(T[:3, 3], data.site("tcp").xpos, atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], data.site("tcp").xmat.reshape(3, 3), atol=1e-12)
    assert model.link_parent[model.link_index("tcp")] == model.link_index("link7")


def test_equality_becomes_mimic():
    model = load_mjcf(DATA / "arm7.xml")
    i = model.link_index("finger_right")
    assert model.joint_type[i] == PRISMATIC
    assert model.joint_names[model.joint_q_index[i]] == "finger_left_joint"
    # q_r = a1 q_l + a0 + ref_r - a1 ref_l
    assert model.joint_multiplier[i] == pytest.approx(0.9)
    assert model.joint_offset[i] == pytest.approx(0.002 + 0.01)
    assert "finger_right_joint" not in model.joint_names


def test_body_with_several_joints_and_free_root():
    model = assert_matches_mujoco(DATA / "multi_joint.xml")
    assert model.joint_names == ("rail", "turn", "tilt", "lift_joint")
    path = model.path_to_root("carriage")
    names = [model.link_joint_names[i] for i in path[:-1]]
    assert names == ["carriage__anchor", "tilt", "turn", "rail", "cart__weld"]
    types = [model.joint_type[model.link_index(f"carriage__{j}")] for j in ("rail", "turn", "tilt")]
    assert types == [PRISMATIC, REVOLUTE, REVOLUTE]
    assert not np.isfinite(model.upper[model.joint_index("lift_joint")])


def test_geometry_conversion():
    model = load_mjcf(DATA / "arm7.xml")
    world = model.link_index("world")
    assert model.collisions[world] == ()  # the plane is skipped
    base = model.collisions[model.link_index("base")][0].shape
    assert isinstance(base, Cylinder) and (base.radius, base.length) == pytest.approx((0.06, 0.06))
    link1 = model.collisions[model.link_index("link1")][0]
    assert isinstance(link1.shape, Capsule) and link1.shape.length == pytest.approx(0.15)
    np.testing.assert_allclose(link1.T_link_geom[:3, 3], [0, 0, 0.075], atol=1e-12)
    box = model.collisions[model.link_index("link2")][0].shape
    assert isinstance(box, Box) and box.size == pytest.approx((0.06, 0.06, 0.24))
    assert isinstance(model.collisions[model.link_index("link3")][0].shape, Sphere)
    ellipsoid = model.collisions[model.link_index("link5")][0].shape
    assert isinstance(ellipsoid, Mesh) and ellipsoid.trimesh.extents == pytest.approx([0.06, 0.08, 0.1], rel=1e-6)
    link6 = model.link_index("link6")
    assert len(model.visuals[link6]) == 1 and model.collisions[link6] == ()  # contype = conaffinity = 0


def test_mesh_geom_from_obj(tmp_path):
    trimesh = pytest.importorskip("trimesh")
    box = trimesh.creation.box(extents=[0.1, 0.04, 0.02])
    box.apply_translation([0.3, 0.2, 0.1])  # MuJoCo re-centres the mesh
    box.export(tmp_path / "part.obj")
    xml = tmp_path / "mesh.xml"
    xml.write_text(
        '<mujoco model="mesh"><asset><mesh name="part" file="part.obj"/></asset><worldbody>'
        '<body name="b" pos="0 0 0.1"><joint name="h" axis="0 1 0" pos="0.01 0 0"/>'
        '<geom type="mesh" mesh="part" pos="0.02 0 0"/></body></worldbody></mujoco>'
    )
    model = assert_matches_mujoco(xml, n=50)
    geom = model.collisions[model.link_index("b")][0]
    assert isinstance(geom.shape, Mesh) and geom.shape.path is None
    # the mesh placed by its geom pose occupies the same space as MuJoCo's compiled geom
    mj = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(mj)
    mujoco.mj_kinematics(mj, data)
    T = forward_kinematics(model, np.zeros(1))[model.link_index("b")] @ geom.T_link_geom
    world_vertices = geom.shape.trimesh.vertices @ T[:3, :3].T + T[:3, 3]
    assert world_vertices.min(axis=0) == pytest.approx(data.geom_xpos[0] - [0.05, 0.02, 0.01], abs=1e-6)
    assert geom.shape.trimesh.volume == pytest.approx(0.1 * 0.04 * 0.02, rel=1e-6)


def test_errors_name_the_file(tmp_path):
    with pytest.raises(ModelError, match="malformed.xml.*MuJoCo could not compile"):
        load_mjcf(DATA / "malformed.xml")
    with pytest.raises(ModelError, match="missing.xml"):
        load_mjcf(tmp_path / "missing.xml")
    bad = tmp_path / "broken.xml"
    bad.write_text("<mujoco><worldbody><body></worldbody>")
    with pytest.raises(ModelError, match="broken.xml"):
        load_mjcf(bad)
    ball = tmp_path / "ball.xml"
    ball.write_text('<mujoco><worldbody><body name="a"><joint name="s" type="ball"/>'
                    '<geom size="0.1"/></body></worldbody></mujoco>')
    with pytest.raises(ModelError, match="ball.xml.*ball joint 's'.*valid joint types: hinge, slide"):
        load_mjcf(ball)
    nested = tmp_path / "nested_free.xml"
    nested.write_text('<mujoco><worldbody><body name="a"><geom size="0.1"/><body name="b">'
                      '<freejoint/><geom size="0.1"/></body></body></worldbody></mujoco>')
    with pytest.raises(ModelError, match="nested_free.xml.*free joint"):
        load_mjcf(nested)
    poly = tmp_path / "poly.xml"
    poly.write_text('<mujoco><worldbody><body name="a"><joint name="p" axis="0 0 1"/><geom size="0.1"/>'
                    '<body name="b"><joint name="r" axis="1 0 0"/><geom size="0.1"/></body></body></worldbody>'
                    '<equality><joint joint1="r" joint2="p" polycoef="0 1 0.5 0 0"/></equality></mujoco>')
    with pytest.raises(ModelError, match="poly.xml.*non-linear"):
        load_mjcf(poly)
    urdf_like = tmp_path / "robot.xml"
    urdf_like.write_text("<robot name='x'/>")
    with pytest.raises(ModelError, match="robot.xml.*expected <mujoco>"):
        load_mjcf(urdf_like)


def test_locked_joint_becomes_fixed(tmp_path):
    xml = tmp_path / "locked.xml"
    xml.write_text('<mujoco><worldbody><body name="a"><joint name="p" axis="0 0 1" range="-1 1"/>'
                   '<geom size="0.1"/><body name="b" pos="0.2 0 0"><joint name="r" axis="1 0 0" pos="0 0.1 0"/>'
                   '<geom size="0.05"/></body></body></worldbody>'
                   '<equality><joint joint1="r" polycoef="0.4 0 0 0 0"/></equality></mujoco>')
    model = load_mjcf(xml)
    assert model.joint_names == ("p",)
    mj = mujoco.MjModel.from_xml_path(str(xml))
    data = mujoco.MjData(mj)
    data.qpos[:] = [0.3, 0.4]
    mujoco.mj_kinematics(mj, data)
    T = forward_kinematics(model, np.array([0.3]))[model.link_index("b")]
    np.testing.assert_allclose(T[:3, 3], data.xpos[2], atol=1e-12)
    np.testing.assert_allclose(T[:3, :3], data.xmat[2].reshape(3, 3), atol=1e-12)


def test_a_body_never_collides_with_its_parent_whatever_its_joints(tmp_path):
    """As MuJoCo's filterparent: a two-hinge wrist overlapping its parent is no self-collision."""
    from prehensile.collision import ExactChecker

    for joints in ('<joint name="a" axis="1 0 0"/>', '<joint name="a" axis="1 0 0"/><joint name="b" axis="0 1 0"/>'):
        path = tmp_path / "wrist.xml"
        path.write_text(f"""<mujoco><worldbody><body name="upper"><joint name="s" axis="0 0 1"/>
            <geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.04"/>
            <body name="lower" pos="0 0 0.3">{joints}<geom type="capsule" fromto="0 0 0 0 0 0.3" size="0.04"/>
            <body name="hand" pos="0 0 0.3"><joint name="h" axis="0 0 1"/><geom type="sphere" size="0.3"/></body></body>
            </body></worldbody></mujoco>""")
        model = load_mjcf(path)
        assert frozenset(("lower", "hand")) in model.disabled_collision_pairs
        contacts = {(a, b) for a, b, _ in ExactChecker(model, []).collisions(model.neutral_configuration())}
        assert contacts == {("upper", "hand")}  # the grandparent still collides
