"""Exact path certification with per-pair free bubbles (prehensile.planning.certify)."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from prehensile.collision.spheres import generate_sphere_model
from prehensile.collision.world import Obstacle
from prehensile.errors import PrehensileError
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.model.geometry import Box, Capsule, Geometry, Mesh, Sphere
from prehensile.kinematics import forward_kinematics
from prehensile.planning import AttachedObject, PlanningContext, certify_path
from prehensile.planning.certify import ExactCertifier, _cover_distance
from prehensile.spatial import make_pose

ALONG_X = np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]])


@pytest.fixture(scope="module")
def arm():
    """Two capsule links (0.5 m, 0.4 m along x) on a base box, joints about z at 0.1 m height."""
    def capsule(length):
        return Geometry(Capsule(0.04, length - 0.08), make_pose(ALONG_X, [length / 2, 0, 0]))

    links = [LinkSpec("base", collisions=[Geometry(Box((0.16, 0.16, 0.1)))]),
             LinkSpec("l1", collisions=[capsule(0.5)]), LinkSpec("l2", collisions=[capsule(0.4)])]
    z = [0.0, 0, 1]
    joints = [JointSpec("j1", "revolute", "base", "l1", make_pose(position=[0, 0, 0.1]), z, -3.0, 3.0),
              JointSpec("j2", "revolute", "l1", "l2", make_pose(position=[0.5, 0, 0]), z, -2.9, 2.9)]
    model = build_model("arm2", "test", links, joints)
    return model, generate_sphere_model(model, cache=False)


def _dense_exact_free(ctx, path, step=0.0005):
    """Every segment sampled every ``step`` m (weighted metric) is free for coal."""
    return all(ctx.exact.is_free(ctx.space.interpolate(a, b, step)).all() for a, b in zip(path[:-1], path[1:]))


def test_path_through_an_obstacle_fails_at_the_right_segment(arm):
    model, spheres = arm
    box = Obstacle("box", Box((0.1, 0.1, 0.3)), make_pose(position=[0.0, 0.7, 0.1]))
    ctx = PlanningContext(model, [box], spheres=spheres)
    path = np.array([[-0.5, 0.0], [0.0, 0.0], [2.5, 0.0]])  # the second segment sweeps l2 through the box
    assert ctx.is_valid(path).all()
    report = certify_path(ctx, path)
    assert not report.ok and report.first_bad_segment == 1 and report.min_distance < 0
    ok = certify_path(ctx, path[:2])
    assert ok.ok and ok.first_bad_segment == -1 and ok.min_distance > 0


def test_free_path_needs_far_fewer_configurations_than_sampling(arm):
    model, spheres = arm
    box = Obstacle("box", Box((0.1, 0.1, 0.3)), make_pose(position=[0.0, 0.7, 0.1]))
    ctx = PlanningContext(model, [box], spheres=spheres)
    path = np.array([[-0.5, 0.0], [0.0, 2.0], [1.0, -1.0]])
    report = certify_path(ctx, path)
    assert report.ok and report.time_s > 0
    samples = sum(len(ctx.space.interpolate(a, b, ctx.certify_resolution)) for a, b in zip(path[:-1], path[1:]))
    assert report.configurations_checked < samples / 10


def test_waypoint_outside_limits_fails(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [], spheres=spheres)
    report = certify_path(ctx, np.array([[0.0, 0.0], [0.5, 0.5], [0.5, 2.95]]))
    assert not report.ok and report.first_bad_segment == 1


def test_bad_paths_and_resolutions_are_errors(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [], spheres=spheres)
    path = np.array([[0.0, 0.0], [0.5, 0.5]])
    with pytest.raises(PrehensileError, match=r"shape \(N >= 1, 2\)"):
        certify_path(ctx, np.zeros((0, 2)))
    # inf would prove a segment from its ends alone; 1e-9 m would size the bisection queue in terabytes
    for resolution in (0.0, -1.0, np.inf, np.nan, 1e-9, "fine"):
        with pytest.raises(PrehensileError, match=r"certify_path: resolution: must be a finite length >= 1e-05 m"):
            certify_path(ctx, path, resolution)
        with pytest.raises(PrehensileError, match=r"check_motion: resolution: must be a finite length >= 1e-05 m"):
            ctx.check_motion(path[0], path[1], resolution)
        with pytest.raises(PrehensileError, match=r"check_motion: resolution: must be a finite"):
            ctx.check_motions(path[:1], path[1:], resolution)
        for name in ("resolution", "certify_resolution"):
            with pytest.raises(PrehensileError, match=f"PlanningContext: {name}: must be a finite length"):
                PlanningContext(model, [], spheres=spheres, **{name: resolution})
    assert certify_path(ctx, path[:1]).ok


def test_self_collision_is_caught(arm):
    model, spheres = arm
    ctx = PlanningContext(model, [], spheres=spheres, acm=np.eye(model.n_links, dtype=bool))  # base-l2 checked
    folded = np.array([[0.0, 0.0], [0.0, 2.9]])  # l2 folds back over the base
    assert not ctx.exact.is_free(folded[1])
    assert not certify_path(ctx, folded).ok


def test_agrees_with_dense_sampling_near_a_concave_mesh(arm):
    """A U-shaped mesh: its hull overlaps l2 inside the U, where only the exact mesh decides."""
    model, spheres = arm
    walls = (((0.3, 0.04, 0.3), [0.0, 0.13, 0.0]), ((0.3, 0.04, 0.3), [0.0, -0.13, 0.0]),
             ((0.04, 0.3, 0.3), [0.13, 0.0, 0.0]))
    parts = [trimesh.creation.box(size, trimesh.transformations.translation_matrix(t)) for size, t in walls]
    u = trimesh.util.concatenate(parts)
    mesh = Obstacle("u", Mesh.from_arrays(u.vertices, u.faces), make_pose(position=[0.8, 0.0, 0.1]))
    ctx = PlanningContext(model, [mesh], spheres=spheres)
    rng = np.random.default_rng(0)
    outcomes = set()
    for _ in range(12):
        path = np.array([[0.0, 0.0], rng.uniform([-0.3, -0.6], [0.3, 0.6])])
        if not ctx.exact.is_free(path).all():
            continue
        report = certify_path(ctx, path)
        dense = _dense_exact_free(ctx, path)
        assert report.ok == dense, path
        outcomes.add(report.ok)
    assert outcomes == {True, False}
    # the certifier uses the exact checker's coal geometry of the world: the mesh's BVH is built once
    assert ctx.certifier._obstacles[0].exact is ctx.exact.obstacle_parts[0].exact
    with pytest.raises(PrehensileError, match="ExactCertifier: 1 obstacle parts for 2 obstacles"):
        ExactCertifier(model, [mesh, mesh], np.eye(4), ctx.acm, parts=ctx.exact.obstacle_parts)


def test_attached_object_is_certified(arm):
    model, spheres = arm
    box = Obstacle("box", Box((0.1, 0.1, 0.3)), make_pose(position=[1.05, 0.325, 0.1]))  # 1.1 m out at 0.3 rad
    path = np.array([[-0.5, 0.0], [0.5, 0.0]])  # l2 stays clear of the box, a rod held beyond it does not
    assert certify_path(PlanningContext(model, [box], spheres=spheres), path).ok
    rod = AttachedObject("rod", "l2", Box((0.4, 0.03, 0.03)), make_pose(position=[0.5, 0.0, 0.0]))
    ctx = PlanningContext(model, [box], spheres=spheres, attached=[rod])
    assert not certify_path(ctx, path).ok


def _u_and_box_world() -> list[Obstacle]:
    u = trimesh.util.concatenate([trimesh.creation.box((0.3, 0.04, 0.3), trimesh.transformations.translation_matrix(
        [0.0, y, 0.0])) for y in (0.13, -0.13)])
    return [Obstacle("u", Mesh.from_arrays(u.vertices, u.faces), make_pose(position=[0.8, 0.0, 0.1])),
            Obstacle("box", Box((0.1, 0.1, 0.3)), make_pose(position=[0.0, 0.7, 0.1]))]


def test_covering_ball_distances_are_lower_bounds(arm):
    """The certifier's bound from covering balls never exceeds coal's exact distance, and is close."""
    model, spheres = arm
    world = _u_and_box_world()
    ctx = PlanningContext(model, world, spheres=spheres)
    cover = ctx.certifier._cover
    rng = np.random.default_rng(2)
    gaps = []
    for q in rng.uniform(model.lower, model.upper, size=(40, model.dof)):
        poses = forward_kinematics(model, q)
        for pair in (p for p in ctx.exact.closest_points(q) if p.distance > 0):  # bounds, not depths
            link, o = model.link_index(pair.link), [w.name for w in world].index(pair.other)
            bound = _cover_distance(poses, link, -1, o, *cover)
            assert bound <= pair.distance + 1e-9
            gaps.append(pair.distance - bound)
    assert np.median(gaps) < 0.05  # balls around 4 cm capsules, mesh obstacle covered by 32 balls


def test_covering_balls_keep_every_verdict(arm):
    """Certification with covering-ball bounds agrees with the coal-only certification."""
    model, spheres = arm
    world = _u_and_box_world()
    covered = PlanningContext(model, world, spheres=spheres)
    assert covered.cover_model is not None
    coal_only = ExactCertifier(covered.collision_model, world, covered.T_world_base, covered.acm, None,
                               covered.exact.obstacle_parts)
    rng = np.random.default_rng(1)
    outcomes = set()
    for _ in range(24):
        path = np.vstack([[-1.5, 0.0], rng.uniform([-3.0, -2.5], [3.0, 2.5], size=(2, 2))])
        if not covered.exact.is_free(path).all():
            continue
        fast, slow = certify_path(covered, path), coal_only.certify(path, covered.certify_resolution)
        assert fast.ok == slow.ok, path
        outcomes.add(fast.ok)
    assert outcomes == {True, False}


def test_an_invalid_input_path_names_the_links_that_collide():
    """NAO's left wrist sweeps through its torso between two free configurations."""
    from prehensile import robots
    from prehensile.planning.certify import check_valid_path

    model = robots.load("nao")
    ctx = PlanningContext(model, [], joints="left_arm")
    a, b = model.neutral_configuration(), model.neutral_configuration()
    a[ctx.space.indices] = [1.63, 0.52, -1.45, -1.2]
    b[ctx.space.indices] = [1.54, 0.26, 1.17, -1.46]
    assert ctx.exact.is_free(np.stack([a, b])).all()
    with pytest.raises(PrehensileError, match=r"edge 0 \(waypoint 0 to 1\) is not: links (torso and l_wrist|l_wrist "
                                              r"and torso) collide"):
        check_valid_path(ctx, np.stack([a, b]), "test")


def test_a_mesh_piece_wholly_inside_a_closed_mesh_collides_whichever_vertex_comes_first():
    """A link mesh of two closed cubes (a merged file), one in a closed crate and one outside;
    first in its vertex list an unused vertex, outside too. Each connected piece is tested for
    containment, so the exact checker and the certification both see the cube in the crate."""
    cube = trimesh.creation.box(extents=(0.04, 0.04, 0.04))
    inside, outside = cube.vertices + [0.3, 0.0, 0.0], cube.vertices + [0.6, 0.0, 0.0]
    vertices = np.concatenate([[[0.6, 0.5, 0.0]], outside, inside])
    faces = np.concatenate([cube.faces + 1, cube.faces + 9])
    joint = [JointSpec("j1", "revolute", "base", "hand", np.eye(4), [1.0, 0, 0], -3.0, 3.0)]  # turns about x
    model = build_model("hand", "test", [LinkSpec("base"), LinkSpec("hand", collisions=[Geometry(
        Mesh.from_arrays(vertices, faces))])], joint)
    crate = trimesh.creation.box(extents=(0.2, 1.2, 1.2))
    world = [Obstacle("crate", Mesh.from_arrays(crate.vertices, crate.faces), make_pose(position=[0.3, 0.0, 0.0]))]
    ctx = PlanningContext(model, world, spheres=generate_sphere_model(model, cache=False))
    path = np.array([[-1.0], [1.0]])
    assert not ctx.exact.is_free(path[0]) and ctx.exact.collisions(path[0])[0][:2] == ("hand", "crate")
    report = certify_path(ctx, path)
    assert not report.ok and report.colliding_links == ("hand",)


def test_a_path_starting_wholly_inside_a_closed_mesh_fails():
    """A pebble inside a link's closed box mesh never meets its surface while the link turns
    about it, nor does a pebble link inside a closed mesh obstacle: only the containment test
    at the path's start shows the collision."""
    box = trimesh.creation.box(extents=(0.4, 0.4, 0.4))
    joint = [JointSpec("j1", "revolute", "base", "cage", np.eye(4), [0, 0, 1.0], -3.0, 3.0)]
    cage = build_model("cage", "test", [LinkSpec("base"), LinkSpec("cage", collisions=[Geometry(
        Mesh.from_arrays(box.vertices, box.faces))])], joint)
    pebble_arm = build_model("cage", "test", [LinkSpec("base"), LinkSpec("cage", collisions=[Geometry(
        Sphere(0.01), make_pose(position=[0.1, 0.0, 0.0]))])], joint)
    path = np.array([[-1.0], [1.0]])
    cases = [(cage, Obstacle("pebble", Sphere(0.01), make_pose(position=position)), inside)
             for position, inside in (([0.0, 0.0, 0.0], True), ([0.15, 0.05, 0.0], True), ([0.5, 0.0, 0.0], False))]
    cases += [(pebble_arm, Obstacle("box", Mesh.from_arrays(box.vertices, box.faces), make_pose(position=at)), inside)
              for at, inside in (([0.0, 0.0, 0.0], True), ([0.0, 0.0, 0.5], False))]
    for model, obstacle, inside in cases:
        ctx = PlanningContext(model, [obstacle], spheres=generate_sphere_model(model, cache=False))
        report = certify_path(ctx, path)
        assert report.ok == (not inside) == bool(ctx.exact.is_free(path[0])), (model.name, obstacle)
        if inside:
            assert report.first_bad_segment == 0 and report.colliding_links == ("cage",)
            assert not ctx.exact.is_free(ctx.space.interpolate(path[0], path[1], 0.01)).any()
