"""J+-RRT, IK-RRT (one arm, bimanual, hand-over) and Multi-EEF-RRT: paths start where asked,
reach a grasp, respect the limits and pass the exact check; statuses; determinism."""

from __future__ import annotations

import numpy as np
import pytest

from prehensile import robots
from prehensile.collision import Obstacle
from prehensile.collision.spheres import generate_sphere_model
from prehensile.errors import PrehensileError
from prehensile.ik import ChainSolver, ObjectRegion
from prehensile.model.geometry import Box, Cylinder, Sphere
from prehensile.planning import PlanningContext, PlanStatus, certify_path
from prehensile.planning.ik_rrt import (IKRRTSettings, _Search, dual_arm_sampler, grasp_sampler, ik_rrt,
                                        multi_eef_rrt, regrasp_sampler)
from prehensile.planning.jplus_rrt import JPlusRRTSettings, jplus_rrt, regrasp_jplus_rrt
from prehensile.scene import PoseGoal
from prehensile.spatial import invert, make_pose, rotation_error


@pytest.fixture(scope="module")
def panda_scene():
    model = robots.load("panda")
    wall = Obstacle("wall", Box((0.3, 0.02, 0.4)), make_pose(position=[0.45, 0.0, 0.3]))
    ctx = PlanningContext(model, [wall], joints="arm")
    solver = ChainSolver(model, "arm")
    q0 = model.neutral_configuration()
    q0[[1, 3, 5]] = [-0.5, -2.0, 1.5]
    rng, goals = np.random.default_rng(0), []
    while len(goals) < 3:  # grasp poses on the other side of the wall
        q = q0.copy()
        q[ctx.space.indices] = rng.uniform(ctx.space.lower, ctx.space.upper)
        T = solver.tool_pose(q)
        if ctx.is_valid(q) and T[1, 3] > 0.1:
            goals.append(T)
    return ctx, solver, q0, np.array(goals)


def assert_valid_path(ctx, path, q_start):
    assert np.array_equal(path[0], q_start)
    assert np.all(ctx.model.within_limits(path))
    assert certify_path(ctx, path).ok


def test_jplus_rrt_reaches_a_grasp(panda_scene):
    ctx, solver, q0, goals = panda_scene
    settings = JPlusRRTSettings(time_budget_s=5.0)
    result = jplus_rrt(ctx, q0, goals, settings=settings, rng=1)
    assert result.success and 0 <= result.goal_index < len(goals)
    assert_valid_path(ctx, result.path, q0)
    tool = solver.tool_pose(result.path[-1])
    target = goals[result.goal_index]
    assert np.linalg.norm(tool[:3, 3] - target[:3, 3]) <= settings.position_tolerance
    assert np.linalg.norm(rotation_error(target[:3, :3], tool[:3, :3])) <= settings.rotation_tolerance
    again = jplus_rrt(ctx, q0, goals, settings, np.random.default_rng(1))  # as rrt_connect; a seed or its generator
    assert np.array_equal(again.path, result.path)


def test_ik_rrt_reaches_a_grasp(panda_scene):
    ctx, solver, q0, goals = panda_scene
    result = ik_rrt(ctx, q0, grasp_sampler(ctx, solver, goals, q0), rng=None)
    assert result.success and result.stats.ik_solutions >= 1
    assert_valid_path(ctx, result.path, q0)
    grasp = result.info["goal"]["grasp"]
    assert result.goal_index == grasp  # the pose reached, as in jplus_rrt
    assert np.linalg.norm(solver.tool_pose(result.path[-1])[:3, 3] - goals[grasp, :3, 3]) <= 1e-4
    again = ik_rrt(ctx, q0, grasp_sampler(ctx, solver, goals, q0), rng=0)  # None is seed 0
    assert np.array_equal(again.path, result.path)


@pytest.mark.parametrize("planner", ["ik_rrt", "jplus_rrt"])
def test_a_grasp_around_a_can_that_only_the_balls_reject_is_reached(planner):
    """Open fingers around a 3 cm can: free on the meshes, the hand's balls touch the can. The
    IK goal is kept (IK-RRT) and the last Jacobian steps are certified exactly (J+-RRT)."""
    model = robots.load("panda")
    start = np.array([0.0, -0.3, 0.0, -2.2, 0.0, 2.0, 0.785, 0.04])
    grasp = np.array([0.0, 0.3, 0.0, -2.0, 0.0, 2.3, 0.785, 0.04])
    solver = ChainSolver(model, "arm")
    T_grasp = solver.tool_pose(grasp)
    can = Obstacle("can", Cylinder(0.015, 0.06), T_grasp)
    ctx = PlanningContext(model, [can], joints="arm", q_ref=start)
    assert not ctx.is_valid(grasp) and ctx.exact.is_free(grasp) and ctx.is_usable_end(grasp)
    if planner == "ik_rrt":
        result = ik_rrt(ctx, start, grasp_sampler(ctx, solver, T_grasp[None], start), IKRRTSettings(5.0), rng=0)
    else:
        result = jplus_rrt(ctx, start, T_grasp[None], JPlusRRTSettings(5.0), rng=0)
    assert result.success and result.goal_index == 0
    assert_valid_path(ctx, result.path, start)
    assert np.linalg.norm(solver.tool_pose(result.path[-1])[:3, 3] - T_grasp[:3, 3]) <= 1e-3
    assert not ctx.is_valid(result.path[-1])  # the balls still touch the can there


def test_ik_planners_to_a_pose_the_start_reaches_stay_there(panda_scene):
    """The first IK seed is q_ref: a start already at one of the poses is the goal
    configuration. Both planners return two waypoints, as rrt_connect from a start to itself."""
    ctx, solver, q0, goals = panda_scene
    poses = np.concatenate((goals[:1], solver.tool_pose(q0)[None]))
    for result in (ik_rrt(ctx, q0, grasp_sampler(ctx, solver, poses, q0), rng=3), jplus_rrt(ctx, q0, poses, rng=3)):
        assert result.success and result.goal_index == 1
        assert result.path.shape == (2, ctx.model.dof) and np.abs(result.path - q0).max() < 1e-6


def test_jplus_rrt_says_how_near_it_came_when_it_times_out(panda_scene):
    ctx, solver, q0, goals = panda_scene
    far = goals[:1].copy()
    far[0, :3, 3] += [2.0, 0.0, 0.0]  # 2 m beyond a reachable grasp: out of reach
    result = jplus_rrt(ctx, q0, far, settings=JPlusRRTSettings(time_budget_s=0.2), rng=0)
    assert result.status is PlanStatus.TIMEOUT
    reason = result.info["reason"]
    assert reason.startswith("no goal reached: the tool came within ") and "out of reach" in reason
    nearest = float(reason.split("within ")[1].split(" mm")[0]) / 1e3
    reach = np.linalg.norm(goals[0, :3, 3] + [2.0, 0.0, 0.0] - solver.tool_pose(q0)[:3, 3])
    assert 1.0 < nearest < reach + 1e-3  # at least 2 m less the arm's reach, no farther than the start's tool


def test_ik_planners_start_where_only_the_balls_collide(panda_scene):
    """As rrt_connect: a start the conservative balls reject but the meshes do not leaves along
    a certified escape motion."""
    ctx, solver, _, goals = panda_scene
    q = ctx.model.neutral_configuration()  # the balls of link 5 and a finger overlap
    assert not ctx.is_valid(q) and ctx.exact.is_free(q)
    for result in (ik_rrt(ctx, q, grasp_sampler(ctx, solver, goals, q), rng=0), jplus_rrt(ctx, q, goals, rng=0)):
        assert result.success
        assert_valid_path(ctx, result.path, q)
    refused = jplus_rrt(ctx, q, goals, settings=JPlusRRTSettings(escape=False))
    assert refused.status is PlanStatus.INVALID_START
    assert refused.info["reason"].startswith("start: free on the exact geometry, but the sphere model's")
    outside = q.copy()
    outside[ctx.space.indices[0]] = ctx.model.upper[ctx.space.indices[0]] + 0.1
    result = ik_rrt(ctx, outside, grasp_sampler(ctx, solver, goals, q), rng=0)
    assert result.status is PlanStatus.INVALID_START and result.info["reason"].startswith("start: joint ")


def test_jplus_rrt_moves_the_named_chain_planned_in_any_joint_order(panda_scene):
    from dataclasses import replace

    from prehensile.model.robot_model import Chain

    ctx, _, q0, _ = panda_scene
    model = ctx.model
    arm = model.chain("arm")
    wrist = Chain("wrist", arm.base_link, "panda_link7", arm.joint_names)  # same joints, another tip
    model = replace(model, chains={**model.chains, "wrist": wrist})
    ctx = PlanningContext(model, [], joints=list(arm.joint_names[::-1]), q_ref=q0)  # the chain's joints reversed
    goal = q0.copy()
    goal[[1, 3]] += [0.3, 0.4]
    solver = ChainSolver(model, "wrist")
    target = solver.tool_pose(goal)
    with pytest.raises(PrehensileError, match="chains arm, wrist all move the planned joints"):
        jplus_rrt(ctx, q0, target[None])
    result = jplus_rrt(ctx, q0, target[None], settings=JPlusRRTSettings(time_budget_s=5.0), rng=0, chain="wrist")
    assert result.success and result.stats.iterations < 200  # Jacobian steps in the chain's own order
    assert np.linalg.norm(solver.tool_pose(result.path[-1])[:3, 3] - target[:3, 3]) <= 1e-3
    with pytest.raises(PrehensileError, match="chain 'hand' moves panda_finger_joint1, the context plans"):
        jplus_rrt(ctx, q0, target[None], chain="hand")


def test_solvers_placed_elsewhere_than_the_robot_are_errors(panda_scene):
    ctx, solver, q0, goals = panda_scene
    moved = ChainSolver(ctx.model, "arm", T_world_root=make_pose(position=[0.15, 0.1, 0.0]))
    with pytest.raises(PrehensileError, match="grasp_sampler: the solver of chain 'arm' has T_world_root"):
        grasp_sampler(ctx, moved, goals, q0)
    with pytest.raises(PrehensileError, match="dual_arm_sampler: the solver of chain 'arm'"):
        dual_arm_sampler(ctx, [solver, moved], [goals, goals], q0)
    with pytest.raises(PrehensileError, match=r"dual_arm_sampler: expected two arms of different chains"):
        dual_arm_sampler(ctx, [solver, solver], [goals, goals], q0)
    with pytest.raises(PrehensileError, match=r"grasp_sampler: q_ref: expected shape \(\.\.\., 8\)"):
        grasp_sampler(ctx, solver, goals, q0[:7])
    fingers = ChainSolver(ctx.model, "hand")
    with pytest.raises(PrehensileError, match="grasp_sampler: chain 'hand' moves panda_finger_joint1, which the "
                                              "context does not plan"):
        grasp_sampler(ctx, fingers, goals, q0)


def test_a_sampler_whose_q_ref_moves_unplanned_joints_is_refused_up_front(panda_scene):
    ctx, solver, q0, goals = panda_scene
    q_ref = q0.copy()
    q_ref[7] = 0.035  # the fingers differ from the start's; the context plans the arm only
    with pytest.raises(PrehensileError, match=r"grasp_sampler: q_ref and the start differ in joints the context does "
                                              r"not plan \(panda_finger_joint1; planned: panda_joint1"):
        ik_rrt(ctx, q0, grasp_sampler(ctx, solver, goals, q_ref), rng=0)
    with pytest.raises(PrehensileError, match="multi_eef_rrt: the sampler of 'left' is a function, not a GoalSampler"):
        multi_eef_rrt(ctx, q0, {"left": lambda rng, call, attempts, budget: (None, {})})
    with pytest.raises(PrehensileError, match="ik_rrt: the sampler is a ndarray, not a GoalSampler"):
        ik_rrt(ctx, q0, goals)


def test_a_sampler_takes_q_ref_as_a_list(panda_scene):
    ctx, solver, q0, goals = panda_scene
    result = ik_rrt(ctx, q0, grasp_sampler(ctx, solver, goals, q0.tolist()), rng=0)
    assert result.status is PlanStatus.SUCCESS
    assert_valid_path(ctx, result.path, q0)


def test_multi_eef_rrt_statistics_are_totals_over_the_hands(monkeypatch):
    """Two hands turning panda_joint1 to a goal behind a wall: both search until the budget ends."""
    model = robots.load("panda")
    start = np.array([-0.9, 0.3, 0.0, -1.8, 0.0, 2.1, 0.785, 0.02])
    wall = Obstacle("wall", Box((0.3, 0.06, 0.8)), make_pose(position=[0.45, 0.0, 0.4]))
    ctx = PlanningContext(model, [wall], joints=["panda_joint1"], q_ref=start)
    solver = ChainSolver(model, base="panda_link0", tip="panda_link1")
    goal = start.copy()
    goal[0] = 0.9
    target = solver.tool_pose(goal)[None]
    searches = []
    step = _Search.step

    def recorded_step(search, *args):
        searches.append(search)
        return step(search, *args)

    monkeypatch.setattr(_Search, "step", recorded_step)
    samplers = {hand: grasp_sampler(ctx, solver, target, start) for hand in ("a", "b")}
    result = multi_eef_rrt(ctx, start, samplers, IKRRTSettings(time_budget_s=0.3), rng=0)
    assert result.status is PlanStatus.TIMEOUT
    hands = set(searches)
    assert len(hands) == 2 and all(s.iterations > 0 and s.infos for s in hands)
    assert result.stats.iterations == sum(s.iterations for s in hands)
    assert result.stats.collision_checks == sum(s.checks for s in hands)
    assert result.stats.nodes == sum(s.nodes for s in hands)
    assert result.stats.ik_solutions == sum(len(s.infos) for s in hands)


def test_multi_eef_rrt_names_missing_samplers_and_contexts(panda_scene):
    ctx, solver, q0, goals = panda_scene
    with pytest.raises(PrehensileError, match="no goal samplers"):
        multi_eef_rrt(ctx, q0, {})
    with pytest.raises(PrehensileError, match="no context for right; contexts: left"):
        multi_eef_rrt({"left": ctx}, q0, {"right": grasp_sampler(ctx, solver, goals, q0)})


def test_jplus_rrt_reaches_a_pose_only_reachable_at_a_joint_limit():
    """Jacobian steps are clamped into the limits: the tool pointing forward at table height
    needs panda_joint2 or panda_joint5 at a limit in every IK solution found."""
    model = robots.load("panda")
    ref = np.array([0.0, -0.5, 0.0, -2.0, 0.0, 1.5, 0.785, 0.02])
    ctx = PlanningContext(model, [], joints="arm", q_ref=ref)
    target = make_pose(np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]]), [0.58, 0.0, 0.45])
    result = jplus_rrt(ctx, ref, target[None], JPlusRRTSettings(time_budget_s=20.0), rng=2)
    assert result.success, result.status
    assert_valid_path(ctx, result.path, ref)
    reached = ChainSolver(model, "arm").tool_pose(result.path[-1])
    assert np.linalg.norm(reached[:3, 3] - target[:3, 3]) <= JPlusRRTSettings().position_tolerance + 1e-9


def test_jplus_rrt_takes_one_start(panda_scene):
    ctx, _, q0, goals = panda_scene
    for start in (q0[None], np.stack([q0, q0])):
        with pytest.raises(PrehensileError, match=r"q_start: expected one configuration \(\d+,\)"):
            jplus_rrt(ctx, start, goals)


def test_settings_are_validated():
    # an infinite budget would search forever for an unreachable pose, or fail in the inner search
    for bad, valid in (({"time_budget_s": -1.0}, "> 0 and finite, got -1.0"),
                       ({"time_budget_s": np.inf}, "> 0 and finite, got inf"),
                       ({"ik_attempts": 0}, "an integer >= 1, got 0"),
                       ({"first_round_iterations": 0}, "an integer >= 1")):
        with pytest.raises(PrehensileError, match=f"IKRRTSettings.{next(iter(bad))} must be {valid}"):
            IKRRTSettings(**bad)
    for bad, valid in (({"goal_probability": 2.0}, r"in \[0, 1\], got 2.0"), ({"time_budget_s": 0.0}, "> 0"),
                       ({"time_budget_s": np.inf}, "> 0 and finite"), ({"max_nodes": 0}, "an integer >= 2"),
                       ({"step": np.nan}, "> 0, got nan")):
        with pytest.raises(PrehensileError, match=f"JPlusRRTSettings.{next(iter(bad))} must be {valid}"):
            JPlusRRTSettings(**bad)


def test_rounds_that_never_search_end_in_a_status(panda_scene):
    """A sampler whose every goal the planner rejects (here: beyond a joint limit) makes rounds
    that end before searching; they no longer double the round size (which overflowed after
    about 56 such rounds, e.g. after a restart on covering balls that reject every IK goal)."""
    from prehensile.planning import GoalSampler

    ctx, _, q0, _ = panda_scene
    beyond = q0.copy()
    beyond[ctx.space.indices[0]] = ctx.model.upper[ctx.space.indices[0]] + 0.5
    calls = []
    sampler = GoalSampler("beyond", q0, lambda rng, call, attempts, budget: (calls.append(call) or beyond, {}))
    result = ik_rrt(ctx, q0, sampler, IKRRTSettings(time_budget_s=0.2), rng=0)
    assert result.status is PlanStatus.TIMEOUT and len(calls) > 100 and result.stats.iterations == 0


def test_unreachable_goals_are_statuses_within_budget(panda_scene):
    ctx, solver, q0, goals = panda_scene
    far = np.eye(4)
    far[:3, 3] = [0.0, 0.0, 3.0]
    result = ik_rrt(ctx, q0, grasp_sampler(ctx, solver, far[None], q0), IKRRTSettings(time_budget_s=0.2), rng=0)
    assert result.status is PlanStatus.NO_GOAL_CONFIGURATION and result.stats.plan_time_s < 0.4
    assert result.blamed_ends == ()  # IK's failure, not an end's
    assert result.info["reason"].startswith("no valid goal configuration: IK failed on all ")
    result = jplus_rrt(ctx, q0, far[None], settings=JPlusRRTSettings(time_budget_s=0.2), rng=0)
    assert result.status is PlanStatus.TIMEOUT and result.stats.plan_time_s < 0.4
    colliding = q0.copy()
    colliding[ctx.space.indices] = solver.lower  # folded into the floor / itself
    if not ctx.is_valid(colliding):
        assert jplus_rrt(ctx, colliding, goals, rng=0).status is PlanStatus.INVALID_START


@pytest.fixture(scope="module")
def armar():
    model = robots.load("armar3")
    # the torso box needs small balls: the default cover overlaps the upper arms at rest
    return model, ChainSolver(model, "LeftArm"), ChainSolver(model, "RightArm"), generate_sphere_model(model, max_radius=0.04)


def two_hand_pose(model, left, right, spheres, seed):
    """A planning context for hip and both arms, and the hand poses of a valid configuration."""
    ctx = PlanningContext(model, [], joints="TorsoBothArms", spheres=spheres)
    rng = np.random.default_rng(seed)
    for _ in range(1000):
        q = model.neutral_configuration()
        q[ctx.space.indices] = rng.uniform(ctx.space.lower, ctx.space.upper)
        if ctx.is_valid(q):
            return ctx, left.tool_pose(q), right.tool_pose(q)
    raise AssertionError("no valid two-arm configuration in 1000 samples")


def test_bimanual_and_hand_over_ik_rrt(armar):
    model, left, right, spheres = armar
    ctx, T_left, T_right = two_hand_pose(model, left, right, spheres, seed=4)
    q0 = model.neutral_configuration()
    sampler = dual_arm_sampler(ctx, [left, right], [T_left[None], T_right[None]], q0, free="Torso")
    result = ik_rrt(ctx, q0, sampler, IKRRTSettings(time_budget_s=10.0), rng=0)
    assert result.success and result.info["goal"]["grasps"] == (0, 0)
    # IK attempts and search iterations, not seconds, end the rounds: the same seed, the same path
    again = ik_rrt(ctx, q0, dual_arm_sampler(ctx, [left, right], [T_left[None], T_right[None]], q0, free="Torso"),
                   IKRRTSettings(time_budget_s=10.0), rng=0)
    np.testing.assert_array_equal(again.path, result.path)
    assert_valid_path(ctx, result.path, q0)
    assert np.linalg.norm(left.tool_pose(result.path[-1])[:3, 3] - T_left[:3, 3]) <= 1e-4
    # hand-over: the object sits at the left TCP; the right hand holds it by a fixed grasp
    grasps = [np.eye(4)[None], (invert(T_left) @ T_right)[None]]
    region = ObjectRegion(tuple(T_left[:3, 3] - 0.05), tuple(T_left[:3, 3] + 0.05))
    result = ik_rrt(ctx, q0, regrasp_sampler(ctx, [left, right], grasps, region, q0, free="Torso"),
                    IKRRTSettings(time_budget_s=20.0), rng=0)
    assert result.success
    assert_valid_path(ctx, result.path, q0)
    T_object = result.info["goal"]["T_world_object"]
    np.testing.assert_allclose(right.tool_pose(result.path[-1])[:3, 3], (T_object @ grasps[1][0])[:3, 3], atol=1e-4)


def test_free_joints_the_context_does_not_plan_are_refused_up_front(armar):
    model, left, right, spheres = armar
    arms_only = [*left.chain.joint_names, *right.chain.joint_names]
    ctx = PlanningContext(model, [], joints=arms_only, spheres=spheres)
    q0 = model.neutral_configuration()
    poses = [left.tool_pose(q0)[None], right.tool_pose(q0)[None]]
    message = r"{}: the free joints Hip_\w+, Hip_\w+, Hip_\w+ are not planned by the context \(planned: "
    with pytest.raises(PrehensileError, match=message.format("dual_arm_sampler")):
        dual_arm_sampler(ctx, [left, right], poses, q0, free="Torso")
    with pytest.raises(PrehensileError, match=message.format("regrasp_sampler")):
        regrasp_sampler(ctx, [left, right], [np.eye(4)[None], np.eye(4)[None]], None, q0, free="Torso")
    with pytest.raises(PrehensileError, match=message.format(r"regrasp J\+-RRT")):
        regrasp_jplus_rrt(ctx, q0, [left, right], [np.eye(4)[None], np.eye(4)[None]], free="Torso")


def test_multi_eef_rrt_picks_the_free_hand(armar):
    model, _, _, spheres = armar
    left, right = ChainSolver(model, "TorsoLeftArm"), ChainSolver(model, "TorsoRightArm")
    q0 = model.neutral_configuration()
    target = right.tool_pose(q0)
    target[:3, 3] += [-0.05, 0.15, -0.05]
    # a box around the right hand's grasp pose: only the left hand can take its (mirrored) grasp
    box = Obstacle("box", Box((0.15, 0.15, 0.15)), make_pose(position=target[:3, 3]))
    contexts = {"Hand_L": PlanningContext(model, [box], joints="TorsoLeftArm", spheres=spheres),
                "Hand_R": PlanningContext(model, [box], joints="TorsoRightArm", spheres=spheres)}
    mirrored = target.copy()
    mirrored[0, 3] *= -1.0
    mirrored[:3, :3] = left.tool_pose(q0)[:3, :3]
    samplers = {"Hand_R": grasp_sampler(contexts["Hand_R"], right, target[None], q0),
                "Hand_L": grasp_sampler(contexts["Hand_L"], left, mirrored[None], q0)}
    result = multi_eef_rrt(contexts, q0, samplers, IKRRTSettings(time_budget_s=10.0), rng=0)
    assert result.success and result.end_effector == "Hand_L"
    assert_valid_path(contexts["Hand_L"], result.path, q0)


def test_jacobian_steps_hold_a_joint_at_its_limit_and_move_the_others_instead():
    """The clamping loop: clipping the pseudoinverse step leaves the error undone; holding the
    joint at its limit and solving again with the other six reaches the twist."""
    from prehensile.planning.jplus_rrt import _limited_step

    rng = np.random.default_rng(0)
    jac, err, q = rng.normal(size=(6, 7)), 0.01 * rng.normal(size=6), np.zeros(7)
    lower, upper = np.full(7, -10.0), np.full(7, 10.0)
    free = np.linalg.pinv(jac) @ err
    k = int(np.argmax(np.abs(free)))
    (lower if free[k] < 0 else upper)[k] = 0.0  # joint k sits at the limit it wants to cross
    dq = _limited_step(jac, err, q, lower, upper, 0.0)
    assert dq[k] == 0.0 and np.all((lower <= q + dq) & (q + dq <= upper))
    np.testing.assert_allclose(jac @ dq, err, atol=1e-12)
    clipped = np.clip(free, lower - q, upper - q)
    assert np.linalg.norm(jac @ clipped - err) > 0.1 * np.linalg.norm(err)
    damped = _limited_step(jac, err, q, lower, upper, 0.01)
    assert damped[k] == 0.0 and np.linalg.norm(jac @ damped - err) < np.linalg.norm(jac @ clipped - err)
    with pytest.raises(PrehensileError, match="JPlusRRTSettings.damping must be >= 0 and finite"):
        JPlusRRTSettings(damping=-0.1)


def test_plan_to_pose_names_the_valid_planners_and_targets():
    from prehensile.planning import plan_to_pose

    panda = robots.load("panda")
    ctx = PlanningContext(panda, [], joints="arm")
    q = panda.neutral_configuration()
    for planner, target, message in [("rrt_connect", np.eye(4), "does not plan to a pose; valid: ik_rrt, jplus_rrt"),
                                     ("ik_rrt", np.zeros((2, 4)), r"must be a \(4, 4\) pose, a \(3,\) position or"),
                                     ("ik_rrt", np.zeros((0, 4, 4)), r"a non-empty set of them, \(k, 4, 4\)"),
                                     ("jplus_rrt", np.zeros(3), "jplus_rrt steps toward a full pose")]:
        with pytest.raises(PrehensileError, match=message):
            plan_to_pose(ctx, q, target, "arm", planner)
    region = PoseGoal("panda_hand_tcp", ((Sphere(0.1), make_pose(position=[0.4, 0.0, 0.4])),))
    with pytest.raises(PrehensileError, match="a region is the goal: give target=None and T_tip_tcp=None with it"):
        plan_to_pose(ctx, q, np.eye(4), "arm", "ik_rrt", region=(region, np.eye(4)))
    with pytest.raises(PrehensileError, match="goal of link 'panda_hand_tcp' has no orientation constraint; use ik_rrt"):
        plan_to_pose(ctx, q, None, "arm", "jplus_rrt", region=(region, np.eye(4)))
    elbow = PoseGoal("panda_link4", region.regions)
    with pytest.raises(PrehensileError, match="the goal's link 'panda_link4' moves relative to the tip"):
        plan_to_pose(ctx, q, None, "arm", "ik_rrt", region=(elbow, np.eye(4)))


@pytest.mark.parametrize("planner", ["ik_rrt", "jplus_rrt"])
def test_plan_to_pose_ends_in_a_goal_region(panda_scene, planner):
    """Both pose planners plan into a MoveIt-style goal region (a box beyond the wall, 2.4 m
    long with its centre out of reach, the orientation within 0.2 rad per XYZ Euler angle, the
    constrained point 5 cm ahead of the tool): the path is valid and ends inside the region,
    far from its centre; a region that holds the start is reached where the path begins,
    without moving."""
    from prehensile.kinematics import link_pose
    from prehensile.planning import plan_to_pose

    ctx, solver, q0, goals = panda_scene
    tip, offset = solver.chain.tip_link, np.array([0.0, 0.0, 0.05])
    centre = (goals[0] @ [*offset, 1.0])[:3] + [1.18, 0.0, 0.0]  # 1.1 m from the shoulder
    region = PoseGoal(tip, ((Box((2.4, 0.04, 0.04)), make_pose(position=centre)),), offset=offset,
                      orientation=goals[0][:3, :3], tolerances=np.full(3, 0.2))
    result = plan_to_pose(ctx, q0, None, "arm", planner, 5.0, 3, region=(region, np.eye(4)))
    assert result.success, result.info
    assert_valid_path(ctx, result.path, q0)
    T_end = link_pose(ctx.model, result.path[-1], tip)
    assert region.satisfied(np.eye(4), T_end) and np.linalg.norm((T_end @ [*offset, 1.0])[:3] - centre) > 0.3
    T_start = link_pose(ctx.model, q0, tip)
    around_start = PoseGoal(tip, ((Sphere(0.05), make_pose(position=(T_start @ [*offset, 1.0])[:3])),),
                            offset=offset, orientation=T_start[:3, :3], tolerances=np.full(3, 0.2))
    result = plan_to_pose(ctx, q0, None, "arm", planner, 5.0, 3, region=(around_start, np.eye(4)))
    assert result.success and np.all(result.path == q0)
