"""Time parameterization: limits, rest at the ends, path following, blending, bad input."""

from __future__ import annotations

import json

import numpy as np
import pytest

from prehensile.errors import PrehensileError
from prehensile.planning import PlanResult, PlanStats, PlanStatus
from prehensile.planning.trajectory import (DEFAULT_ACCELERATION, DEFAULT_VELOCITY, Trajectory, model_limits,
                                            time_parameterize)

TOL = 1e-6  # relative slack on the limits


def _panda_problem():
    import prehensile.robots as robots

    model = robots.load("panda")
    indices = model.chain_q_indices("arm")
    velocity, acceleration = model_limits(model, indices)
    rng = np.random.default_rng(7)
    lower, upper = model.lower[indices], model.upper[indices]
    path = lower + (upper - lower) * rng.uniform(0.2, 0.8, (6, len(indices)))
    return model, indices, path, velocity, acceleration


def _distance_to_polyline(points: np.ndarray, path: np.ndarray) -> np.ndarray:
    """(M,) Euclidean distance of each point to the polyline through path (N, n)."""
    a, d = path[:-1], np.diff(path, axis=0)
    r = np.einsum("mkn,kn->mk", points[:, None] - a, d) / np.einsum("kn,kn->k", d, d)
    foot = a + np.clip(r, 0.0, 1.0)[..., None] * d
    return np.min(np.linalg.norm(points[:, None] - foot, axis=-1), axis=1)


def test_panda_path_respects_limits_rests_at_ends_and_follows_the_polyline():
    model, indices, path, velocity, acceleration = _panda_problem()
    traj = time_parameterize(path, velocity, acceleration, dt=0.01)
    assert traj.duration > 0 and traj.t[0] == 0.0 and np.all(np.diff(traj.t) > 0)
    assert np.allclose(np.diff(traj.t)[:-1], 0.01) and np.diff(traj.t)[-1] <= 0.01 + 1e-12
    assert np.all(np.abs(traj.qd) <= velocity * (1 + TOL))
    assert np.all(np.abs(traj.qdd) <= acceleration * (1 + TOL))
    assert np.array_equal(traj.q[0], path[0]) and np.array_equal(traj.q[-1], path[-1])
    assert np.all(traj.qd[0] == 0) and np.all(traj.qd[-1] == 0) and np.all(traj.qdd[-1] == 0)
    assert np.all(traj.sample(traj.duration + 5.0)[2] == 0)  # held at rest after the end
    assert np.max(_distance_to_polyline(traj.q, path)) < 1e-9
    # every waypoint is visited, at rest
    for waypoint in path[1:-1]:
        k = np.argmin(np.linalg.norm(traj.q - waypoint, axis=1))
        assert np.linalg.norm(traj.q[k] - waypoint) < 1e-3 and np.linalg.norm(traj.qd[k]) < 0.05
    # sampling between the stored samples stays on the path too
    q, qd, qdd = traj.sample(np.linspace(0.0, traj.duration, 2345))
    assert q.shape == (2345, 7) and qd.shape == qdd.shape == q.shape
    assert np.max(_distance_to_polyline(q, path)) < 1e-5
    assert np.all(np.abs(qd) <= velocity * (1 + 1e-3))
    assert np.allclose(traj.sample(traj.t[5])[0], traj.q[5])


@pytest.mark.parametrize("acceleration", [15.0, 1e4])
def test_sampling_between_samples_follows_the_motion_within_the_limits(acceleration):
    """Stops at corners far shorter than the period (1e4 rad/s^2, 10 ms): sample() evaluates
    the motion itself, whose velocity and finite differences stay within the limits; a cubic
    through the samples would overshoot the velocity limit by a third."""
    path, velocity = np.array([[0.0, 0.0], [0.5, 0.2], [0.6, -0.4]]), 2.175
    traj = time_parameterize(path, velocity, acceleration, dt=0.01)
    t = np.arange(0.0, traj.duration, 1e-5)
    q, qd, qdd = traj.sample(t)
    assert np.max(np.abs(qd)) <= velocity * (1 + TOL) and np.max(np.abs(qdd)) <= acceleration * (1 + TOL)
    assert np.max(np.abs(np.diff(q, axis=0))) <= velocity * 1e-5 * (1 + TOL)
    assert np.max(_distance_to_polyline(q, path)) < 1e-9
    np.testing.assert_allclose(traj.sample(traj.t), (traj.q, traj.qd, traj.qdd), atol=1e-12)
    samples_only = Trajectory(traj.t, traj.q, traj.qd, traj.qdd)  # no motion: the cubic between samples
    assert samples_only.motion is None and traj.motion is not None
    np.testing.assert_allclose(samples_only.sample(traj.t[3])[0], traj.q[3])
    overshoot = np.max(np.abs(samples_only.sample(t)[1])) / velocity
    assert (overshoot > 1.2) == (acceleration > 100)


def test_same_input_same_output_and_json():
    _, _, path, velocity, acceleration = _panda_problem()
    names = tuple(f"j{i}" for i in range(7))
    a = time_parameterize(path, velocity, acceleration, joint_names=names)
    b = time_parameterize(path, velocity, acceleration, joint_names=names)
    assert np.array_equal(a.t, b.t) and np.array_equal(a.q, b.q) and np.array_equal(a.qdd, b.qdd)
    data = json.loads(json.dumps(a.to_dict()))
    assert data["joint_names"] == list(names) and data["duration"] == pytest.approx(a.duration)
    assert np.array_equal(np.array(data["q"]), a.q)
    assert time_parameterize(path, velocity, acceleration).to_dict()["joint_names"] == []
    assert a == a and a != b  # compared by identity: equal arrays do not raise an ambiguous truth value
    result = PlanResult(PlanStatus.SUCCESS, path, PlanStats())
    assert result == result and result != PlanResult(PlanStatus.SUCCESS, path.copy(), PlanStats())


def test_single_segment_matches_the_analytic_trapezoid():
    a, b = np.array([0.0, 0.0]), np.array([2.0, -0.5])
    velocity, acceleration = np.array([1.0, 1.0]), np.array([2.0, 2.0])
    traj = time_parameterize(np.stack([a, b]), velocity, acceleration)
    # joint 0 binds: accelerate at 2 rad/s^2 to 1 rad/s (0.25 rad), cruise 1.5 rad, decelerate
    assert traj.duration == pytest.approx(0.5 + 1.5 + 0.5, rel=1e-4)
    assert np.max(np.abs(traj.qd[:, 0])) == pytest.approx(1.0, rel=1e-6)


def test_repeats_and_collinear_waypoints_do_not_stop_the_motion():
    a, b = np.array([0.0, 0.0, 0.0]), np.array([1.0, 0.5, -0.2])
    dense = np.concatenate([[a, a], np.linspace(a, b, 17), [b]])
    single = time_parameterize(np.stack([a, b]), 1.0, 2.0)
    traj = time_parameterize(dense, 1.0, 2.0)
    assert traj.duration == pytest.approx(single.duration, rel=1e-12)
    assert np.array_equal(traj.q, single.q)


def test_single_configuration_and_bad_input():
    traj = time_parameterize(np.array([[0.1, 0.2], [0.1, 0.2]]), 1.0, 1.0)
    assert traj.duration == 0.0 and traj.q.shape == (1, 2) and np.all(traj.qd == 0)
    assert np.allclose(traj.sample(np.array([0.0, 3.0]))[0], [[0.1, 0.2], [0.1, 0.2]])
    path = np.array([[0.0, 0.0], [1.0, 1.0]])
    with pytest.raises(PrehensileError, match="path"):
        time_parameterize(np.array([[0.0, np.nan], [1.0, 1.0]]), 1.0, 1.0)
    with pytest.raises(PrehensileError, match="path"):
        time_parameterize(np.zeros((0, 2)), 1.0, 1.0)
    with pytest.raises(PrehensileError, match="velocity_limits"):
        time_parameterize(path, np.array([1.0, 0.0]), 1.0)
    with pytest.raises(PrehensileError, match="acceleration_limits"):
        time_parameterize(path, 1.0, np.ones(3))
    for dt in (0.0, float("inf")):
        with pytest.raises(PrehensileError, match="time_parameterize: dt must be > 0 and finite, got"):
            time_parameterize(path, 1.0, 1.0, dt=dt)
    for step in (0.0, -0.01, float("nan")):
        with pytest.raises(PrehensileError, match="time_parameterize: blend_step must be > 0, got"):
            time_parameterize(path, 1.0, 1.0, blend_check=lambda a, b: True, blend_step=step)
    with pytest.raises(PrehensileError, match="joint names"):
        Trajectory(np.zeros(1), np.zeros((1, 2)), np.zeros((1, 2)), np.zeros((1, 2)), ("a",))
    with pytest.raises(PrehensileError, match=r"takes 1e\+09 s, 1e\+11 samples at dt = 0.01 s, more than 1000000"):
        time_parameterize(path, 1e-9, 1e-9)


def test_blending_only_when_checked():
    _, _, path, velocity, acceleration = _panda_problem()
    # a dense, gently curved path: stopping at every waypoint is slow, blending is not
    s = np.linspace(0.0, 1.0, 25)[:, None]
    curved = path[0] + s * (path[1] - path[0]) + 0.3 * np.sin(np.pi * s) * np.ones(7)
    stops = time_parameterize(curved, velocity, acceleration)
    chords = []
    blended = time_parameterize(curved, velocity, acceleration, blend_check=lambda a, b: chords.append((a, b)) or True)
    assert len(chords) > len(curved) and blended.duration < 0.5 * stops.duration
    assert np.all(np.abs(blended.qd) <= velocity * (1 + TOL))
    assert np.all(np.abs(blended.qdd) <= acceleration * (1 + TOL))
    assert np.all(blended.qd[0] == 0) and np.all(blended.qd[-1] == 0)
    assert np.array_equal(blended.q[-1], curved[-1])
    assert np.max(_distance_to_polyline(blended.q, curved)) < 0.01  # close to, not on, the polyline
    rejected = time_parameterize(curved, velocity, acceleration, blend_check=lambda a, b: False)
    assert np.array_equal(rejected.q, stops.q)


def test_blending_is_kept_only_when_it_is_faster():
    """A path that turns back on itself: the spline overshoots and takes longer than stopping."""
    reversal = np.array([[0.0, 0.0], [1.0, 0.0], [0.0, 0.01]])
    stops = time_parameterize(reversal, 1.0, 2.0)
    spline = time_parameterize(reversal, 1.0, 2.0, blend_check=lambda a, b: True)
    assert np.array_equal(spline.q, stops.q)


def test_blending_never_makes_a_motion_slower():
    """Sharp turns: TOPP-RA meets the limits only at its gridpoints, and the spline's
    curvature between them needed slowing down; slowed, it must still beat stopping at the
    corners to be kept (it once was kept and then took up to 21 % longer)."""
    rng = np.random.default_rng(1)
    for _ in range(100):
        count, n = rng.integers(3, 12), rng.integers(2, 8)
        path = np.cumsum(rng.normal(size=(count, n)), axis=0)
        velocity, acceleration = rng.uniform(0.5, 2.0, n), rng.uniform(1.0, 5.0, n)
        stops = time_parameterize(path, velocity, acceleration).duration
        blended = time_parameterize(path, velocity, acceleration, blend_check=lambda a, b: True).duration
        assert blended <= stops * (1 + 1e-3)  # the samples' residual excess may slow it by a hair


def test_blended_wiggly_paths_keep_the_limits_at_every_sample():
    # dense, wiggling paths like an elastic band's: the spline's curvature peaks at its knots
    rng = np.random.default_rng(0)
    velocity, acceleration = np.full(3, 1.0), np.full(3, 2.0)
    for _ in range(5):
        path = np.cumsum(rng.uniform(-0.05, 0.05, (100, 3)) + 0.02, axis=0)
        traj = time_parameterize(path, velocity, acceleration, blend_check=lambda a, b: True)
        assert np.all(np.abs(traj.qd) <= velocity * (1 + TOL))
        assert np.all(np.abs(traj.qdd) <= acceleration * (1 + TOL))
        assert np.max(np.abs(traj.qdd) / acceleration) > 0.9  # time-optimal: a joint at its limit


def test_straight_segments_get_the_exact_time_optimal_profile():
    # 1 rad at 1 rad/s, 2 rad/s^2: 0.5 s to accelerate, 0.5 s at speed, 0.5 s to brake
    traj = time_parameterize(np.array([[0.0, 0.0], [1.0, 0.5]]), np.ones(2), np.full(2, 2.0), dt=0.001)
    assert traj.duration == pytest.approx(1.5) and np.max(np.abs(traj.qd[:, 0])) == pytest.approx(1.0)
    short = time_parameterize(np.array([[0.0], [0.1]]), 1.0, 2.0)  # a triangle: never at full speed
    assert short.duration == pytest.approx(2 * np.sqrt(0.1 / 2.0))
    q = np.zeros(3)
    for tiny in (1e-5, 1e-6, 1e-7):  # TOPP-RA called such segments uncontrollable
        path = np.stack([q, q + 0.5, q + 0.5 + [0.0, tiny, 0.0], q + [1.0, 0.0, 0.0]])
        traj = time_parameterize(path, 2.0, 2.0)
        assert np.all(np.abs(traj.qd) <= 2.0 * (1 + TOL)) and np.array_equal(traj.q[-1], path[-1])


def test_model_limits():
    model, indices, _, velocity, acceleration = _panda_problem()
    assert np.array_equal(velocity, model.velocity_limit[indices])
    assert np.all(acceleration == DEFAULT_ACCELERATION) and acceleration.shape == (7,)
    from dataclasses import replace

    unlimited = replace(model, velocity_limit=np.full(model.dof, np.inf))
    assert np.all(model_limits(unlimited, acceleration=5.0)[0] == DEFAULT_VELOCITY)
    assert np.all(model_limits(unlimited, acceleration=5.0)[1] == 5.0)
    assert model_limits(model, [0, 2], acceleration=[1.0, 2.0])[1].tolist() == [1.0, 2.0]
    for bad, message in [({"indices": [0, 8]}, "indices must be variable indices in \\[0, 8\\)"),
                         ({"indices": ["panda_joint1"]}, "indices must be"),
                         ({"acceleration": [1.0, 2.0]}, "acceleration must be one positive number or 8"),
                         ({"acceleration": -1.0}, "acceleration must be"),
                         ({"acceleration": float("nan")}, "acceleration must be")]:
        with pytest.raises(PrehensileError, match=message):
            model_limits(model, **bad)


def test_a_spline_that_fails_in_one_place_is_split_there_not_dropped():
    """A check that rejects the spline near one corner (an elastic band's waypoint at a joint
    limit, where the spline overshoots) stops the motion near that corner only."""
    _, _, path, velocity, acceleration = _panda_problem()
    s = np.linspace(0.0, 1.0, 33)[:, None]
    curved = path[0] + s * (path[1] - path[0]) + 0.3 * np.sin(np.pi * s) * np.ones(7)
    stops = time_parameterize(curved, velocity, acceleration)
    whole = time_parameterize(curved, velocity, acceleration, blend_check=lambda a, b: True)
    near = curved[5]
    check = lambda a, b: min(np.abs(a - near).max(), np.abs(b - near).max()) > 0.02  # noqa: E731
    split = time_parameterize(curved, velocity, acceleration, blend_check=check)
    assert whole.duration < split.duration < 0.5 * stops.duration
    assert np.all(np.abs(split.qd) <= velocity * (1 + TOL)) and np.all(np.abs(split.qdd) <= acceleration * (1 + TOL))
    assert np.array_equal(split.q[0], curved[0]) and np.array_equal(split.q[-1], curved[-1])
    close = np.abs(split.q - near).max(axis=1) < 0.015  # only the polyline comes this close
    assert close.any() and np.max(_distance_to_polyline(split.q[close], curved)) < 1e-9
    assert np.max(_distance_to_polyline(split.q, curved)) > 1e-3  # blended elsewhere


def test_blended_paths_of_any_scale_are_timed():
    """Splines through corners micrometres to metres apart (escape and approach segments end a
    planned path) get a profile within the limits; TOPP-RA once found none for runs a few mm long."""
    rng = np.random.default_rng(7)
    for _ in range(200):
        n, count = rng.integers(1, 8), rng.integers(3, 9)
        steps = rng.normal(size=(count - 1, n))
        steps *= (10.0 ** rng.uniform(-6, 1, count - 1) / np.linalg.norm(steps, axis=1))[:, None]
        path = np.concatenate([np.zeros((1, n)), np.cumsum(steps, axis=0)])
        velocity, acceleration = rng.uniform(0.1, 3.0, n), rng.uniform(0.1, 10.0, n)
        traj = time_parameterize(path, velocity, acceleration, blend_check=lambda a, b: True)
        assert np.all(np.abs(traj.qd) <= velocity * (1 + TOL)) and np.all(np.abs(traj.qdd) <= acceleration * (1 + TOL))
        assert np.array_equal(traj.q[0], path[0]) and np.array_equal(traj.q[-1], path[-1])


def test_a_spline_toppra_cannot_time_stops_at_its_corners(monkeypatch):
    import prehensile.planning.trajectory as trajectory_module

    _, _, path, velocity, acceleration = _panda_problem()
    monkeypatch.setattr(trajectory_module, "_toppra_knots", lambda *args: None)
    traj = time_parameterize(path, velocity, acceleration, blend_check=lambda a, b: True)
    assert np.array_equal(traj.q, time_parameterize(path, velocity, acceleration).q)
