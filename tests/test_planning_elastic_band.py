"""Elastic band: pushes a Panda path away from a box, tightens, never breaks validity."""

from __future__ import annotations

import importlib

import numpy as np
import pytest

from prehensile.collision.world import Obstacle
from prehensile.errors import PrehensileError
from prehensile.model.geometry import Box
from prehensile.planning.elastic_band import ElasticBandSettings, elastic_band, external_force
from prehensile.spatial import make_pose

elastic_band_module = importlib.import_module("prehensile.planning.elastic_band")  # the package exports the function

# the hand sweeps over a box (joint 1 from -1 to 1); at the middle its fingers are ~1 cm above it
Q_START = np.array([-1.0, 0.3, 0.0, -1.8, 0.0, 2.1, 0.8, 0.02])
Q_GOAL = np.array([1.0, 0.3, 0.0, -1.8, 0.0, 2.1, 0.8, 0.02])
BOX = Obstacle("box", Box((0.1, 0.1, 0.1)), make_pose(position=[0.633, 0.0, 0.207]))


@pytest.fixture(scope="module")
def panda():
    import prehensile.robots as robots

    try:
        return robots.load("panda")
    except PrehensileError as error:
        pytest.skip(str(error))


def _context(model, obstacles):
    from prehensile.planning.context import PlanningContext

    return PlanningContext(model, obstacles, joints="arm", q_ref=Q_START)


def _world_clearance(ctx, path: np.ndarray) -> np.ndarray:
    """(N,) exact robot-vs-world distance (m) at each waypoint."""
    return np.array([min(p.distance for p in ctx.exact.closest_points(q)) for q in path])


def _valid(ctx, path: np.ndarray) -> bool:
    return all(ctx.is_valid(q) for q in path) and all(ctx.check_motion(a, b) for a, b in zip(path[:-1], path[1:]))


def test_closest_points_are_consistent(panda):
    ctx = _context(panda, [BOX])
    middle = 0.5 * (Q_START + Q_GOAL)
    pairs = ctx.exact.closest_points(middle)
    assert len(pairs) == sum(1 for g in ctx.exact.model.collisions if g)  # one per link with geometry
    for pair in pairs:
        assert pair.other == "box" and pair.point_on_robot.shape == pair.point_on_other.shape == (3,)
        assert np.linalg.norm(pair.point_on_robot - pair.point_on_other) == pytest.approx(pair.distance, abs=1e-6)
        assert np.all(np.abs(pair.point_on_other - [0.633, 0.0, 0.207]) <= 0.05 + 1e-6)  # on the box
    near = ctx.exact.closest_points(middle, max_distance=0.05)
    assert [(p.link, p.distance) for p in near] == [(p.link, p.distance) for p in pairs if p.distance <= 0.05]
    assert 0 < len(near) < len(pairs)


def test_band_moves_a_path_away_from_a_box(panda):
    ctx = _context(panda, [BOX])
    path = np.stack([Q_START, Q_GOAL])
    assert _valid(ctx, path)
    band = elastic_band(ctx, path, ElasticBandSettings(d_min=0.05))
    assert len(band) > 10
    assert np.array_equal(band[0], Q_START) and np.array_equal(band[-1], Q_GOAL)
    assert _valid(ctx, band)
    assert np.all(band[:, 7] == Q_START[7])  # the finger is not planned: untouched
    before = ctx.exact.min_distance(np.linspace(Q_START, Q_GOAL, len(band)))
    after = ctx.exact.min_distance(band)
    assert before.min() < 0.015 and after.min() > 0.04
    assert np.array_equal(band, elastic_band(ctx, path, ElasticBandSettings(d_min=0.05)))  # deterministic


def test_external_force_points_away_from_the_obstacle(panda):
    ctx = _context(panda, [BOX])
    middle = 0.5 * (Q_START + Q_GOAL)
    force = external_force(ctx, middle, d_min=0.05)
    assert np.linalg.norm(force) > 0
    q = middle.copy()
    q[ctx.space.indices] += 0.05 * force / np.linalg.norm(force)
    assert _world_clearance(ctx, q[None])[0] > _world_clearance(ctx, middle[None])[0] + 0.005
    # one waypoint, pushed only by the obstacle: its clearance grows, the ends stay
    path = np.stack([Q_START, middle, Q_GOAL])
    band = elastic_band(ctx, path, ElasticBandSettings(k_int=0.0, max_iterations=3, max_spacing=None))
    assert len(band) == 3 and np.array_equal(band[[0, 2]], path[[0, 2]])
    assert _world_clearance(ctx, band[1:2])[0] > _world_clearance(ctx, path[1:2])[0] + 0.01


def test_band_tightens_a_detour_far_from_obstacles(panda):
    far = Obstacle("far", Box((0.1, 0.1, 0.1)), make_pose(position=[-1.0, -1.0, 0.05]))
    ctx = _context(panda, [far])
    detour = Q_START.copy()
    detour[[1, 3]] += [-0.3, 0.3]
    path = np.stack([Q_START, 0.5 * (Q_START + Q_GOAL) + (detour - Q_START), Q_GOAL])
    assert _valid(ctx, path)
    band = elastic_band(ctx, path, ElasticBandSettings(k_int=0.05, max_iterations=20, max_spacing=0.1))
    length = ctx.space.path_length
    assert length(ctx.space.active(band)) < 0.9 * length(ctx.space.active(path))
    assert np.array_equal(band[[0, -1]], path[[0, -1]]) and _valid(ctx, band)


class _Rejecting:
    """A context whose motion check refuses everything (the exact certification of the input
    path still passes)."""

    def __init__(self, ctx):
        self.model, self.space, self.exact, self.is_valid = ctx.model, ctx.space, ctx.exact, ctx.is_valid
        self.spheres, self.sphere_model = ctx.spheres, ctx.sphere_model
        self.certifier, self.certify_resolution, self.resolution = ctx.certifier, ctx.certify_resolution, ctx.resolution

    def check_motions(self, qa, qb, resolution=None) -> np.ndarray:
        return np.zeros(len(qa), dtype=bool)


def test_rejected_updates_leave_the_path_unchanged(panda):
    ctx = _Rejecting(_context(panda, [BOX]))
    path = np.stack([Q_START, Q_GOAL])
    band = elastic_band(ctx, path, ElasticBandSettings(max_spacing=0.2))
    t = np.linspace(0.0, 1.0, len(band))[:, None]
    assert np.allclose(band, (1 - t) * Q_START + t * Q_GOAL)


def test_subdividing_keeps_every_waypoint_exactly(panda):
    ctx = _context(panda, [])
    rng, paths = np.random.default_rng(0), 0
    while paths < 20:  # a + 1.0 * (b - a) differs from b in the last bit for some of these
        goal = Q_START.copy()
        goal[:7] = rng.uniform(ctx.space.lower, ctx.space.upper)
        path = np.stack([Q_START, 0.5 * (Q_START + goal), goal])
        if not _valid(ctx, path):
            continue
        paths += 1
        band = elastic_band(ctx, path, ElasticBandSettings(max_iterations=0))
        assert len(band) > 3 and all((band == q).all(axis=1).any() for q in path)


def test_the_ball_prefilter_changes_nothing(panda, monkeypatch):
    """Waypoints whose covering balls keep d_min from the world skip the exact distance queries:
    the band is the same as with every waypoint queried."""
    ctx = _context(panda, [BOX])
    path = np.stack([Q_START, Q_GOAL])
    settings = ElasticBandSettings(max_spacing=0.2, max_iterations=20)
    near = elastic_band_module._near_obstacles(ctx, elastic_band(ctx, path, settings), settings.d_min)
    assert near.any() and not near.all()
    filtered = elastic_band(ctx, path, settings)
    monkeypatch.setattr(elastic_band_module, "_near_obstacles", lambda ctx, path, d_min: np.ones(len(path), bool))
    np.testing.assert_array_equal(elastic_band(ctx, path, settings), filtered)


def test_a_time_budget_stops_the_iterations(panda, monkeypatch):
    """A clock that reads one second later at each call: a 2.5 s budget (read once at the
    start) ends the band after its third iteration, as three iterations without a budget."""
    ctx = _context(panda, [BOX])
    path = np.stack([Q_START, Q_GOAL])
    three = elastic_band(ctx, path, ElasticBandSettings(max_iterations=3, tolerance=0.0))
    ticks = iter(range(1000))
    monkeypatch.setattr(elastic_band_module, "clock", lambda: float(next(ticks)))
    cut = elastic_band(ctx, path, ElasticBandSettings(max_iterations=100, tolerance=0.0, time_budget_s=2.5))
    assert next(ticks) == 4 and np.array_equal(cut, three)


def test_a_colliding_input_path_is_refused(panda):
    """The hand sweeps through a box on the second edge: an error names that edge and link."""
    low = Obstacle("low box", Box((0.1, 0.1, 0.3)), make_pose(position=[0.633, 0.0, 0.15]))
    ctx = _context(panda, [low])
    middle = Q_START.copy()
    middle[0] = -0.5
    with pytest.raises(PrehensileError, match=r"edge 1 \(waypoint 1 to 2\) is not: link panda_\w+ hits an obstacle"):
        elastic_band(ctx, np.stack([Q_START, middle, Q_GOAL]))


def test_bad_settings_and_path(panda):
    with pytest.raises(PrehensileError, match="ElasticBandSettings.d_min must be > 0 and finite, got 0.0"):
        ElasticBandSettings(d_min=0.0)
    with pytest.raises(PrehensileError, match="ElasticBandSettings.d_min must be > 0 and finite, got inf"):
        ElasticBandSettings(d_min=np.inf)  # every pair would push with an infinite force
    with pytest.raises(PrehensileError, match="ElasticBandSettings.k_int must be >= 0 and finite, got -1.0"):
        ElasticBandSettings(k_int=-1.0)
    with pytest.raises(PrehensileError, match="ElasticBandSettings.max_spacing must be > 0 or None, got 0"):
        ElasticBandSettings(max_spacing=0)
    with pytest.raises(PrehensileError, match="ElasticBandSettings.certify_retries must be an integer >= 0, got -1"):
        ElasticBandSettings(certify_retries=-1)
    with pytest.raises(PrehensileError, match="ElasticBandSettings.time_budget_s must be > 0 and finite or None"):
        ElasticBandSettings(time_budget_s=0.0)
    ctx = _context(panda, [])
    with pytest.raises(PrehensileError, match=r"elastic_band: path must have shape \(N >= 1, 8\)"):
        elastic_band(ctx, np.zeros((0, 8)))
    moved = np.stack([Q_START, Q_START])
    moved[1, 7] = 0.03  # a finger joint the context does not plan
    with pytest.raises(PrehensileError, match=r"elastic_band: the path moves joints .*\(panda_finger_joint1; planned"):
        elastic_band(ctx, moved)
