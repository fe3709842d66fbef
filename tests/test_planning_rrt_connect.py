"""RRT-Connect, motion checks, motion bounds and shortcutting (prehensile.planning)."""

from __future__ import annotations

import dataclasses
import importlib
import logging
import re
import time

import numpy as np
import pytest

from prehensile import robots
from prehensile.collision.spheres import SphereModel, generate_sphere_model
from prehensile.collision.world import Obstacle
from prehensile.errors import PrehensileError
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.model.robot_model import Chain
from prehensile.model.geometry import Box, Capsule, Geometry, Mesh, Sphere
from prehensile.planning import (
    AttachedObject, ElasticBandSettings, PlanningContext, PlanResult, PlanStats, PlanStatus, RRTConnectSearch,
    RRTConnectSettings,
    certify_path, elastic_band, rrt_connect, shortcut,
)
from prehensile.clock import COMPILING, clock
from prehensile.collision import sphere_kernels as SK
from prehensile.planning.certify import CertifyReport, certified_escape, refine_after_failure
from prehensile.planning.context import ball_joint_weights, motion_weights
from prehensile.planning.cspace import IDLE_WEIGHT
from prehensile.planning.jplus_rrt import JPlusRRTSettings, jplus_rrt
from prehensile.planning.kernels import BLOCKED, FREE, NO_LIMIT, _scales, motion_free
from prehensile.planning.shortcut import MAX_INSERTED, prune, shortcut_rows, waypoint_marks
from prehensile.spatial import make_pose

from conftest import MBM, WEDGE, require_shared

ALONG_X = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])  # rotates a shape's z axis onto x
FAST = RRTConnectSettings(time_budget_s=2.0)


def _arm(axes=("z", "z", "z"), flange=False):
    """Three capsule links of 0.4, 0.4, 0.25 m along x, joints about ``axes``, on a base disc
    at the origin; a geometry-less ``tip`` 0.3 m along the last link (turned about x by a
    fourth joint if ``flange``); the chain ``arm`` runs from base to tip."""
    unit = {"x": [1.0, 0, 0], "y": [0, 1.0, 0], "z": [0, 0, 1.0]}
    def capsule(length):
        return Geometry(Capsule(0.04, length - 0.08), make_pose(ALONG_X, [length / 2, 0, 0]))

    links = [LinkSpec("base", collisions=[Geometry(Box((0.16, 0.16, 0.1)))]),
             LinkSpec("l1", collisions=[capsule(0.4)]), LinkSpec("l2", collisions=[capsule(0.4)]),
             LinkSpec("l3", collisions=[capsule(0.25)]), LinkSpec("tip")]
    joints = [JointSpec("j1", "revolute", "base", "l1", make_pose(position=[0, 0, 0.1]), unit[axes[0]], -3.0, 3.0),
              JointSpec("j2", "revolute", "l1", "l2", make_pose(position=[0.4, 0, 0]), unit[axes[1]], -2.6, 2.6),
              JointSpec("j3", "revolute", "l2", "l3", make_pose(position=[0.4, 0, 0]), unit[axes[2]], -2.6, 2.6),
              JointSpec("jt", "revolute" if flange else "fixed", "l3", "tip", make_pose(position=[0.3, 0, 0]),
                        unit["x"], -3.0, 3.0)]
    return build_model("arm", "test", links, joints, [Chain("arm", "base", "tip", ())])


def _box(name, center, size):
    return Obstacle(name, Box(tuple(size)), make_pose(position=center))


@pytest.fixture(scope="module")
def arm():
    model = _arm()
    return model, generate_sphere_model(model, cache=False)


def _exact_free_path(ctx, path, step=0.002):
    """Every segment of path sampled every ``step`` m (weighted metric) is free for coal."""
    idx = ctx.space.indices
    q = [a + np.linspace(0, 1, int(np.ceil(ctx.space.distance(a[idx], b[idx]) / step)) + 1)[:, None] * (b - a)
         for a, b in zip(path[:-1], path[1:])]
    return bool(np.all(ctx.exact.is_free(np.concatenate(q))))


def _check_result(ctx, result, start, goal):
    assert result.status is PlanStatus.SUCCESS, result
    path = result.path
    np.testing.assert_array_equal(path[0], start)
    np.testing.assert_array_equal(path[-1], goal)
    assert np.all(ctx.model.within_limits(path))
    assert result.info["certify"].ok
    assert _exact_free_path(ctx, path)
    s = result.stats
    assert s.plan_time_s > 0 and s.simplify_time_s >= 0 and s.certify_time_s > 0 and s.collision_checks > 0


def test_plans_around_a_wall_and_every_edge_is_free(arm):
    model, spheres = arm
    wall = _box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])
    ctx = PlanningContext(model, [wall], spheres=spheres)
    start, goal = np.array([0.0, 0.2, 0.0]), np.array([1.2, -0.3, 0.4])
    assert not ctx.check_motion(start, goal)  # the straight motion sweeps through the wall
    result = rrt_connect(ctx, start, goal, FAST, np.random.default_rng(1))
    _check_result(ctx, result, start, goal)
    assert len(result.path) >= 3
    for a, b in zip(result.path[:-1], result.path[1:]):
        assert ctx.check_motion(a, b)


@pytest.mark.parametrize("prune", [True, False])
def test_provisional_edges_are_checked_before_a_path_is_returned(arm, prune):
    """With one eager evaluation per edge most tree edges stay provisional; those the pruning
    keeps (or all, without pruning) must be checked in full before the path is returned."""
    model, spheres = arm
    ctx = PlanningContext(model, [_box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])], spheres=spheres)
    start, goal = np.array([0.0, 0.2, 0.0]), np.array([1.2, -0.3, 0.4])
    settings = RRTConnectSettings(eager_checks=1, shortcut=prune, shortcut_iterations=0, certify=False)
    for seed in range(8):
        path = rrt_connect(ctx, start, goal, settings, np.random.default_rng(seed)).path
        np.testing.assert_array_equal(path[[0, -1]], [start, goal])
        assert all(ctx.check_motion(a, b) for a, b in zip(path[:-1], path[1:]))


def test_direct_edge_is_taken_when_free(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [], spheres=spheres)
    start, goal = np.array([0.0, 0.3, 0.2]), np.array([1.0, 0.5, -0.2])
    result = rrt_connect(ctx, start, goal, FAST)
    _check_result(ctx, result, start, goal)
    assert len(result.path) == 2 and result.stats.iterations == 0


def test_segments_shorter_than_half_a_step_are_decided_by_their_ends(arm):
    model, spheres = arm
    wall = _box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])
    ctx = PlanningContext(model, [wall], spheres=spheres, resolution=0.01)
    free = np.array([0.0, 0.2, 0.0])
    for delta in (1e-5, 1e-3, 1e-2):  # well under, near and over half a step of the tip
        assert ctx.check_motion(free, free + [delta, 0, 0])
    blocked = np.array([0.75, 0.0, 0.0])  # through the wall
    assert not ctx.is_valid(blocked)
    assert not ctx.check_motion(free, blocked) and not ctx.check_motion(blocked, blocked + [1e-5, 0, 0])


def test_same_seed_gives_the_same_path(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [_box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])], spheres=spheres)
    start, goal = np.array([0.0, 0.2, 0.0]), np.array([1.2, -0.3, 0.4])
    paths = [rrt_connect(ctx, start, goal, FAST, rng).path for rng in (np.random.default_rng(5), 5)]  # or its seed
    np.testing.assert_array_equal(paths[0], paths[1])
    np.testing.assert_array_equal(shortcut(ctx, paths[0], 3), shortcut(ctx, paths[0], np.random.default_rng(3)))


def test_infeasible_problem_times_out_within_the_budget(arm):
    model, spheres = arm
    # a wall along the +x axis from near the base to beyond reach; joint 1 cannot go round (|q1| <= 3 < pi)
    wall = _box("wall", [0.75, 0.0, 0.1], [1.1, 0.02, 0.6])
    ctx = PlanningContext(model, [wall], spheres=spheres)
    start, goal = np.array([0.8, 0.0, 0.0]), np.array([-0.8, 0.0, 0.0])
    assert ctx.is_valid(np.stack([start, goal])).all()
    budget = 0.3
    begun = time.perf_counter()
    result = rrt_connect(ctx, start, goal, RRTConnectSettings(time_budget_s=budget))
    elapsed = time.perf_counter() - begun
    assert result.status is PlanStatus.TIMEOUT and result.path.shape == (0, model.dof)
    assert budget <= result.stats.plan_time_s < budget + 0.1 and elapsed < budget + 0.2


def test_invalid_start_and_goal(arm):
    model, spheres = arm
    block = _box("block", [0.6, 0.0, 0.1], [0.1, 0.1, 0.3])  # on the stretched-out arm
    ctx = PlanningContext(model, [block], spheres=spheres)
    free = np.array([1.5, 0.0, 0.0])
    settings = RRTConnectSettings(time_budget_s=0.2)
    invalid_start = rrt_connect(ctx, np.zeros(3), free, settings)
    assert invalid_start.status is PlanStatus.INVALID_START and invalid_start.blamed_ends == ("start",)
    assert invalid_start.info["reason"] == f"start: {ctx.why_invalid(np.zeros(3))}"
    assert rrt_connect(ctx, free, np.zeros(3), settings).status is PlanStatus.INVALID_GOAL
    outside = rrt_connect(ctx, free, np.array([0.0, 2.9, 0.0]), settings)  # limits
    assert outside.status is PlanStatus.INVALID_GOAL and outside.info["reason"].startswith("goal: joint ")
    goal_set = rrt_connect(ctx, free, np.array([[0.0, 2.9, 0.0], free, np.zeros(3)]), settings)
    assert goal_set.success and "reason" not in goal_set.info and goal_set.goal_index == 1
    unusable = rrt_connect(ctx, free, np.array([[0.0, 2.9, 0.0], np.zeros(3)]), settings)
    assert re.fullmatch(r"goal 0: joint .*; goal 1: \w+ collides with block .*", unusable.info["reason"])
    many = rrt_connect(ctx, free, np.array([[0.0, 2.9 + 0.01 * i, 0.0] for i in range(8)]), settings)
    assert many.status is PlanStatus.INVALID_GOAL  # the first few reasons are told, not thousands
    assert re.fullmatch(r"(goal [0-4]: joint [^;]*; ){5}3 more goals rejected", many.info["reason"])
    assert re.fullmatch(r"\w+ collides with block \(\d+(\.\d+)? mm deep\)(; .*)?", ctx.why_invalid(np.zeros(3)))
    assert re.fullmatch(r"joint \w+ = 2\.9 outside its limits \[-?[\d.]+, [\d.]+\]",
                        ctx.why_invalid(np.array([0.0, 2.9, 0.0])))
    assert ctx.why_invalid(free) == ""
    with pytest.raises(PrehensileError, match=r"why_invalid: expected one configuration \(3,\)"):
        ctx.why_invalid(np.zeros((2, 3)))
    assert ctx.spheres.ball_contacts(free) == [] and ("l2", "world") in ctx.spheres.ball_contacts(np.zeros(3))
    with pytest.raises(Exception, match="q_goal"):
        rrt_connect(ctx, free, np.zeros(4), settings)
    with pytest.raises(PrehensileError, match=r"q_goal: no goals given \(shape \(0, 3\)\)"):
        rrt_connect(ctx, free, np.zeros((0, 3)), settings)
    with pytest.raises(PrehensileError, match="q_start: expected numbers, got 'abc'"):
        rrt_connect(ctx, "abc", free, settings)
    for rng in (-1, 1.5):
        with pytest.raises(PrehensileError, match=f"rng: expected a numpy Generator, a seed .*, got {rng}"):
            rrt_connect(ctx, free, np.zeros(3), settings, rng=rng)


def test_the_search_keeps_its_own_ends(arm):
    """Changing the caller's start after the search began changes nothing; goals equal to the
    start within 1e-9 in a joint not planned end the path exactly at the start's value."""
    model, spheres = arm
    ctx = PlanningContext(model, [], joints=["j1", "j2"], spheres=spheres)
    start, goal = np.array([0.2, 0.0, 0.3]), np.array([1.0, 0.5, 0.3 + 1e-10])
    search = RRTConnectSearch(ctx, start, RRTConnectSettings())
    search.add_goals(goal)
    start[:] = 0.0
    result = search.solve(1.0)
    assert result.success and np.array_equal(result.path[0], [0.2, 0.0, 0.3])
    assert np.all(result.path[:, 2] == 0.3) and goal[2] == 0.3 + 1e-10  # the caller's goal is untouched


def test_batched_motion_checks_match_single_ones(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [_box("block", [0.6, 0.0, 0.1], [0.1, 0.1, 0.3])], spheres=spheres)
    rng = np.random.default_rng(5)
    qa, qb = model.random_configurations(rng, 40), model.random_configurations(rng, 40)
    qb[:5] = qa[:5] + 0.05 * rng.normal(size=(5, 3))  # short segments, mostly free
    qb[5, 1] = 2.9  # outside the limits
    batch = ctx.check_motions(qa, qb)
    assert np.array_equal(batch, [ctx.check_motion(a, b) for a, b in zip(qa, qb)])
    assert 0 < batch.sum() < len(batch) and not batch[5]
    with pytest.raises(PrehensileError, match=r"check_motions: expected qa and qb of one shape"):
        ctx.check_motions(qa, qb[:3])

def test_pairs_the_planned_joints_do_not_move_are_tested_exactly_once():
    """NAO's biceps' balls reach into the torso's (the meshes are 10 mm apart). Planning the left
    arm, the right arm and the torso are one static pair, tested on the meshes; the left arm's
    pairs stay on the balls, and why_invalid names them."""
    nao = robots.load("nao")
    ctx = PlanningContext(nao, [], joints="left_arm")
    static = {frozenset((nao.link_names[i], nao.link_names[j])) for i, j in ctx.static_pairs}
    assert frozenset(("torso", "RBicep")) in static and frozenset(("torso", "LBicep")) not in static
    q = nao.neutral_configuration()
    assert ctx.exact.is_free(q) and ctx.static_free(q) and not ctx.is_valid(q)
    assert ctx.spheres.ball_contacts(q) == [("torso", "LBicep")]
    assert ctx.why_invalid(q).startswith("free on the exact geometry") and "torso with LBicep" in ctx.why_invalid(q)
    qs = np.repeat(q[None], 200, axis=0)
    qs[:, ctx.space.indices] = np.random.default_rng(0).uniform(ctx.space.lower, ctx.space.upper, (200, ctx.space.n))
    valid = qs[ctx.is_valid(qs)]
    assert len(valid) > 50 and ctx.exact.is_free(valid).all()
    _check_result(ctx, rrt_connect(ctx, valid[0], valid[1], FAST, np.random.default_rng(0)), valid[0], valid[1])
    hugging = q.copy()  # the right arm, not planned, pressed into the torso: every motion of the left one is invalid
    hugging[nao.joint_index("RShoulderRoll")] = nao.upper[nao.joint_index("RShoulderRoll")]
    hugging[nao.joint_index("RElbowRoll")] = nao.upper[nao.joint_index("RElbowRoll")]
    assert not ctx.exact.is_free(hugging) and not ctx.static_free(hugging) and not ctx.is_valid(hugging)
    assert rrt_connect(ctx, hugging, hugging, FAST).status is PlanStatus.INVALID_START
    assert "torso collides with RBicep" in ctx.why_invalid(hugging)
    with pytest.raises(PrehensileError, match="differ in joints the context does not plan"):
        ctx.check_motion(q, hugging)


def test_a_joint_that_moves_no_geometry_is_planned():
    """A bare flange bounds no motion; a small weight keeps it in the metric, and it turns to its goal."""
    ctx = PlanningContext(_arm(flange=True), [_box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])])
    weights = ctx.space.weights
    assert weights[3] == pytest.approx(IDLE_WEIGHT * weights.max())
    start, goal = np.array([0.0, 0.2, 0.0, -2.5]), np.array([1.2, -0.3, 0.4, 2.5])
    _check_result(ctx, rrt_connect(ctx, start, goal, FAST, rng=0), start, goal)


def test_goal_set_reports_the_goal_reached(arm):
    model, spheres = arm
    wall = _box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])
    ctx = PlanningContext(model, [wall, _box("block", [0.6, 0.0, 0.1], [0.1, 0.1, 0.3])], spheres=spheres)
    start = np.array([1.2, -0.3, 0.4])
    goals = np.array([[0.0, 0.0, 0.0], [0.0, 0.2, 0.0], [-1.0, 0.5, 0.5]])  # the first one collides
    result = rrt_connect(ctx, start, goals, FAST, np.random.default_rng(2))
    assert result.goal_index in (1, 2)
    _check_result(ctx, result, start, goals[result.goal_index])


def _turner():
    """A 0.4 m bar on one continuous joint about z, 0.1 m above a base disc."""
    bar = Geometry(Box((0.4, 0.05, 0.05)), make_pose(position=[0.25, 0, 0]))
    links = [LinkSpec("base"), LinkSpec("bar", collisions=[bar])]
    joints = [JointSpec("turn", "continuous", "base", "bar", make_pose(position=[0, 0, 0.1]), [0, 0, 1.0])]
    return build_model("turner", "test", links, joints)


@pytest.mark.parametrize("blocked", [False, True])
def test_a_continuous_joint_turns_the_shorter_way_unless_it_is_blocked(blocked):
    """2.8 -> -2.8 rad is 0.68 rad through +-pi; a post there forces the 5.6 rad the other way."""
    post = _box("post", [-0.3, 0.0, 0.1], [0.05, 0.05, 0.3])
    ctx = PlanningContext(_turner(), [post] if blocked else [])
    start, goal = np.array([2.8]), np.array([-2.8])
    result = rrt_connect(ctx, start, goal, FAST, 0)
    reached = goal if blocked else goal + 2 * np.pi  # the same angle, a turn apart
    _check_result(ctx, result, start, reached)
    assert result.goal_index == 0
    turned = result.path[:, 0]
    assert (turned.min(), turned.max()) == ((-2.8, 2.8) if blocked else (2.8, pytest.approx(reached[0])))


def test_direct_edges_to_a_goal_set_take_steps_like_iterations(arm):
    """One kernel call tries at most as many goals' direct edges as it may run iterations (a
    large goal set cannot keep it from the clock); goals added later get theirs, not the nodes
    the search grew meanwhile."""
    from prehensile.planning.rrt_connect import DIRECT, DIRECT_END, ITERATIONS, RUNNING, SIZE, search as search_kernel

    model, spheres = arm
    slot = [_box(f"side {y}", [0.7, y, 0.1], [1.0, 0.04, 0.4]) for y in (-0.1, 0.1)]
    ctx = PlanningContext(model, slot, spheres=spheres)
    query = RRTConnectSearch(ctx, np.zeros(3), FAST, 0)  # stretched out in a slot it cannot leave
    goals = np.column_stack([np.linspace(1.2, 2.0, 30), np.zeros(30), np.zeros(30)])  # all out of the slot
    query.add_goals(goals)
    assert query._run(np.inf, 0) == (0, -1)  # plants the ends, searches nothing
    trees, space = query.trees, ctx.space
    bounds = space.sampling_bounds(query.start[space.indices])
    assert (trees.counters[DIRECT], trees.counters[DIRECT_END]) == (0, 30)

    def steps(count: int) -> int:
        return search_kernel(trees.nodes, trees.parents, trees.flags, trees.points, trees.work, trees.counters,
                             trees.path, trees.marks, trees.owner, True, query.state, count, np.inf, COMPILING, 1.0,
                             query.res, 3, space.indices, space.weights, *bounds, query.start.copy(),
                             ctx.spheres.data, ctx.scratch, ctx.motion_arrays(query.res))

    assert steps(4) == RUNNING and trees.counters[DIRECT] == 4 and trees.counters[ITERATIONS] == 0
    assert steps(40) == RUNNING and trees.counters[DIRECT] == 30 and trees.counters[ITERATIONS] == 14
    grown = int(trees.counters[SIZE + 1])
    query.add_goals(goals[:2])
    assert (trees.counters[DIRECT], trees.counters[DIRECT_END]) == (grown, grown + 2)


def test_a_search_stops_at_its_iteration_cap(arm):
    """Capped calls run exactly the iterations asked (the clock is far away) and resume."""
    model, spheres = arm
    slot = [_box(f"side {y}", [0.7, y, 0.1], [1.0, 0.04, 0.4]) for y in (-0.1, 0.1)]
    ctx = PlanningContext(model, slot, spheres=spheres)
    search = RRTConnectSearch(ctx, np.zeros(3), FAST, 0)  # stretched out in a slot it cannot leave
    search.add_goals(np.array([np.pi / 2, 0.0, 0.0]))
    first, second = search.solve(5.0, max_iterations=40), search.solve(5.0, max_iterations=25)
    assert (first.status, first.stats.iterations, second.stats.iterations) == (PlanStatus.TIMEOUT, 40, 25)
    for bad in (0, 2.5, "5"):
        with pytest.raises(PrehensileError, match=f"max_iterations must be an integer >= 1 or None, got {bad!r}"):
            search.solve(1.0, max_iterations=bad)
    assert search.solve(5.0, max_iterations=10.0).stats.iterations == 10  # a whole float counts


def test_search_resumes_its_trees_and_takes_goals_added_later(arm):
    model, spheres = arm
    # the wall of the infeasible problem above: from +x the arm cannot reach -x
    wall = _box("wall", [0.75, 0.0, 0.1], [1.1, 0.02, 0.6])
    ctx = PlanningContext(model, [wall], spheres=spheres)
    start = np.array([0.8, 0.0, 0.0])
    search = RRTConnectSearch(ctx, start, RRTConnectSettings(escape=False), np.random.default_rng(3))
    none = search.solve(0.1)  # no goal yet
    assert none.status is PlanStatus.INVALID_GOAL and none.info["reason"] == "no goal given: call add_goals first"
    search.add_goals(np.array([-0.8, 0.0, 0.0]))  # behind the wall
    first = search.solve(0.05)
    second = search.solve(0.05)
    assert first.status is second.status is PlanStatus.TIMEOUT
    assert second.stats.nodes > first.stats.nodes  # the same trees grew on
    reachable = np.array([1.5, 0.5, -0.5])
    search.add_goals(reachable)
    for budget in (0.0, -1.0, float("nan"), "1"):
        with pytest.raises(PrehensileError, match="solve: time_budget_s must be > 0 and finite, got"):
            search.solve(budget)
    for bad, message in ((dict(time_budget_s=float("inf")), "time_budget_s must be > 0 and finite, got inf"),
                         (dict(shortcut_min_gain=1.0), r"shortcut_min_gain must be in \[0, 1\), got 1.0"),
                         (dict(eager_checks="3"), "eager_checks must be an integer >= 1, got '3'"),
                         (dict(max_nodes=2.5), "max_nodes must be an integer >= 2, got 2.5")):
        with pytest.raises(PrehensileError, match=f"RRTConnectSettings.{message}"):  # not later, in solve
            RRTConnectSettings(**bad)
    result = search.solve(2.0)
    assert result.goal_index == 1  # rows count over every goal added
    _check_result(ctx, result, start, reachable)


def test_new_trees_keep_no_goal_of_the_old_ones(arm):
    """Trees made anew (as after a failed certification, in a context whose balls reject the
    goal) search nothing until a usable goal joins: the old trees' goal roots do not carry
    over (they once did, and the search grew a goal tree from no root: paths to nowhere)."""
    model, spheres = arm
    start, goal, other = np.array([0.8, 0.0, 0.0]), np.array([-0.8, 0.0, 0.0]), np.array([1.5, 0.5, -0.5])
    query = RRTConnectSearch(PlanningContext(model, [], spheres=spheres), start, FAST, 0)
    query.add_goals(goal)
    assert query._run(np.inf, 0) == (0, -1) and query.goal_row == {0: 0}  # planted, nothing searched
    on_goal = _box("on the goal", [0.42, -0.43, 0.1], [0.2, 0.2, 0.2])  # on the arm turned by -0.8 rad
    query.context, query.trees = PlanningContext(model, [on_goal], spheres=spheres), None
    assert not query.context.is_valid(goal) and query.context.is_valid(other)
    assert query._run(np.inf, 50) == (-1, -1) and query.goal_row == {}
    query.add_goals(other)
    result = query.solve(2.0)
    assert result.status is PlanStatus.SUCCESS and result.goal_index == 1
    np.testing.assert_array_equal(result.path[-1], other)


def test_attached_object_is_carried_around_obstacles(arm):
    model, spheres = arm
    post = Obstacle("post", Sphere(0.06), make_pose(position=[0.446, 1.016, 0.1]))  # 0.23 m off the arm
    start, goal = np.array([0.0, 1.2, 0.0]), np.array([0.6, 1.2, 0.0])
    bare = PlanningContext(model, [post], spheres=spheres)
    assert bare.check_motion(start, goal)  # the arm alone sweeps past the post
    rod = AttachedObject("rod", "l3", Box((0.5, 0.05, 0.05)), make_pose(position=[0.3, 0.0, 0.0]))
    ctx = PlanningContext(model, [post], spheres=spheres, attached=[rod])
    assert "attached/rod" in ctx.collision_model.link_names
    assert ctx.is_valid(np.stack([start, goal])).all()  # holding it touches the last link: allowed
    assert not ctx.check_motion(start, goal)  # but the rod sweeps through the post
    result = rrt_connect(ctx, start, goal, FAST, np.random.default_rng(3))
    _check_result(ctx, result, start, goal)  # ctx.exact includes the rod


def test_an_end_with_a_held_object_wholly_inside_a_closed_mesh_is_invalid(arm):
    """The balls see a closed mesh's surface, not its inside: an end nested in it is refused
    at once with the exact reason, not searched from until the budget runs out."""
    import trimesh

    model, spheres = arm
    start, goal = np.array([0.0, 1.2, 0.0]), np.array([0.6, 1.2, 0.0])
    offset = make_pose(position=[0.5, 0.0, 0.0])  # 0.25 m beyond the last link's end
    cube = AttachedObject("cube", "l3", Box((0.04, 0.04, 0.04)), offset)
    shell = trimesh.creation.icosphere(subdivisions=2, radius=0.1)
    for end, status in ((goal, PlanStatus.INVALID_GOAL), (start, PlanStatus.INVALID_START)):
        where = forward_kinematics(model, end)[model.link_index("l3")] @ offset
        world = [Obstacle("shell", Mesh.from_arrays(shell.vertices, shell.faces), make_pose(position=where[:3, 3]))]
        ctx = PlanningContext(model, world, spheres=spheres, attached=[cube])
        assert ctx.spheres.is_free(end) and not ctx.is_valid(end)
        result = rrt_connect(ctx, start, goal, RRTConnectSettings(time_budget_s=5.0), 0)
        assert result.status is status and result.stats.plan_time_s < 1.0
        assert "attached/cube collides with shell" in result.info["reason"]
        bare = PlanningContext(model, world, spheres=spheres)  # the arm alone is outside the shell
        assert bare.is_valid(end)


def test_attached_objects_are_validated_and_may_be_several_shapes(arm):
    model, spheres = arm
    bar, ball = Box((0.2, 0.05, 0.05)), Sphere(0.04)
    empty = Mesh.from_arrays(np.zeros((0, 3)), np.zeros((0, 3)))
    for shape, message in [(empty, "'plate': Mesh.*needs a positive size"), ([], "'plate': no shape"),
                           ((bar, "box"), "'plate': box needs a positive size")]:
        with pytest.raises(PrehensileError, match=message):
            AttachedObject("plate", "l3", shape)
    with pytest.raises(PrehensileError, match="'plate': T_link_object: upper-left 3x3 block is not a rotation"):
        AttachedObject("plate", "l3", bar, 2.0 * np.eye(4))
    assert AttachedObject("plate", "l3", bar, touch_links="l2").touch_links == ("l2",)  # one name, not its letters
    dumbbell = AttachedObject("dumbbell", "l3", [bar, Geometry(ball, make_pose(position=[0.1, 0, 0]))])
    assert [g.shape for g in dumbbell.geometries()] == [bar, ball]
    mirrored = AttachedObject("wedge", "l3", Mesh(WEDGE, (1.0, -1.0, 1.0)))  # a mirror image, as URDF allows
    ctx = PlanningContext(model, [], spheres=spheres, attached=[dumbbell, mirrored])
    assert len(ctx.collision_model.collisions[ctx.collision_model.link_index("attached/dumbbell")]) == 2
    assert ctx.collision_model.collisions[ctx.collision_model.link_index("attached/wedge")][0].shape.scale[1] == -1.0
    for held, message in [(AttachedObject("mug", "l4", bar), "object 'mug', link: robot 'arm' has no link 'l4'"),
                          (AttachedObject("mug", "l3", bar, touch_links="l9"), "'mug', touch_links: .* no link 'l9'")]:
        with pytest.raises(PrehensileError, match=message):
            PlanningContext(model, [], spheres=spheres, attached=[held])


def test_goal_the_balls_reject_is_reached_by_a_certified_escape(arm):
    model, spheres = arm
    # stretched out, l3 spans x 0.8..1.05 at y 0; a box face 2 mm beside its surface
    box = _box("box", [0.92, 0.04 + 0.002 + 0.05, 0.1], [0.1, 0.1, 0.1])
    ctx = PlanningContext(model, [box], spheres=spheres)
    start, goal = np.array([-1.0, 0.5, 0.0]), np.zeros(3)
    assert ctx.exact.is_free(goal) and not ctx.is_valid(goal)
    result = rrt_connect(ctx, start, goal, FAST, np.random.default_rng(0))
    _check_result(ctx, result, start, goal)
    strict = RRTConnectSettings(time_budget_s=0.2, escape=False)
    assert rrt_connect(ctx, start, goal, strict).status is PlanStatus.INVALID_GOAL
    rng = np.random.default_rng(0)
    assert certified_escape(ctx, goal, start, rng, 0.5 * ctx.resolution) is not None
    assert certified_escape(ctx, goal, start, rng, 0.5 * ctx.resolution, deadline=clock()) is None  # out of time
    # as a start it searches until the budget runs out: out of time is a TIMEOUT, not an invalid start
    assert rrt_connect(ctx, goal, start, RRTConnectSettings(time_budget_s=1e-9)).status is PlanStatus.TIMEOUT
    _check_result(ctx, rrt_connect(ctx, goal, start, FAST, np.random.default_rng(0)), goal, start)
    inside = _box("inside", [0.92, 0.0, 0.1], [0.05, 0.05, 0.05])  # exactly colliding: no escape
    assert rrt_connect(PlanningContext(model, [inside], spheres=spheres), start, goal, FAST).status \
        is PlanStatus.INVALID_GOAL


def test_a_start_the_balls_accept_near_an_obstacle_needs_no_escape():
    """A start within half a resolution of an obstacle whose balls no motion moves away (a
    post spinning about its own axis beside a box) has no escape; it is a node all the same,
    and the plan must not spend its budget searching one."""
    links = [LinkSpec("base"),
             LinkSpec("post", collisions=[Geometry(Capsule(0.04, 0.3), make_pose(position=[0, 0, 0.2]))]),
             LinkSpec("arm", collisions=[Geometry(Capsule(0.03, 0.3), make_pose(ALONG_X, [0.2, 0, 0]))])]
    joints = [JointSpec("spin", "revolute", "base", "post", np.eye(4), [0, 0, 1.0], -3.0, 3.0),
              JointSpec("lift", "revolute", "post", "arm", make_pose(position=[0, 0, 0.45]), [0, 1.0, 0], -1.0, 1.0)]
    model = build_model("spinner", "test", links, joints)
    spheres = generate_sphere_model(model, cache=False)
    post = spheres.sphere_link == model.link_index("post")
    reach = float(np.max(np.linalg.norm(spheres.centers[post, :2], axis=1) + spheres.radii[post]))
    box = _box("box", [reach + 0.001 + 0.05, 0.0, 0.2], [0.1, 0.1, 0.1])  # 1 mm beside the post's balls
    ctx = PlanningContext(model, [box], spheres=spheres)
    start, goal = np.zeros(2), np.array([2.0, 0.5])
    assert ctx.is_valid(start) and ctx.spheres.clearance(start, 0.01, self_pairs=False) < 0.5 * ctx.resolution
    budget = 5.0
    result = rrt_connect(ctx, start, goal, RRTConnectSettings(time_budget_s=budget), rng=0)
    _check_result(ctx, result, start, goal)
    assert result.info["escapes"] == 0 and result.stats.plan_time_s < 0.5 * budget  # not spent searching an escape


def _slot(spheres):
    """A slot narrower than the arm's links, balls a quarter of the covering ``spheres``' size
    (they slip through it), and a start and goal on either side of it."""
    slot = [_box(name, [0.8, 0.0, 0.1 + side * 0.085], [0.6, 0.3, 0.1]) for name, side in (("top", 1), ("bottom", -1))]
    thin = SphereModel(spheres.link_names, spheres.sphere_link, spheres.centers, 0.25 * spheres.radii)
    return slot, thin, np.array([-1.2, 0.0, 0.0]), np.array([1.2, 0.0, 0.0])


def test_path_failing_certification_is_planned_again_on_the_cover(arm):
    """Thin balls slip through a slot narrower than the links; their path fails the exact
    certification, and covering balls on the links that collided make the planner go around
    with the arm folded."""
    model, spheres = arm
    slot, thin, start, goal = _slot(spheres)
    alone = PlanningContext(model, slot, spheres=thin)  # no cover given: the thin balls padded to cover
    assert alone.check_motion(start, goal) and alone.refined({"l2"}) is not None
    padded = rrt_connect(alone, start, goal, FAST, np.random.default_rng(0))
    _check_result(alone, padded, start, goal)
    assert padded.info["attempts"] >= 2 and padded.info["refined"]
    # balls that cover already have nothing to refine: the next search runs at half the resolution
    whole = PlanningContext(model, slot, spheres=spheres)
    report = CertifyReport(ok=False, colliding_links=("l2",))
    assert whole.refined({"l2"}) is None
    assert refine_after_failure(whole, whole, frozenset(), 0.004, report, last=True) == (whole, frozenset(), 0.002)
    ctx = PlanningContext(model, slot, spheres=thin, cover=spheres)
    covered = ctx.refined({"l1", "l2", "l3"})
    assert covered.certifier is ctx.certifier and not covered.check_motion(start, goal)
    assert ctx.refined({"l3", "l2", "l1"}) is covered
    result = rrt_connect(ctx, start, goal, FAST, np.random.default_rng(0))
    _check_result(ctx, result, start, goal)
    assert result.info["attempts"] >= 2 and set(result.info["refined"]) <= {"l1", "l2", "l3"}
    assert result.info["refined"]
    # with one retry left, it covers every link at once
    once = rrt_connect(ctx, start, goal, RRTConnectSettings(time_budget_s=2.0, certify_retries=1),
                       np.random.default_rng(0))
    _check_result(ctx, once, start, goal)
    assert once.info["attempts"] == 2 and {"l1", "l2", "l3"} <= set(once.info["refined"])
    mixed = ctx.refined({"l2"}).sphere_model
    for link, balls in (("l1", thin), ("l2", spheres), ("l3", thin)):
        np.testing.assert_array_equal(mixed.link_spheres(link)[1], balls.link_spheres(link)[1])
    with pytest.raises(PrehensileError, match="covering"):
        PlanningContext(model, slot, spheres=thin, cover=thin)


def test_jplus_rrt_plans_again_on_the_cover_after_a_failed_certification(arm):
    """J+-RRT's path through the slot fails certification; without retries that is the answer,
    with them a new tree on the links' covering balls reaches the same tool pose around it."""
    model, spheres = arm
    slot, thin, start, goal = _slot(spheres)
    ctx = PlanningContext(model, slot, spheres=thin, cover=spheres)
    target = forward_kinematics(model, goal)[model.link_index("tip")]
    settings = JPlusRRTSettings(time_budget_s=5.0, certify_retries=0)
    through = jplus_rrt(ctx, start, target[None], settings, rng=5)
    assert through.status is PlanStatus.CERTIFICATION_FAILED and not through.info["certify"].ok
    assert through.info["attempts"] == 1 and through.path.shape == (0, 3)
    around = jplus_rrt(ctx, start, target[None], dataclasses.replace(settings, certify_retries=3), rng=5)
    assert around.status is PlanStatus.SUCCESS and around.info["attempts"] >= 2 and around.info["refined"]
    np.testing.assert_array_equal(around.path[0], start)
    assert around.info["certify"].ok and _exact_free_path(ctx, around.path)
    reached = forward_kinematics(model, around.path[-1])[model.link_index("tip")]
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) <= settings.position_tolerance
    assert around.stats.collision_checks > through.stats.collision_checks


def test_shortcuts_and_bands_of_a_certified_path_stay_certified_on_thin_balls(arm, caplog):
    """On balls that slip through the slot, shortening a certified path that goes around it
    would cut through it; the certified shortcut and band are made again on the cover (given,
    or the thin balls padded), or return the input."""
    model, spheres = arm
    slot, thin, start, goal = _slot(spheres)
    ctx = PlanningContext(model, slot, spheres=thin, cover=spheres)
    path = rrt_connect(ctx, start, goal, FAST, np.random.default_rng(0)).path
    assert certify_path(ctx, path).ok and ctx.check_motion(start, goal)
    loose = shortcut(ctx, path, 0, min_gain=0.0, certify=False)
    assert not certify_path(ctx, loose).ok  # through the slot
    alone = PlanningContext(model, slot, spheres=thin)
    for context in (ctx, alone):
        for seed in range(2):
            short = shortcut(context, path, seed, min_gain=0.0)
            assert certify_path(ctx, short).ok and ctx.space.path_length(short) <= ctx.space.path_length(path) + 1e-9
            np.testing.assert_array_equal(short[[0, -1]], path[[0, -1]])
    with caplog.at_level(logging.INFO, logger="prehensile.planning.certify"):
        np.testing.assert_array_equal(shortcut(alone, path, 0, retries=0), path)  # no retry: the input
    assert "none of 1 reworked paths passed the exact certification" in caplog.text
    assert "WARNING" not in caplog.text  # the input is certified
    caplog.clear()
    with caplog.at_level(logging.WARNING, logger="prehensile.planning.certify"):
        np.testing.assert_array_equal(shortcut(alone, loose, 0, retries=0), loose)
        np.testing.assert_array_equal(elastic_band(alone, loose, ElasticBandSettings(max_spacing=None,
                                                                                     certify_retries=0)), loose)
    for who in ("shortcut", "elastic_band"):
        assert f"{who}: the input path fails the exact certification" in caplog.text
    pull = ElasticBandSettings(k_int=0.05, k_ext=0.0, max_iterations=200)
    assert not certify_path(ctx, elastic_band(ctx, path, dataclasses.replace(pull, certify=False))).ok
    band = elastic_band(ctx, path, pull)
    assert certify_path(ctx, band).ok
    np.testing.assert_array_equal(band[[0, -1]], path[[0, -1]])


def test_a_start_only_the_thin_balls_let_through_is_an_invalid_start(arm, monkeypatch):
    """The exact l3 touches a small block the thin balls miss: the path fails certification,
    the covering balls then reject the start, and no escape is certified from an exact contact."""
    model, spheres = arm
    thin = SphereModel(spheres.link_names, spheres.sphere_link, spheres.centers, 0.25 * spheres.radii)
    block = [_box("block", [0.93, 0.035, 0.1], [0.02, 0.02, 0.02])]
    ctx = PlanningContext(model, block, spheres=thin, cover=spheres)
    start, goal = np.zeros(3), np.array([1.0, 0.0, 0.0])
    assert ctx.spheres.is_free(start) and not ctx.exact.is_free(start)
    result = rrt_connect(ctx, start, goal, FAST)
    assert result.status is PlanStatus.INVALID_START, result
    assert not result.info["certify"].ok and "l3" in result.info["refined"]
    assert ctx.why_invalid(start).startswith("l3 collides with block")
    # the statistics count the second attempt's setup (its escape searches may take the budget)
    rrt_connect_module = importlib.import_module("prehensile.planning.rrt_connect")  # the function shadows it
    screen = rrt_connect_module._endpoints

    def slow_on_the_cover(context, *args, **kwargs):
        time.sleep(0.0 if context is ctx else 0.2)
        return screen(context, *args, **kwargs)

    monkeypatch.setattr(rrt_connect_module, "_endpoints", slow_on_the_cover)
    again = rrt_connect(ctx, start, goal, FAST)
    assert again.status is PlanStatus.INVALID_START and again.stats.plan_time_s >= 0.2


def test_refined_contexts_of_two_scenes_share_the_robot_tables_not_the_world(arm):
    """The tables that depend only on the robot and its balls (ball groups, motion weights) are
    built once and shared by the refined contexts of every scene; each still checks its own
    obstacles."""
    model, spheres = arm
    thin = SphereModel(spheres.link_names, spheres.sphere_link, spheres.centers, 0.25 * spheres.radii)
    left, right = _box("left", [0.0, 0.8, 0.1], [0.1, 0.1, 0.1]), _box("right", [0.0, -0.8, 0.1], [0.1, 0.1, 0.1])
    a = PlanningContext(model, [left], spheres=thin, cover=spheres).refined({"l3"})
    b = PlanningContext(model, [right], spheres=thin, cover=spheres).refined({"l3"})
    assert a.sphere_model is b.sphere_model
    assert a.spheres.data[10] is b.spheres.data[10] and a.motion[0] is not b.motion[0]
    np.testing.assert_array_equal(a.motion[0], b.motion[0])
    toward_left, toward_right = np.array([np.pi / 2, 0.0, 0.0]), np.array([-np.pi / 2, 0.0, 0.0])
    np.testing.assert_array_equal(a.is_valid(np.stack([toward_left, toward_right])), [False, True])
    np.testing.assert_array_equal(b.is_valid(np.stack([toward_left, toward_right])), [True, False])


def test_context_checks_shapes_and_limits(arm):
    model, spheres = arm
    block = _box("block", [0.6, 0.0, 0.1], [0.1, 0.1, 0.3])
    ctx = PlanningContext(model, [block], spheres=spheres, joints=["j1", "j2"])
    assert ctx.space.n == 2
    q = np.array([[0.0, 0.0, 0.0], [1.5, 0.0, 0.0], [0.0, 2.9, 0.0]])
    np.testing.assert_array_equal(ctx.is_valid(q), [False, True, False])
    assert ctx.is_valid(q.reshape(3, 1, 3)).shape == (3, 1)
    start, goal = np.array([1.5, 0.0, 0.3]), np.array([2.0, 0.5, 0.3])
    result = rrt_connect(ctx, start, goal, FAST)
    _check_result(ctx, result, start, goal)
    assert np.all(result.path[:, 2] == 0.3)  # j3 is not planned
    with pytest.raises(PrehensileError, match=r"not planned \(j3; planned: j1, j2\)"):
        rrt_connect(ctx, start, np.array([2.0, 0.5, 0.0]), FAST)


def test_shortcut_never_lengthens_nor_invalidates(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [_box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])], spheres=spheres)
    start, goal = np.array([0.0, 0.2, 0.0]), np.array([1.2, -0.3, 0.4])
    raw = rrt_connect(ctx, start, goal, RRTConnectSettings(shortcut=False, certify=False),
                      np.random.default_rng(4)).path
    # a detour through valid random configurations, each leg free
    rng = np.random.default_rng(0)
    detour = [raw[0]]
    for q in raw[1:]:
        while True:
            mid = 0.5 * (detour[-1] + q) + rng.normal(scale=0.2, size=3)
            if ctx.check_motion(detour[-1], mid) and ctx.check_motion(mid, q):
                detour += [mid, q]
                break
    detour = np.array(detour)
    length = ctx.space.path_length(detour)
    for seed in range(3):
        short = shortcut(ctx, detour, np.random.default_rng(seed), iterations=50)
        np.testing.assert_array_equal(short[0], start)
        np.testing.assert_array_equal(short[-1], goal)
        assert ctx.space.path_length(short) <= length + 1e-9
        assert all(ctx.check_motion(a, b) for a, b in zip(short[:-1], short[1:]))
    for bad, valid in ((dict(iterations=-1), "an integer >= 0"), (dict(iterations=2.5), "an integer >= 0"),
                       (dict(time_budget_s=-1.0), ">= 0"), (dict(time_budget_s=float("nan")), ">= 0"),
                       (dict(min_gain=-0.1), r"in \[0, 1\)"), (dict(min_gain=1.0), r"in \[0, 1\)"),
                       (dict(retries=-1), "an integer >= 0"), (dict(retries=0.5), "an integer >= 0")):
        (name, value), = bad.items()
        with pytest.raises(PrehensileError, match=f"shortcut: {name} must be {valid}, got {value}"):
            shortcut(ctx, detour, 0, **bad)
    with pytest.raises(PrehensileError, match="shortcut: resolution: must be a finite length"):
        shortcut(ctx, detour, 0, resolution=float("inf"))  # would let every shortcut through the wall
    # the time limit is read before every random attempt: none runs without time; pruning still does
    pruned = shortcut(ctx, detour, 0, iterations=0)
    assert len(pruned) < len(detour)
    np.testing.assert_array_equal(shortcut(ctx, detour, 0, iterations=50, time_budget_s=0.0), pruned)
    # rows for the inserted waypoints are capped, not one per attempt; a full buffer ends the attempts
    assert len(shortcut(ctx, detour, 0, iterations=10**9, time_budget_s=0.01)) <= len(detour) + MAX_INSERTED
    buffer, marks = np.empty((len(detour) + 1, 3)), waypoint_marks(len(detour) + 1)
    buffer[:len(detour)], marks[0][:len(detour)] = detour, np.arange(len(detour))
    n = shortcut_rows(ctx, buffer, len(detour), marks, np.random.default_rng(0), 200, 0.0, 1.0, ctx.resolution, None,
                      prune_first=False)
    assert n <= len(buffer) and np.array_equal(buffer[n - 1], goal)
    assert all(ctx.check_motion(a, b) for a, b in zip(buffer[:n - 1], buffer[1:n]))
    with pytest.raises(PrehensileError, match=r"shortcut: the input path must be valid; its edge 1 .* hits an obstacle"):
        shortcut(ctx, np.array([start, start, goal]), 0)  # the straight motion sweeps through the wall
    # pruning again spends no check on the pairs of waypoints found blocked before
    work = (ctx.space.indices, ctx.space.weights, ctx.resolution, ctx.spheres.data, ctx.scratch,
            ctx.motion_arrays(ctx.resolution))
    path, (ids, checked, memo) = detour.copy(), waypoint_marks(len(detour))
    ids[:] = np.arange(len(detour))
    n = prune(path, len(detour), (ids, checked, memo), *work, np.zeros(1, int))
    again = []
    for remembered in (memo, np.full_like(memo, -1)):
        spent = np.zeros(1, int)
        marks = (ids[:n].copy(), checked[:n].copy(), remembered.copy())
        again.append((prune(path[:n].copy(), n, marks, *work, spent), spent[0]))
    assert again[0][0] == again[1][0] and again[0][1] < again[1][1]
    # ... also when the shortcut is handed the marks of the pruning the path had (as the planner does)
    handed = []
    for remembered in (memo, np.full_like(memo, -1)):
        spent, buffer = np.zeros(1, int), np.empty((len(detour) + 4, model.dof))
        buffer[:n] = path[:n]
        marks = waypoint_marks(len(buffer))
        marks[0][:n], marks[2][:len(memo)] = ids[:n], remembered
        m = shortcut_rows(ctx, buffer, n, marks, np.random.default_rng(1), 4, 0.0, 0.05, ctx.resolution, spent,
                          prune_first=False)
        handed.append((buffer[:m], spent[0]))
    np.testing.assert_array_equal(handed[0][0], handed[1][0])
    assert handed[0][1] < handed[1][1]
    empty = PlanningContext(model, [], spheres=spheres)
    straight = np.array([start, 0.5 * (start + goal), goal])  # collinear: pruned without a check
    assert len(shortcut(empty, straight, rng)) == 2
    ids, checked, memo = waypoint_marks(3)
    checked[:2] = True, False  # an edge merged from collinear ones is checked only if they all were
    assert prune(straight.copy(), 3, (ids, checked, memo), *work, np.zeros(1, int)) == 2 and not checked[0]
    corner = np.array([start, [0.9, 0.1, 0.1], goal])  # monotone joints: saves no length, still cut
    np.testing.assert_array_equal(shortcut(empty, corner, rng), corner[[0, 2]])


@pytest.mark.parametrize("axes", [("z", "y", "x"), ("x", "z", "y")])
def test_ball_joint_weights_bound_the_speed_of_every_ball(axes):
    model = _arm(axes)
    spheres = generate_sphere_model(model, cache=False)
    W = ball_joint_weights(model, spheres.sphere_link, spheres.centers, spheres.radii)
    rng = np.random.default_rng(0)
    directions = rng.normal(size=(40, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    for q in model.random_configurations(rng, 30):
        for j in range(model.dof):
            k = int(np.flatnonzero(model.joint_q_index == j)[0])
            dq = np.zeros(model.dof)
            dq[j] = 1e-7
            before, after = forward_kinematics(model, q), forward_kinematics(model, q + dq)
            for s, (link, c, r) in enumerate(zip(spheres.sphere_link, spheres.centers, spheres.radii)):
                points = c + r * directions  # on the ball's surface: the fastest points of the ball
                moved = np.linalg.norm((points @ after[link][:3, :3].T + after[link][:3, 3])
                                       - (points @ before[link][:3, :3].T + before[link][:3, 3]), axis=1)
                assert moved.max() / 1e-7 <= W[s, k] * (1 + 1e-5) + 1e-9


def test_a_space_names_its_joints_when_given_the_wrong_ones():
    model = robots.load("panda")
    with pytest.raises(PrehensileError, match=r"'panda_joint1' is a joint, not a chain .* as a list: \['panda_joint1'\]"):
        PlanningContext(model, [], joints="panda_joint1")
    space = PlanningContext(model, [], joints=["panda_joint1", "panda_joint2"]).space
    assert np.array_equal(space.full([0.1, 0.2])[:3], [0.1, 0.2, model.neutral_configuration()[2]])
    with pytest.raises(PrehensileError, match=r"full: expected the 2 planned joints \(panda_joint1, panda_joint2\)"):
        space.full(np.zeros(8))


def test_pair_weights_bound_how_fast_every_link_pair_can_close_in():
    """Panda: branching fingers, a prismatic mimic joint; a ball per link, every pair and the world.
    A pair's distance changes along a straight segment by no more than its weights allow."""
    model = robots.load("panda")
    rng = np.random.default_rng(4)
    centers, radii = rng.uniform(-0.05, 0.05, size=(model.n_links, 3)), rng.uniform(0.01, 0.1, model.n_links)
    link_weights = ball_joint_weights(model, np.arange(model.n_links), centers, radii)
    pairs = np.array([(a, b) for a in range(model.n_links) for b in range(-1, model.n_links) if a != b])
    W = motion_weights(model, link_weights, pairs)
    directions = rng.normal(size=(12, 3))
    directions /= np.linalg.norm(directions, axis=1)[:, None]
    world = rng.uniform(-1.0, 1.0, size=(12, 3))
    qs = model.random_configurations(rng, 20)
    for qa, qb in zip(qs[:-1], qs[1:]):
        qb = qa + rng.uniform(0.01, 0.3) * (qb - qa)
        ends = forward_kinematics(model, qa), forward_kinematics(model, qb)
        bound = W @ np.abs(qb - qa)
        points = [[(centers[k] + radii[k] * directions) @ T[k][:3, :3].T + T[k][:3, 3] for k in range(model.n_links)]
                  for T in ends]  # on each link's ball, in the world
        for p, (a, b) in enumerate(pairs):
            gaps = [np.linalg.norm(at[a][:, None] - (at[b] if b >= 0 else world)[None], axis=2) for at in points]
            assert np.abs(gaps[1] - gaps[0]).max() <= bound[p] + 1e-12, (model.link_names[a], b)
    fingers = [model.link_index(f"panda_{side}finger") for side in ("left", "right")]
    siblings = W[np.flatnonzero((pairs == fingers).all(axis=1))[0]]  # the arm moves both fingers alike
    assert np.all(siblings[:7] == 0.0) and siblings[7] > 0.0
    assert np.all(W[np.flatnonzero((pairs == [fingers[0], -1]).all(axis=1))[0]] > 0.0)


@pytest.mark.parametrize("axes", [("z", "z", "z"), ("z", "y", "x")])
def test_bubbles_never_pass_a_segment_that_dense_sampling_finds_colliding(axes):
    """At a tiny resolution the check rests on the free bubbles alone (world and self pairs)."""
    model = _arm(axes)
    spheres = generate_sphere_model(model, cache=False)
    ctx = PlanningContext(model, [_box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])], spheres=spheres,
                          resolution=1e-5)
    rng = np.random.default_rng(3)
    valid = [q for q in model.random_configurations(rng, 200) if ctx.is_valid(q)]
    verdicts = []
    for a, b in zip(valid[:-1], valid[1:]):
        b = a + rng.uniform(0.1, 1.0) * (b - a)
        verdicts.append(ctx.check_motion(a, b))
        dense = a + np.linspace(0, 1, 500)[:, None] * (b - a)
        if verdicts[-1]:
            assert np.all(ctx.spheres.is_free(dense))
        if ctx.is_valid(b):  # ends known free: the check starts in the middle
            known = motion_free(a, b, ctx.resolution, ctx.spheres.data, ctx.scratch,
                                ctx.motion_arrays(ctx.resolution), ctx.counters, NO_LIMIT, 0)
            assert known != FREE or np.all(ctx.spheres.is_free(dense))
    assert 10 < sum(verdicts) < len(verdicts) - 10  # both outcomes are exercised


def test_segment_with_free_ends_blocked_in_the_middle_takes_one_evaluation(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [_box("wall", [0.55, 0.25, 0.1], [0.1, 0.3, 0.3])], spheres=spheres)
    start, goal = np.array([0.0, 0.2, 0.0]), np.array([1.2, -0.3, 0.4])
    assert ctx.is_valid(start) and ctx.is_valid(goal) and not ctx.is_valid(0.5 * (start + goal))
    counters = np.zeros(1, dtype=np.int64)
    for new_ends in (0, 1, 2):  # new ends are tested first
        counters[0] = 0
        assert motion_free(start, goal, ctx.resolution, ctx.spheres.data, ctx.scratch,
                           ctx.motion_arrays(ctx.resolution), counters, NO_LIMIT, new_ends) == BLOCKED
        assert counters[0] == new_ends + 1


@pytest.mark.parametrize("slack", [0.0, 0.01])
def test_free_bubbles_of_self_pairs_hold(slack):
    """On the folding arm without obstacles (only self pairs count), the bubble of q(s) on a
    segment, s +- the scaled clearance, holds no configuration where two balls overlap by more
    than ``slack`` (m): the balls shrunk by half the slack are free there."""
    model = _arm(("y", "y", "y"))
    balls = generate_sphere_model(model, cache=False)
    ctx = PlanningContext(model, [], spheres=balls)
    shrunk = SphereModel(balls.link_names, balls.sphere_link, balls.centers, balls.radii - 0.5 * slack, False)
    judge = PlanningContext(model, [], spheres=shrunk).spheres
    data, motion = ctx.spheres.data, ctx.motion_arrays(ctx.resolution)
    rng = np.random.default_rng(4)
    qs = model.random_configurations(rng, 400)
    blocked = 0
    for qa, qb in zip(qs[:-1], qs[1:]):
        _scales(qa, qb, data[-1], motion)
        s = rng.uniform()
        bubble = SK.clearance(qa + s * (qb - qa), data, ctx.scratch, 1.0, motion[4], slack)
        if bubble > 0:
            inside = np.linspace(max(s - bubble, 0.0), min(s + bubble, 1.0), 200)
            assert np.all(judge.is_free(qa + inside[:, None] * (qb - qa)))
            blocked += not np.all(judge.is_free(qa + np.linspace(0, 1, 200)[:, None] * (qb - qa)))
    assert blocked >= 10  # segments whose bubbles had a self-collision to stay clear of


def _mbm_setup():
    require_shared(MBM)
    from prehensile.collision.spheres import pad_sphere_model, spheres_from_urdf
    from prehensile.model import load_urdf
    from prehensile.scene.moveit import iter_mbm_problems

    folder = MBM / "panda"
    model = load_urdf(folder / "panda.urdf", folder / "panda.srdf")
    spheres = pad_sphere_model(spheres_from_urdf(model, folder / "panda_spherized.urdf"), model)
    return model, spheres, iter_mbm_problems(folder / "problems.tar.bz2")


def test_mbm_problems_give_certified_exact_paths():
    model, spheres, problems = _mbm_setup()
    picked = {("table_pick_panda", 1), ("box_panda", 2), ("bookshelf_small_panda", 4), ("cage_panda", 5),
              ("cage_panda", 4)}
    solved = escaped = 0
    for problem in problems:
        if (problem.scenario, problem.index) not in picked:
            continue
        ctx = PlanningContext(model, problem.scene.collision_obstacles(), spheres=spheres)
        start, goal = problem.request.start_configuration(model), problem.request.goal_configuration(model)
        result = rrt_connect(ctx, start, goal, FAST, np.random.default_rng(problem.index))
        _check_result(ctx, result, start, goal)
        solved += 1
        if not ctx.is_valid(goal):  # cage 4: a grasp the padded balls reject, left by a certified escape
            escaped += 1
            strict = RRTConnectSettings(time_budget_s=0.2, escape=False)
            assert rrt_connect(ctx, start, goal, strict).status is PlanStatus.INVALID_GOAL
    assert solved == 5 and escaped == 1


def test_mbm_search_paths_pass_the_sphere_motion_check():
    """Every edge of a search's path passes the motion check on the balls, the goal tree's
    provisional edges too when a direct edge from the start reaches a node the goal tree grew
    (with these settings, the 52nd cage problem returned such an edge unchecked, and blocked)."""
    require_shared(MBM)
    from prehensile.benchmarking.mbm import MBMSettings, PreparedProblem, benchmark_spheres, load_problems
    from prehensile.model import load_urdf

    folder = MBM / "panda"
    model = load_urdf(folder / "panda.urdf", folder / "panda.srdf")
    spheres = benchmark_spheres(model, folder / "panda_spherized.urdf")
    cage = [p for p in load_problems(folder / "problems.tar.bz2", model, 52) if p.scenario == "cage_panda"][51]
    prepared = PreparedProblem(model, spheres, cage, MBMSettings())
    ctx = prepared.ctx
    settings = RRTConnectSettings(time_budget_s=2.0, eager_checks=8, shortcut=False, certify=False)
    path = rrt_connect(ctx, prepared.q_start, prepared.q_goal, settings, np.random.default_rng(251)).path
    assert len(path) >= 2 and all(ctx.check_motion(a, b) for a, b in zip(path[:-1], path[1:]))


def test_a_robot_standing_on_a_table_plans():
    """The base's balls reach below the base: only the exact geometry tells standing on a
    table (free) from standing in it (every configuration collides)."""
    panda = robots.load("panda")
    ready = np.array([0.0, -0.785, 0.0, -2.356, 0.0, 1.571, 0.785, 0.02])
    goal = ready.copy()
    goal[0] = 1.0
    for depth in (-0.001, 0.005):  # table top 1 mm below the base, 5 mm above its underside
        table = _box("table", [0.5, 0.0, -0.02 + depth], [1.2, 1.6, 0.04])
        ctx = PlanningContext(panda, [table], joints="arm", q_ref=ready)
        result = rrt_connect(ctx, ready, goal, FAST, np.random.default_rng(0))
        if depth < 0:
            assert not ctx.spheres.static_hit and ctx.why_invalid(ready) == ""
            _check_result(ctx, result, ready, goal)
        else:
            assert result.status is PlanStatus.INVALID_START
            assert ctx.why_invalid(ready) == "panda_link0 collides with table (5.03 mm deep)"


def test_a_humanoid_standing_on_the_floor_plans_an_arm():
    """NAO's feet do not move when it plans its left arm: their balls, which reach into the
    floor, are left out; the exact geometry tells standing 1 mm above the floor from standing
    in it."""
    nao = robots.load("nao")
    q = nao.neutral_configuration()
    for joint, value in dict(LShoulderPitch=1.0, LShoulderRoll=0.3, LElbowRoll=-0.3, RShoulderPitch=1.0,
                             RShoulderRoll=-0.3, RElbowRoll=0.3).items():
        q[nao.joint_index(joint)] = value
    goal = q.copy()
    goal[nao.joint_index("LShoulderPitch")] = -0.3
    floor = _box("floor", [0.0, 0.0, -0.05], [2.0, 2.0, 0.1])
    for height, free in ((0.334, True), (0.328, False)):  # the soles 1 mm above the floor, 5 mm in it
        ctx = PlanningContext(nao, [floor], joints="left_arm", q_ref=q, T_world_base=make_pose(position=[0, 0, height]))
        assert ctx.still_links[nao.link_index("l_ankle")] and not ctx.still_links[nao.link_index("LBicep")]
        assert bool(ctx.static_free(q)) == free and ctx.exact.is_free(q) == free
        result = rrt_connect(ctx, q, goal, FAST, np.random.default_rng(0))
        if free:
            _check_result(ctx, result, q, goal)
        else:
            assert result.status is PlanStatus.INVALID_START and "collides with floor" in ctx.why_invalid(q)


@pytest.mark.parametrize("kwargs, message", [
    ({"obstacles": [Box((0.1, 0.1, 0.1))]}, r"obstacles\[0\]: expected an Obstacle"),
    ({"obstacles": [Obstacle("empty", Mesh.from_arrays(np.zeros((0, 3)), np.zeros((0, 3))), np.eye(4))]},
     r"obstacles\[0\] 'empty'.*positive size"),
    ({"obstacles": [Obstacle("ball", Sphere(0.1), np.diag([2.0, 2.0, 2.0, 1.0]))]}, "not a rotation matrix"),
    ({"T_world_base": np.full((4, 4), np.nan)}, "T_world_base: contains NaN"),
    ({"T_world_base": np.eye(3)}, r"T_world_base: expected shape \(\.\.\., 4, 4\)"),
    ({"q_ref": np.zeros((1, 3))}, r"q_ref: expected one configuration \(3,\) for robot .arm., got shape \(1, 3\)"),
    ({"acm": np.zeros((3, 3), dtype=bool)}, r"acm must be \(\d+, \d+\)"),
])
def test_bad_context_inputs_are_errors(arm, kwargs, message):
    model, spheres = arm
    kwargs = {"obstacles": [], **kwargs}
    with pytest.raises(PrehensileError, match=message):
        PlanningContext(model, kwargs.pop("obstacles"), spheres=spheres, **kwargs)


def test_a_timeout_names_links_whose_balls_overlap_almost_everywhere(arm):
    """Balls on the base that reach every pose of l2 (whose geometry never comes near it) leave
    no free configuration; a timeout says so, with how often the geometry collides."""
    model, spheres = arm
    fat = spheres.radii.copy()
    fat[spheres.sphere_link == model.link_index("base")] = 0.9
    ctx = PlanningContext(model, [], spheres=SphereModel(spheres.link_names, spheres.sphere_link, spheres.centers, fat))
    q = np.array([[0.0, 0.0, 0.0], [1.0, -2.0, 2.0]])
    overlaps = ctx.spheres.link_overlaps(q)
    for k in range(len(q)):
        names = model.link_names
        assert [(names[a], names[b]) for a, b in np.argwhere(overlaps[k])] == ctx.spheres.ball_contacts(q[k])
    assert ctx.overlapping_links() == [("base", "l2", 64, 0), ("base", "l3", 64, 0)]
    timeout = PlanResult(PlanStatus.TIMEOUT, np.zeros((0, 3)), PlanStats(iterations=10))
    reason = ctx.explain(timeout, q[0], q[1]).info["reason"]
    assert reason.startswith("the balls of base and l2 overlap in 64 of 64 random configurations (their geometry "
                             "collides in 0); the balls of base and l3 overlap in 64 of 64"), reason
    assert "disable such a pair in the SRDF" in reason
    plain = PlanningContext(model, [], spheres=spheres)
    assert plain.overlapping_links() == [] and "reason" not in plain.explain(timeout, q[0], q[1]).info
