"""Hand-over (regrasp) planning on ARMAR-III, 17 DoF: Regrasp-IK-RRT and Regrasp-/bimanual
J+-RRT. Every path starts where asked, ends with both TCPs at the grasps of one object pose,
respects the limits and passes the exact check; statuses; determinism."""

from __future__ import annotations

import numpy as np
import pytest

from prehensile import robots
from prehensile.collision import Obstacle
from prehensile.collision.spheres import generate_sphere_model
from prehensile.errors import PrehensileError
from prehensile.ik import ChainSolver, ObjectRegion
from prehensile.model.geometry import Box, Cylinder
from prehensile.planning import (
    AttachedObject, IKRRTSettings, JPlusRRTSettings, PlanningContext, PlanStatus, certify_path, ik_rrt,
    regrasp_jplus_rrt, regrasp_sampler,
)
from prehensile.ik.reach import reach_samples
from prehensile.planning.ik_rrt import self_free_reach, separate_grasp_pairs
from prehensile.spatial import invert, make_pose, matrix_to_rpy, rotation_error

CUP = Cylinder(0.04, 0.2)
IK_RRT = IKRRTSettings(time_budget_s=10.0)  # rounds in attempts and iterations: the same on any machine
JPLUS = JPlusRRTSettings(time_budget_s=10.0)


def side_grasps(headings_deg) -> np.ndarray:
    """Grasps T_cup_tcp (k, 4, 4): TCP z (approach) horizontal toward the cup axis from the
    given headings (0: along +y, 90: along +x), 11 cm out."""
    out = []
    for a in np.radians(headings_deg):
        z, x = np.array([np.sin(a), np.cos(a), 0.0]), np.array([0.0, 0.0, -1.0])
        out.append(make_pose(np.column_stack([x, np.cross(z, x), z]), -0.11 * z))
    return np.array(out)


@pytest.fixture(scope="module")
def scene():
    """The cup held in the right hand (reaching forward) and three left-hand grasps from the left."""
    model = robots.load("armar3")
    spheres = generate_sphere_model(model, max_radius=0.04)
    right_grasp = side_grasps([0.0])
    hand = tuple(n for n in model.link_names if n.endswith(("_L", "_L_J0", "_L_J1", "_R_J0", "_R_J1"))
                 and any(k in n for k in ("Hand", "Thumb", "Index", "Middle", "Ring", "Pinky", "TCP", "GCP")))
    cup = AttachedObject("cup", "TCP_R", CUP, invert(right_grasp[0]), touch_links=hand)
    table = Obstacle("table", Box((1.2, 0.6, 0.05)), make_pose(position=[0.0, 0.8, 0.775]))
    ctx = PlanningContext(model, [table], joints="TorsoBothArms", spheres=spheres, attached=[cup])
    arms = [ChainSolver(model, "LeftArm"), ChainSolver(model, "RightArm")]
    q0, grasps = model.neutral_configuration(), [side_grasps([100.0, 120.0, 140.0]), right_grasp]
    # one plan of each kind compiles the kernels before the searches whose budgets matter
    ik_rrt(ctx, q0, regrasp_sampler(ctx, arms, grasps, None, q0, free="Torso"), IKRRTSettings(60.0), rng=0)
    regrasp_jplus_rrt(ctx, q0, arms, grasps, free="Torso", settings=JPlusRRTSettings(60.0), rng=0)
    return ctx, arms, grasps, q0


def assert_hand_over(ctx, arms, grasps, path, q_start, info, position_tolerance, rotation_tolerance):
    """The path starts at q_start, stays in the limits, passes the exact check and ends with
    both TCPs at their grasps of ``info["T_world_object"]``."""
    assert np.array_equal(path[0], q_start)
    assert np.all(ctx.model.within_limits(path))
    assert certify_path(ctx, path).ok
    T_object, (i, j) = info["T_world_object"], info["grasps"]
    for arm, grasp in zip(arms, (grasps[0][i], grasps[1][j])):
        tool, target = arm.tool_pose(path[-1]), T_object @ grasp
        assert np.linalg.norm(tool[:3, 3] - target[:3, 3]) <= position_tolerance
        assert np.linalg.norm(rotation_error(target[:3, :3], tool[:3, :3])) <= rotation_tolerance


def test_regrasp_ik_rrt_free_object(scene):
    ctx, arms, grasps, q0 = scene
    sampler = regrasp_sampler(ctx, arms, grasps, None, q0, free="Torso")
    result = ik_rrt(ctx, q0, sampler, IK_RRT, rng=3)
    assert result.success and result.stats.ik_solutions >= 1
    s = arms[0].settings
    assert_hand_over(ctx, arms, grasps, result.path, q0, result.info["goal"], s.position_tolerance,
                     s.rotation_tolerance)
    i, j = result.info["goal"]["grasps"]
    assert result.goal_index == i * len(grasps[1]) + j  # the pair as one index, as in J+-RRT
    again = ik_rrt(ctx, q0, sampler, IK_RRT, rng=3)
    assert np.array_equal(again.path, result.path)


def test_regrasp_ik_rrt_keeps_the_object_in_its_region(scene):
    ctx, arms, grasps, q0 = scene
    region = ObjectRegion((0.0, 0.4, 1.0), (0.25, 0.6, 1.2), (-0.2, -0.2, -0.6), (0.2, 0.2, 0.6))
    result = ik_rrt(ctx, q0, regrasp_sampler(ctx, arms, grasps, region, q0, free="Torso"), IK_RRT, rng=1)
    assert result.success
    goal = result.info["goal"]
    s = arms[0].settings
    assert_hand_over(ctx, arms, grasps, result.path, q0, goal, s.position_tolerance, s.rotation_tolerance)
    T = goal["T_world_object"]
    lower, upper = region.bounds()
    inside = np.concatenate([T[:3, 3], matrix_to_rpy(T[:3, :3])])
    assert np.all(inside >= lower - 1e-9) and np.all(inside <= upper + 1e-9)


def test_regrasp_jplus_rrt_free_object(scene):
    ctx, arms, grasps, q0 = scene
    result = regrasp_jplus_rrt(ctx, q0, arms, grasps, free="Torso", settings=JPLUS, rng=2)
    assert result.success and result.stats.ik_solutions == 0
    assert_hand_over(ctx, arms, grasps, result.path, q0, result.info, JPLUS.position_tolerance,
                     JPLUS.rotation_tolerance)
    i, j = result.info["grasps"]
    assert result.goal_index == i * len(grasps[1]) + j
    again = regrasp_jplus_rrt(ctx, q0, arms, grasps, free="Torso", settings=JPLUS, rng=2)
    assert np.array_equal(again.path, result.path)


def test_bimanual_jplus_rrt_picks_a_reachable_object_pose(scene):
    ctx, arms, grasps, q0 = scene
    handed = regrasp_jplus_rrt(ctx, q0, arms, grasps, free="Torso", settings=JPLUS, rng=5)
    assert handed.success
    far = make_pose(position=[0.0, 2.0, 1.0])  # out of reach: the planner must take the other pose
    objects = np.array([far, handed.info["T_world_object"]])
    result = regrasp_jplus_rrt(ctx, q0, arms, grasps, objects, free="Torso", settings=JPLUS, rng=0)
    assert result.success and result.info["object_index"] == 1
    assert np.array_equal(result.info["T_world_object"], objects[1])
    assert_hand_over(ctx, arms, grasps, result.path, q0, result.info, JPLUS.position_tolerance,
                     JPLUS.rotation_tolerance)


def test_separate_grasp_pairs_drops_overlapping_hands(scene):
    ctx, arms, grasps, _ = scene
    both_front = [side_grasps([0.0, 120.0]), grasps[1]]  # the left hand where the right one is, or beside
    assert separate_grasp_pairs(ctx, arms, both_front).tolist() == [[1, 0]]


def test_reach_samples_are_free_of_the_body_at_the_samplers_q_ref():
    """NAO's neutral configuration puts its arms' balls into the torso. Built on a context at
    that configuration, the hand-over sampler takes each arm's reachability samples at its own
    valid q_ref; where the other arm is does not matter (it moves to the goal too), the body does."""
    nao = robots.load("nao")
    arms = [ChainSolver(nao, "left_arm_wrist"), ChainSolver(nao, "right_arm_wrist")]
    ctx = PlanningContext(nao, [], joints=[j for arm in arms for j in arm.chain.joint_names])
    assert not ctx.is_valid(ctx.space.q_ref)
    rng = np.random.default_rng(0)
    q_ref = next(q for q in nao.random_configurations(rng, 100) if ctx.is_valid(q))
    left = self_free_reach(ctx, arms[0], q_ref)
    assert 0 < len(left.values) < len(reach_samples(arms[0]).values)
    elsewhere = q_ref.copy()
    elsewhere[arms[1].var_q] = nao.random_configurations(rng, 1)[0, arms[1].var_q]
    assert np.array_equal(self_free_reach(ctx, arms[0], elsewhere).values, left.values)
    sampler = regrasp_sampler(ctx, arms, [np.eye(4)[None], np.eye(4)[None]], None, q_ref)
    assert np.array_equal(sampler.q_ref, q_ref)


def test_infeasible_hand_overs_are_statuses_within_budget(scene):
    ctx, arms, grasps, q0 = scene
    clash = [grasps[1], grasps[1]]  # both hands on the same pose: no pair is worth an IK attempt
    assert len(separate_grasp_pairs(ctx, arms, clash)) == 0
    result = ik_rrt(ctx, q0, regrasp_sampler(ctx, arms, clash, None, q0, free="Torso"),
                    IKRRTSettings(time_budget_s=0.2), rng=0)
    assert result.status is PlanStatus.NO_GOAL_CONFIGURATION and result.stats.plan_time_s < 0.4
    far = make_pose(position=[0.0, 2.0, 1.0])[None]
    result = regrasp_jplus_rrt(ctx, q0, arms, grasps, far, settings=JPlusRRTSettings(time_budget_s=0.2), rng=0)
    assert result.status is PlanStatus.TIMEOUT and result.stats.plan_time_s < 0.4 and len(result.path) == 0
    colliding = q0.copy()
    colliding[ctx.model.joint_index("Hip_Pitch")] = ctx.model.upper[ctx.model.joint_index("Hip_Pitch")]
    colliding[arms[1].var_q] = arms[1].upper  # the right arm folded into the torso
    assert not ctx.is_valid(colliding)
    assert regrasp_jplus_rrt(ctx, colliding, arms, grasps, rng=0).status is PlanStatus.INVALID_START
    unplanned = PlanningContext(ctx.model, [], joints="TorsoLeftArm")
    with pytest.raises(PrehensileError, match="does not plan"):
        regrasp_jplus_rrt(unplanned, q0, arms, grasps, rng=0)
