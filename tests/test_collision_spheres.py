"""Sphere models: generated and padded balls cover the collision geometry; disk cache; the
sphere checker's clearance is the exact ball-to-obstacle distance."""

from __future__ import annotations

import logging

import numpy as np
import pytest

from conftest import SHARED, WEDGE, part_urdf
from prehensile.collision import spheres as spheres_module
from prehensile.collision.acm import rigid_bodies
from prehensile.collision.exact import ExactChecker
from prehensile.collision.sphere_checker import SphereChecker
from prehensile.collision.sphere_fit import cover_geometries, geometry_triangles, primitive_overshoot
from prehensile.collision.world import Obstacle
from prehensile.errors import ModelError, PrehensileError
from prehensile.collision.spheres import (
    SphereModel, generate_sphere_model, pad_sphere_model, spheres_from_urdf,
)
from prehensile.model import load_urdf
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.kinematics import forward_kinematics
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.robots import load_path
from prehensile.spatial import make_pose, rpy_to_matrix

MBM = SHARED / "bench" / "mbm" / "panda"
needs_mbm = pytest.mark.skipif(not (MBM / "panda.urdf").is_file(), reason="MBM Panda files not found")


def _primitive_robot():
    tilt = make_pose(rpy_to_matrix([0.3, -0.4, 0.2]), [0.05, -0.02, 0.1])
    links = [
        LinkSpec("base", collisions=[Geometry(Box((0.4, 0.3, 0.05)), make_pose(position=[0, 0, 0.025]))]),
        LinkSpec("column", collisions=[Geometry(Cylinder(0.06, 0.5), make_pose(position=[0, 0, 0.25])),
                                       Geometry(Sphere(0.08), make_pose(position=[0, 0, 0.5]))]),
        LinkSpec("arm", collisions=[Geometry(Capsule(0.04, 0.3), tilt)]),
        LinkSpec("plate", collisions=[Geometry(Box((0.02, 0.2, 0.1)), tilt)]),
        LinkSpec("marker"),
    ]
    joints = [
        JointSpec("j1", "revolute", "base", "column", make_pose(position=[0, 0, 0.05]), np.array([0.0, 0, 1]), -3, 3),
        JointSpec("j2", "revolute", "column", "arm", make_pose(position=[0, 0, 0.5]), np.array([0.0, 1, 0]), -2, 2),
        JointSpec("j3", "fixed", "arm", "plate", make_pose(position=[0.2, 0, 0])),
        JointSpec("j4", "fixed", "plate", "marker", np.eye(4)),
    ]
    return build_model("prims", "test", links, joints)


def _surface_points(geometry: Geometry, rng: np.random.Generator, n: int = 400) -> np.ndarray:
    """Points on the true surface of a primitive (not a tessellation), in the link frame."""
    shape = geometry.shape
    if isinstance(shape, Box):
        half = np.asarray(shape.size) / 2
        p = rng.uniform(-half, half, (n, 3))
        axis = rng.integers(0, 3, n)
        p[np.arange(n), axis] = np.where(rng.random(n) < 0.5, -1, 1) * half[axis]
    elif isinstance(shape, Sphere):
        d = rng.normal(size=(n, 3))
        p = shape.radius * d / np.linalg.norm(d, axis=1, keepdims=True)
    else:
        a = rng.uniform(0, 2 * np.pi, n)
        z = rng.uniform(-shape.length / 2, shape.length / 2, n)
        p = np.column_stack([shape.radius * np.cos(a), shape.radius * np.sin(a), z])
        if isinstance(shape, Capsule):
            d = rng.normal(size=(n, 3))
            cap = shape.radius * d / np.linalg.norm(d, axis=1, keepdims=True)
            cap[:, 2] += np.sign(cap[:, 2]) * shape.length / 2
            p = np.vstack([p, cap])
        else:
            r = shape.radius * np.sqrt(rng.random(n))
            disc = np.column_stack([r * np.cos(a), r * np.sin(a), np.where(rng.random(n) < 0.5, -1, 1) * shape.length / 2])
            p = np.vstack([p, disc])
    T = np.asarray(geometry.T_link_geom)
    return p @ T[:3, :3].T + T[:3, 3]


def _triangle_samples(triangles: np.ndarray, rng: np.random.Generator, per: int = 12) -> np.ndarray:
    u, v = rng.random((2, len(triangles), per))
    flip = u + v > 1
    u, v = np.where(flip, 1 - u, u), np.where(flip, 1 - v, v)
    a, b, c = triangles[:, 0, None], triangles[:, 1, None], triangles[:, 2, None]
    return (a + u[..., None] * (b - a) + v[..., None] * (c - a)).reshape(-1, 3)


def _uncovered(points: np.ndarray, centers: np.ndarray, radii: np.ndarray, tol: float = 1e-9) -> int:
    if len(points) == 0:
        return 0
    d = np.linalg.norm(points[:, None, :] - centers[None], axis=-1) - radii[None]
    return int(np.sum(d.min(axis=1) > tol))


def assert_covers(model, spheres: SphereModel, rng) -> None:
    """Every vertex, sampled triangle point and (for primitives) true surface point of every
    link lies in one of that link's balls."""
    for i, geometries in enumerate(model.collisions):
        centers, radii = spheres.link_spheres(i)
        for geometry in geometries:
            triangles = geometry_triangles(geometry)
            points = [triangles.reshape(-1, 3), _triangle_samples(triangles, rng)]
            if not isinstance(geometry.shape, Mesh):
                points.append(_surface_points(geometry, rng))
            missing = _uncovered(np.concatenate(points), centers, radii)
            assert missing == 0, f"link {model.link_names[i]}: {missing} points outside its balls"


@pytest.fixture(scope="module")
def panda():
    return load_urdf(MBM / "panda.urdf", MBM / "panda.srdf")


def test_generated_spheres_cover_primitive_robot(tmp_path, monkeypatch):
    monkeypatch.setenv("PREHENSILE_CACHE", str(tmp_path))
    model = _primitive_robot()
    spheres = generate_sphere_model(model, n_spheres=6)
    assert spheres.link_spheres("marker")[1].size == 0
    assert all(spheres.link_spheres(n)[1].size > 0 for n in ("base", "column", "arm", "plate"))
    assert_covers(model, spheres, np.random.default_rng(0))


def test_max_radius_is_a_target_and_the_links_above_it_are_logged(caplog):
    caplog.set_level(logging.INFO, logger="prehensile.collision.spheres")
    model = _primitive_robot()
    spheres = generate_sphere_model(model, n_spheres=2, max_radius=0.07, cache=False)
    column = spheres.link_spheres("column")[1]
    assert spheres.link_spheres("base")[1].max() <= 0.07  # the box got more balls
    assert column.max() == pytest.approx(0.08)  # the ball primitive keeps its radius
    assert "WARNING" in caplog.text and "base" not in caplog.text
    assert "balls above the target radius 0.07 m on column 0.080 m" in caplog.text
    assert_covers(model, spheres, np.random.default_rng(0))


@pytest.mark.parametrize("scale", [(1.0, -1.0, 1.0), (-1.0, -1.0, -1.0)])
def test_generated_spheres_cover_a_mirrored_urdf_mesh(tmp_path, monkeypatch, scale):
    """The balls of a mesh mirrored by its URDF scale cover the mirror image, also when the
    unmirrored mesh's balls are in the cache."""
    monkeypatch.setenv("PREHENSILE_CACHE", str(tmp_path))
    for name in ("plain", "mirrored"):
        (tmp_path / name).mkdir()
    generate_sphere_model(load_path(part_urdf(tmp_path / "plain", f'<mesh filename="{WEDGE}"/>')))
    mesh = f'<mesh filename="{WEDGE}" scale="{" ".join(map(str, scale))}"/>'
    model = load_path(part_urdf(tmp_path / "mirrored", mesh))
    spheres = generate_sphere_model(model)
    assert _uncovered(Mesh(WEDGE).trimesh.vertices * scale, *spheres.link_spheres("part")) == 0
    assert_covers(model, spheres, np.random.default_rng(0))


def test_a_urdf_capsule_of_length_0_is_one_ball_to_both_checkers(tmp_path):
    model = load_path(part_urdf(tmp_path, '<capsule radius="0.05" length="0"/>'))
    spheres = generate_sphere_model(model, cache=False)
    centers, radii = spheres.link_spheres("part")
    assert np.allclose(centers, 0.0) and radii.tolist() == [0.05]
    assert_covers(model, spheres, np.random.default_rng(0))
    q = np.zeros(1)
    for x, distance in ((0.1, 0.03), (0.06, -0.01)):  # a 0.02 m ball beside the capsule, or overlapping it
        obstacles = [Obstacle("ball", Sphere(0.02), make_pose(position=[x, 0.0, 0.0]))]
        exact = ExactChecker(model, obstacles)
        assert exact.min_distance(q) == pytest.approx(distance)
        assert exact.is_free(q) == SphereChecker(model, obstacles, spheres=spheres).is_free(q) == (distance > 0)


@needs_mbm
def test_generated_spheres_cover_mbm_panda(panda):
    spheres = generate_sphere_model(panda)
    assert 0 < spheres.n_spheres <= 8 * 11
    assert_covers(panda, spheres, np.random.default_rng(1))


@needs_mbm
def test_padded_mbm_spheres_cover_meshes_and_raw_ones_do_not(panda):
    raw = spheres_from_urdf(panda, MBM / "panda_spherized.urdf")
    assert raw.n_spheres == 59
    rng = np.random.default_rng(2)
    with pytest.raises(AssertionError):
        assert_covers(panda, raw, rng)
    padded = pad_sphere_model(raw, panda)
    assert padded.n_spheres >= raw.n_spheres
    assert np.all(padded.radii[: raw.n_spheres] >= 0)
    assert_covers(panda, padded, rng)
    assert padded.covering and pad_sphere_model(padded, panda) is padded  # nothing left to cover


def test_cache_round_trip(tmp_path, monkeypatch):
    monkeypatch.setenv("PREHENSILE_CACHE", str(tmp_path))
    model = _primitive_robot()
    first = generate_sphere_model(model, n_spheres=5)
    files = list((tmp_path / "spheres").glob("*.npz"))
    assert len(files) == 1 and not list((tmp_path / "spheres").glob("*.tmp"))

    def fail(*args, **kwargs):
        raise AssertionError("the second call must load from disk, not fit again")

    monkeypatch.setattr(spheres_module, "cover_geometries", fail)
    second = generate_sphere_model(model, n_spheres=5)
    for name in ("sphere_link", "centers", "radii"):
        assert np.array_equal(getattr(first, name), getattr(second, name))
    assert second.link_names == first.link_names
    with pytest.raises(AssertionError):  # other parameters: another key, so a new fit
        generate_sphere_model(model, n_spheres=4)


def _ball_to_obstacle(centers: np.ndarray, radii: np.ndarray, obstacle: Obstacle) -> np.ndarray:
    """(S,) distance (m) from balls (S, 3), (S,) to a primitive obstacle; negative inside."""
    T = np.asarray(obstacle.T_world_shape)
    local = (centers - T[:3, 3]) @ T[:3, :3]
    shape = obstacle.shape
    if isinstance(shape, Sphere):
        return np.linalg.norm(local, axis=1) - shape.radius - radii
    if isinstance(shape, Box):
        return np.linalg.norm(np.maximum(np.abs(local) - np.asarray(shape.size) / 2, 0.0), axis=1) - radii
    half = shape.length / 2
    if isinstance(shape, Cylinder):
        radial = np.maximum(np.linalg.norm(local[:, :2], axis=1) - shape.radius, 0.0)
        return np.hypot(radial, np.maximum(np.abs(local[:, 2]) - half, 0.0)) - radii
    axis_point = np.zeros_like(local)
    axis_point[:, 2] = np.clip(local[:, 2], -half, half)
    return np.linalg.norm(local - axis_point, axis=1) - shape.radius - radii


def test_world_clearance_is_the_exact_ball_distance():
    """The pruning hierarchy (bounding balls against obstacle boxes, chunks, balls) loses
    nothing: clearance against the world equals the brute-force minimum over every moving
    ball and every obstacle, for rotated boxes, cylinders, capsules and spheres."""
    model = _primitive_robot()
    tilt = make_pose(rpy_to_matrix([0.5, 0.3, -0.7]), [0.35, 0.2, 0.55])
    obstacles = [
        Obstacle("box", Box((0.3, 0.1, 0.2)), tilt),
        Obstacle("cyl", Cylinder(0.05, 0.4), make_pose(rpy_to_matrix([1.2, 0.0, 0.4]), [-0.3, 0.3, 0.6])),
        Obstacle("cap", Capsule(0.04, 0.3), make_pose(rpy_to_matrix([0.0, 0.9, 0.2]), [0.1, -0.4, 0.7])),
        Obstacle("ball", Sphere(0.07), make_pose(position=[-0.2, -0.3, 0.35])),
    ]
    checker = SphereChecker(model, obstacles)
    balls = checker.spheres
    moving = rigid_bodies(model)[balls.sphere_link] != rigid_bodies(model)[0]  # the root body's balls never move
    q = model.random_configurations(np.random.default_rng(4), 400)
    poses = forward_kinematics(model, q)[:, balls.sphere_link[moving]]
    centers = np.einsum("nsij,sj->nsi", poses[..., :3, :3], balls.centers[moving]) + poses[..., :3, 3]
    each = np.array([[_ball_to_obstacle(c, balls.radii[moving], o).min() for o in obstacles] for c in centers])
    truth = each.min(axis=1)
    clearance = checker.clearance(q, self_pairs=False)
    free = truth >= 0.0
    assert 20 < free.sum() < len(q) - 20  # free and colliding configurations
    assert set(np.argmin(each[free], axis=1)) == set(range(len(obstacles)))  # every shape is nearest somewhere
    assert np.allclose(clearance[free], truth[free], atol=1e-9)
    assert np.all(clearance[~free] < 0.0)
    capped = checker.clearance(q[free], cap=0.05, self_pairs=False)
    assert np.allclose(capped, np.minimum(truth[free], 0.05), atol=1e-9)

    # screen: the three verdicts of one call agree with within_limits, is_free and the world clearance
    margin, outside = 0.05, q.copy()
    outside[::3, 0] = model.upper[0] + 1e-6
    inside, screened_free, near = checker.screen(outside.reshape(20, 20, -1), margin)
    assert inside.shape == screened_free.shape == near.shape == (20, 20)
    assert np.array_equal(inside.ravel(), model.within_limits(outside)) and not inside.all()
    screened_free, near = checker.screen(q, margin)[1:]
    assert np.array_equal(screened_free, checker.is_free(q))
    single = checker.single_test()  # the callback test of one configuration: the same verdicts
    assert [single(row) for row in q] == checker.is_free(q).tolist()
    assert np.array_equal(near, clearance < margin)
    assert 20 < (near.ravel() & free).sum() < free.sum() - 20  # near and far free configurations


@pytest.mark.parametrize("shape", ["plane", "box", "torus"])
def test_mesh_obstacles_are_covered_by_tight_oriented_boxes(shape):
    """Every triangle lies in a box; a plane and a box-shaped mesh are covered exactly (a few
    large triangles used to give one ball as large as the whole mesh)."""
    import trimesh

    from prehensile.collision.sphere_fit import box_cover

    mesh = {"plane": trimesh.Trimesh([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]]),
            "box": trimesh.creation.box(extents=(1.2, 0.8, 0.05)),
            "torus": trimesh.creation.torus(0.3, 0.05)}[shape]
    triangles = geometry_triangles(Geometry(Mesh.from_arrays(mesh.vertices, mesh.faces)))
    poses, halves = box_cover(triangles, 32)
    assert len(poses) <= 32 and np.allclose(np.linalg.det(poses[:, :3, :3]), 1.0)
    local = np.einsum("kji,tvkj->tvki", poses[:, :3, :3], triangles[:, :, None] - poses[None, None, :, :3, 3])
    inside = np.all(np.abs(local) <= halves + 1e-9, axis=-1).all(axis=1)  # (T, K): all three vertices in box k
    assert inside.any(axis=1).all()
    if shape == "torus":  # the boxes hug the tube: the hole (radius 0.25 m) stays free within 0.2 m
        angle = np.linspace(0, 2 * np.pi, 50)
        hole = np.column_stack([0.2 * np.cos(angle), 0.2 * np.sin(angle), np.zeros(50)])
        local = np.einsum("kji,pkj->pki", poses[:, :3, :3], hole[:, None] - poses[None, :, :3, 3])
        assert not np.all(np.abs(local) <= halves, axis=-1).any()
    else:  # flat boxes in the faces' planes, within the mesh's bounds: its faces exactly
        corners = np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T
        world = np.einsum("kij,ckj->cki", poses[:, :3, :3], corners[:, None] * halves) + poses[:, :3, 3]
        assert np.all(np.min(halves, axis=1) < 1e-12)
        assert np.all((world >= mesh.bounds[0] - 1e-9) & (world <= mesh.bounds[1] + 1e-9))


def test_a_table_mesh_checks_like_the_box_it_is():
    import trimesh

    model = _primitive_robot()
    pose = make_pose(rpy_to_matrix([0.0, 0.0, 0.3]), [0.4, 0.1, 0.6])  # the column stands beside it
    table = trimesh.creation.box(extents=(0.6, 0.5, 0.04))
    as_mesh = SphereChecker(model, [Obstacle("table", Mesh.from_arrays(table.vertices, table.faces), pose)])
    as_box = SphereChecker(model, [Obstacle("table", Box((0.6, 0.5, 0.04)), pose)])
    q = model.random_configurations(np.random.default_rng(1), 500)
    free = as_box.is_free(q)
    assert 20 < free.sum() < len(q) - 20
    assert np.array_equal(as_mesh.is_free(q), free)


def test_checker_inputs_a_robot_without_joints_and_contacts_of_the_base():
    """A bad base pose is an error; a robot with no joints is checked like any other; the
    base's balls in an obstacle are reported as the base's world contact."""
    model = _primitive_robot()
    brick = Obstacle("brick", Box((0.1, 0.1, 0.1)), make_pose(position=[0.15, 0.1, 0.02]))  # in the base plate
    nan_base = make_pose(position=[0.0, 0.0, np.nan])
    with pytest.raises(PrehensileError, match="SphereChecker: T_world_base: contains NaN"):
        SphereChecker(model, [brick], T_world_base=nan_base)
    with pytest.raises(PrehensileError, match="SphereChecker: T_world_base: .*not a rotation"):
        SphereChecker(model, [brick], T_world_base=np.diag([10.0, 10.0, 10.0, 1.0]))
    with pytest.raises(PrehensileError, match=r"SphereChecker: acm must be \(5, 5\)"):
        SphereChecker(model, [brick], acm=np.zeros((4, 4), bool))
    balls = generate_sphere_model(model, cache=False)
    with pytest.raises(ModelError, match="non-finite radius"):
        SphereModel(balls.link_names, balls.sphere_link, balls.centers, np.full(balls.n_spheres, np.nan))
    checker = SphereChecker(model, [brick])
    assert checker.static_hit and ("base", "world") in checker.ball_contacts(np.zeros(2))
    assert not checker.single_test()(np.zeros(2)) and not checker.is_free(np.zeros(2))
    rigid = build_model("rigid", "test", [LinkSpec("base", collisions=[Geometry(Box((0.2, 0.2, 0.2)))])], [])
    for world, free in (([], True), ([brick], False)):
        checker = SphereChecker(rigid, world)
        assert checker.is_free(np.zeros(0)) == free and checker.is_free(np.zeros((3, 0))).tolist() == [free] * 3
        assert (checker.clearance(np.zeros(0)) > 0) == free


def test_ball_contacts_agree_with_the_compiled_test():
    """ball_contacts answers a configuration the compiled test finds free at once; every other
    one lists its contacts. Both agree with the balls measured here in numpy, on NAO beside a box."""
    from prehensile import robots

    nao = robots.load("nao")
    box = Obstacle("box", Box((0.06, 0.4, 0.1)), make_pose(position=[0.18, 0.0, 0.1]))  # in reach of both arms
    checker = SphereChecker(nao, [box])
    balls, moving = checker.spheres, checker.data[14]  # the links measured against the world
    q = nao.random_configurations(np.random.default_rng(0), 300)
    poses = forward_kinematics(nao, q)[:, balls.sphere_link]
    centers = np.einsum("bnij,nj->bni", poses[..., :3, :3], balls.centers) + poses[..., :3, 3]
    tested = np.isin(balls.sphere_link, checker.group_links[moving])
    hits_world = [np.any(_ball_to_obstacle(c[tested], balls.radii[tested], box) < 0.0) for c in centers]
    overlaps = checker.link_overlaps(q).any(axis=(1, 2))
    free = checker.is_free(q)
    assert 30 < free.sum() < len(q) - 30 and any(hits_world) and overlaps.any()
    assert np.array_equal(free, ~(overlaps | hits_world))
    for k in range(len(q)):
        contacts = checker.ball_contacts(q[k])
        assert (contacts == []) == free[k] and (("world" in {b for _, b in contacts}) == hits_world[k])


@pytest.mark.parametrize("kwargs, message", [
    ({"max_edge": 0.0}, "max_edge must be > 0 and finite, got 0.0"),  # used to subdivide forever
    ({"max_radius": -1.0}, "max_radius must be > 0 and finite or None, got -1.0"),
    ({"n_spheres": 0}, "n_spheres must be an integer >= 1, got 0"),
    ({"n_spheres": 2.5}, "n_spheres must be an integer >= 1, got 2.5"),
])
def test_sphere_generation_refuses_bad_parameters(kwargs, message):
    with pytest.raises(ModelError, match=f"generate_sphere_model: {message}"):
        generate_sphere_model(_primitive_robot(), cache=False, **kwargs)
    if "max_edge" in kwargs:
        model = _primitive_robot()
        with pytest.raises(ModelError, match=f"pad_sphere_model: {message}"):
            pad_sphere_model(generate_sphere_model(model, cache=False), model, cache=False, **kwargs)


def test_primitive_balls_stay_near_the_primitive(caplog):
    """Generated balls reach at most max_overshoot out of a box (the budget grows for it); eight
    balls on ARMAR-III's torso box reached 0.1 m out. A target only: the 64 balls of the cap
    reach 0.038 m out of that box (logged), and a cylinder's axis balls reach about 0.41 of its
    radius out of its flat ends, whatever the budget."""
    box = Geometry(Box((0.34, 0.24, 0.51)))
    for target in (0.06, 0.04):
        centers, radii = cover_geometries((box,), max_overshoot=target)
        assert primitive_overshoot(box, centers, radii) <= target
    coarse = cover_geometries((box,), max_overshoot=np.inf)
    assert len(coarse[1]) <= 8 and primitive_overshoot(box, *coarse) > 0.1
    with caplog.at_level(logging.INFO):
        centers, radii = cover_geometries((box,))
    assert "60 balls reach 0.038 m out of it (target 0.020 m)" in caplog.text
    points = np.random.default_rng(0).uniform(-0.5, 0.5, (20_000, 3)) * [0.34, 0.24, 0.51]  # inside the box
    assert (np.linalg.norm(points[:, None] - centers[None], axis=2) <= radii).any(axis=1).all()
    disc = Geometry(Cylinder(0.05, 0.1))
    assert primitive_overshoot(disc, *cover_geometries((disc,))) == pytest.approx(np.hypot(0.05, 0.05) - 0.05)
