"""Forward kinematics and Jacobians against pinocchio and finite differences."""

from __future__ import annotations

import numpy as np
import pytest

from conftest import erd_robot
from pinocchio_reference import PinocchioReference
from prehensile.errors import PrehensileError
from prehensile.kinematics import forward_kinematics, frame_jacobian, link_pose
from prehensile.model import load_urdf

ERD_URDFS = [
    "panda_description/urdf/panda.urdf",
    "ur_description/urdf/ur5_robot.urdf",
    "xarm_description/urdf/xarm7.urdf",
    "tiago_description/robots/tiago.urdf",  # continuous wheels, prismatic torso
    "pr2_description/urdf/pr2.urdf",  # mimic joints, continuous joints
    "romeo_description/urdf/romeo.urdf",  # humanoid tree
]


@pytest.fixture(scope="module", params=ERD_URDFS, ids=lambda p: p.split("/")[-1])
def erd(request):
    path = erd_robot(request.param)
    return load_urdf(path), path


def test_fk_matches_pinocchio_on_example_robots(erd):
    model, path = erd
    reference = PinocchioReference(model, path)
    q = model.random_configurations(np.random.default_rng(1), 2000)
    ours = forward_kinematics(model, q)
    worst = max(np.abs(ours[i] - reference.link_poses(q[i])).max() for i in range(len(q)))
    assert worst < 1e-9


def test_configurations_outside_the_limits_are_posed_as_given(erd):
    """forward_kinematics does not clip q to the limits (nor does pinocchio); within_limits tells."""
    model, path = erd
    limited = np.flatnonzero(np.isfinite(model.lower) & np.isfinite(model.upper))
    q = model.neutral_configuration()
    q[limited] = np.where(limited % 2, model.upper[limited] + 0.3, model.lower[limited] - 0.3)
    assert limited.size and not model.within_limits(q)
    poses = forward_kinematics(model, q)
    assert np.abs(poses - PinocchioReference(model, path).link_poses(q)).max() < 1e-9
    assert not np.allclose(poses, forward_kinematics(model, np.clip(q, model.lower, model.upper)))


def test_jacobian_matches_pinocchio_and_finite_differences(erd):
    import pinocchio as pin

    model, path = erd
    reference = PinocchioReference(model, path)
    rng = np.random.default_rng(2)
    tip = model.link_names[max(range(model.n_links), key=lambda i: len(model.path_to_root(i)))]
    for q in model.random_configurations(rng, 20):
        for frame, pin_frame in (("world", pin.LOCAL_WORLD_ALIGNED), ("local", pin.LOCAL)):
            _, J = frame_jacobian(model, q, tip, frame=frame)
            pin_q = reference.pin_q(q)
            fid = reference.pin_model.getFrameId(tip)
            J_pin = pin.computeFrameJacobian(reference.pin_model, reference.data, pin_q, fid, pin_frame)
            # map pinocchio velocity columns to ours (mimic columns add onto their leader)
            mapped = np.zeros_like(J)
            for link, joint_name in enumerate(model.link_joint_names):
                if joint_name and model.joint_q_index[link] >= 0 and reference.pin_model.existJointName(joint_name):
                    col = reference.pin_model.joints[reference.pin_model.getJointId(joint_name)].idx_v
                    mapped[:, model.joint_q_index[link]] += model.joint_multiplier[link] * J_pin[:, col]
            assert np.abs(J - mapped).max() < 1e-9


def finite_difference_jacobian(model, q, link, T_link_frame, eps=1e-6):
    """Central differences of the frame's position and orientation, world axes."""
    J = np.zeros((6, model.dof))
    for k in range(model.dof):
        dq = np.zeros(model.dof)
        dq[k] = eps
        T_plus = link_pose(model, q + dq, link, T_link_frame)
        T_minus = link_pose(model, q - dq, link, T_link_frame)
        J[:3, k] = (T_plus[:3, 3] - T_minus[:3, 3]) / (2 * eps)
        dR = T_plus[:3, :3] @ T_minus[:3, :3].T
        J[3:, k] = np.array([dR[2, 1] - dR[1, 2], dR[0, 2] - dR[2, 0], dR[1, 0] - dR[0, 1]]) / (4 * eps)
    return J


def test_jacobian_with_tool_offset_matches_finite_differences(erd):
    model, _ = erd
    rng = np.random.default_rng(3)
    T_link_tool = np.eye(4)
    T_link_tool[:3, 3] = [0.05, -0.02, 0.1]
    for link in rng.choice(model.link_names[1:], size=3, replace=False):
        for q in model.random_configurations(rng, 5):
            _, J = frame_jacobian(model, q, link, T_link_tool)
            assert np.abs(J - finite_difference_jacobian(model, q, link, T_link_tool)).max() < 1e-6


def test_batched_equals_single_and_keeps_batch_shape(erd):
    model, _ = erd
    q = model.random_configurations(np.random.default_rng(4), 12).reshape(3, 4, model.dof)
    batched = forward_kinematics(model, q)
    assert batched.shape == (3, 4, model.n_links, 4, 4)
    assert np.array_equal(batched[1, 2], forward_kinematics(model, q[1, 2]))
    pose, J = frame_jacobian(model, q, model.link_names[-1])
    assert pose.shape == (3, 4, 4, 4) and J.shape == (3, 4, 6, model.dof)
    assert np.allclose(J[2, 1], frame_jacobian(model, q[2, 1], model.link_names[-1])[1])


def test_base_pose_moves_every_link(erd):
    model, _ = erd
    q = model.random_configurations(np.random.default_rng(5))
    T_world_base = np.eye(4)
    T_world_base[:3, :3] = [[0, -1, 0], [1, 0, 0], [0, 0, 1]]
    T_world_base[:3, 3] = [1.0, 2.0, 0.5]
    assert np.allclose(forward_kinematics(model, q, T_world_base), T_world_base @ forward_kinematics(model, q))
    link = model.link_names[-1]
    for bad, message in [(np.eye(3), r"expected shape \(\.\.\., 4, 4\)"),
                         (np.ones((4, 4)), "upper-left 3x3 block is not a rotation"),
                         (np.tile(np.eye(4), (2, 1, 1)), r"expected one pose \(4, 4\), got \(2, 4, 4\)")]:
        for call in (lambda: forward_kinematics(model, q, bad),
                     lambda: frame_jacobian(model, q, link, T_world_base=bad)):
            with pytest.raises(PrehensileError, match="T_world_base: " + message):
                call()
    for call in (frame_jacobian, link_pose):
        with pytest.raises(PrehensileError, match="T_link_frame: expected shape"):
            call(model, q, link, T_link_frame=np.eye(3))
    with pytest.raises(PrehensileError, match="T_link_frame: upper-left 3x3 block is not a rotation"):
        link_pose(model, q, link, T_link_frame=np.diag([2.0, 2.0, 2.0, 1.0]))


def test_bad_configurations_are_clear_errors(erd):
    model, _ = erd
    with pytest.raises(PrehensileError, match=f"expected shape \\(\\.\\.\\., {model.dof}\\)"):
        forward_kinematics(model, np.zeros(model.dof + 1))
    q = np.zeros((3, model.dof))
    q[2, 0] = np.nan
    with pytest.raises(PrehensileError, match=r"NaN or infinite values at batch index \(2,\)$"):
        forward_kinematics(model, q)
    with pytest.raises(PrehensileError, match="NaN"):
        forward_kinematics(model, q[2])
    with pytest.raises(KeyError, match="no link 'nope'"):
        frame_jacobian(model, q[0], "nope")


def test_polynomial_sincos_matches_libm():
    from numba import njit

    from prehensile.kinematics.kernels import sincos, sincos_into

    @njit
    def worst(xs):
        error = 0.0
        for x in xs:
            s, c = sincos(x)
            error = max(error, abs(s - np.sin(x)), abs(c - np.cos(x)))
        return error

    rng = np.random.default_rng(0)
    quadrant_edges = np.arange(-8, 9) * np.pi / 4
    near = np.concatenate([rng.uniform(-8, 8, 200_000), quadrant_edges, np.nextafter(quadrant_edges, 0)])
    assert worst(near) <= 2.3e-16
    assert worst(rng.uniform(-100, 100, 100_000)) <= 1.2e-14
    assert np.all(np.isnan(njit(lambda x: sincos(x))(np.nan)))
    sines, cosines = np.empty_like(near), np.empty_like(near)
    njit(lambda x, s, c: sincos_into(x, s, c))(near, sines, cosines)
    assert np.abs(sines - np.sin(near)).max() <= 2.3e-16 and np.abs(cosines - np.cos(near)).max() <= 2.3e-16
