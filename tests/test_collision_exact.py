"""Exact (coal) and sphere checkers on hand-made cases; allowed-collision matrices."""

from __future__ import annotations

import numpy as np
import pytest
import trimesh

from conftest import WEDGE, part_urdf
from prehensile.collision.acm import allowed_collision_matrix, compute_acm, rigid_bodies
from prehensile.collision.exact import ExactChecker
from prehensile.collision.sphere_checker import SphereChecker
from prehensile.collision.world import Obstacle
from prehensile.errors import PrehensileError
from prehensile.model.builder import JointSpec, LinkSpec, build_model
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.robots import load_path
from prehensile.spatial import make_pose, rpy_to_matrix


def _arm():
    """Planar 2-link arm about z: base (cylinder and a post ball at (1, 0.5, 0.3)), upper
    (sphere r 0.1 at x 0.5), tool fixed to upper with a box, fore (capsule along x from x 1.05
    to 1.75 at q = 0) and a geometry-less tip. The SRDF-style list disables base-fore."""
    rot_y = make_pose(np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]))  # capsule z-axis -> x
    links = [
        LinkSpec("base", collisions=[Geometry(Cylinder(0.1, 0.2)),
                                     Geometry(Sphere(0.1), make_pose(position=[1.0, 0.5, 0.3]))]),
        LinkSpec("upper", collisions=[Geometry(Sphere(0.1), make_pose(position=[0.5, 0, 0]))]),
        LinkSpec("tool", collisions=[Geometry(Box((0.1, 0.1, 0.1)), make_pose(position=[0.8, 0, 0]))]),
        LinkSpec("fore", collisions=[Geometry(Capsule(0.05, 0.6), rot_y @ make_pose(position=[0, 0, 0.4]))]),
        LinkSpec("tip"),
    ]
    z = np.array([0.0, 0, 1])
    joints = [
        JointSpec("j1", "revolute", "base", "upper", make_pose(position=[0, 0, 0.3]), z, -3.0, 3.0),
        JointSpec("jt", "fixed", "upper", "tool", np.eye(4)),
        JointSpec("j2", "revolute", "upper", "fore", make_pose(position=[1.0, 0, 0]), z, -3.0, 3.0),
        JointSpec("jtip", "fixed", "fore", "tip", make_pose(position=[0.8, 0, 0])),
    ]
    return build_model("arm", "test", links, joints, disabled_collision_pairs=[("base", "fore")])


def test_acm_skips_adjacent_same_body_geometryless_and_srdf_pairs():
    model = _arm()
    names = model.link_names
    acm = allowed_collision_matrix(model)
    idx = {n: names.index(n) for n in names}
    body = rigid_bodies(model)
    assert body[idx["tool"]] == body[idx["upper"]]
    assert acm[idx["upper"], idx["tool"]]  # same rigid body
    assert acm[idx["base"], idx["upper"]] and acm[idx["base"], idx["tool"]]  # adjacent bodies
    assert acm[idx["upper"], idx["fore"]] and acm[idx["tool"], idx["fore"]]
    assert acm[idx["tip"]].all()  # no geometry
    assert acm[idx["base"], idx["fore"]]  # disabled pair
    assert not allowed_collision_matrix(model, srdf=False)[idx["base"], idx["fore"]]
    assert np.array_equal(acm, acm.T)


def test_compute_acm_is_superset_of_structural_pairs():
    model = _arm()
    acm = compute_acm(model, n_samples=50, rng=1)
    structural = allowed_collision_matrix(model, srdf=False)
    assert np.all(acm[structural])
    assert np.array_equal(acm, compute_acm(model, n_samples=50, rng=1))


def test_box_hits_known_link_and_distance_is_analytic():
    model = _arm()
    q = np.array([0.0, 0.0])
    # upper's sphere sits at (0.5, 0, 0.3) with radius 0.1; a 0.2 box centred 0.25 above it
    box = Obstacle("block", Box((0.2, 0.2, 0.2)), make_pose(position=[0.5, 0.0, 0.3 + 0.1 + 0.1 + 0.05]))
    exact = ExactChecker(model, [box], acm=allowed_collision_matrix(model))
    assert exact.is_free(q)
    assert exact.min_distance(q) == pytest.approx(0.05, abs=1e-6)
    hit = Obstacle("block", Box((0.2, 0.2, 0.2)), make_pose(position=[0.5, 0.0, 0.3 + 0.1 + 0.1 - 0.03]))
    exact = ExactChecker(model, [hit])
    assert not exact.is_free(q)
    contacts = exact.collisions(q)
    assert [(a, b) for a, b, _ in contacts] == [("upper", "block")]
    assert contacts[0][2] == pytest.approx(0.03, abs=1e-6)
    assert not SphereChecker(model, [hit]).is_free(q)
    # rotating j1 by 90 degrees moves the sphere away from the block
    assert exact.is_free(np.array([np.pi / 2, 0.0]))


def test_sphere_obstacle_distance_and_both_checkers_agree_on_primitives():
    model = _arm()
    ball = Obstacle("ball", Sphere(0.1), make_pose(position=[0.5, 0.35, 0.3]))  # 0.15 from upper's sphere
    exact = ExactChecker(model, [ball])
    assert exact.min_distance(np.zeros(2)) == pytest.approx(0.15, abs=1e-6)
    rng = np.random.default_rng(3)
    obstacles = [
        Obstacle("box", Box((0.3, 0.2, 0.4)), make_pose(position=[0.9, -0.6, 0.3])),
        Obstacle("cyl", Cylinder(0.08, 0.5), make_pose(position=[-0.7, 0.7, 0.3])),
        Obstacle("cap", Capsule(0.05, 0.4), make_pose(position=[0.2, -1.2, 0.3])),
        ball,
    ]
    q = model.random_configurations(rng, 300)
    sphere = SphereChecker(model, obstacles).is_free(q)
    exact = ExactChecker(model, obstacles)
    truth = exact.is_free(q)
    assert not np.any(sphere & ~truth)  # never free when the exact check collides
    assert 0 < truth.sum() < len(q)


def test_batched_is_free_matches_single_queries():
    model = _arm()
    obstacles = [Obstacle("box", Box((0.3, 0.3, 0.3)), make_pose(position=[0.0, 1.1, 0.3]))]
    q = model.random_configurations(np.random.default_rng(0), 40).reshape(4, 10, 2)
    for checker in (ExactChecker(model, obstacles), SphereChecker(model, obstacles)):
        batch = checker.is_free(q)
        assert batch.shape == (4, 10)
        single = np.array([[checker.is_free(q[i, j]) for j in range(10)] for i in range(4)])
        assert np.array_equal(batch, single)
    sphere = SphereChecker(model, obstacles)
    flat = q.reshape(-1, 2)
    free = sphere.is_free(flat)
    expected = -1 if free.all() else int(np.argmin(free))
    assert sphere.first_collision(flat) == expected
    # an obstacle on the (static) base collides in every configuration
    on_base = [Obstacle("crate", Box((0.1, 0.1, 0.1)), make_pose(position=[0.0, 0.0, 0.1]))]
    assert not SphereChecker(model, on_base).is_free(flat).any()
    assert SphereChecker(model, on_base).first_collision(flat) == 0
    assert not ExactChecker(model, on_base).is_free(flat[:3]).any()


def test_self_collision_respects_acm():
    model = _arm()
    q = np.array([0.0, np.pi / 2])  # fore turns to +y and passes through base's post ball
    unchecked = allowed_collision_matrix(model, srdf=False)
    assert ExactChecker(model, []).is_free(q)  # base-fore disabled
    assert SphereChecker(model, []).is_free(q)
    exact = ExactChecker(model, [], acm=unchecked)
    assert not exact.is_free(q)
    assert [(a, b) for a, b, _ in exact.collisions(q)] == [("base", "fore")]
    assert not SphereChecker(model, [], acm=unchecked).is_free(q)
    assert exact.is_free(np.zeros(2)) and SphereChecker(model, [], acm=unchecked).is_free(np.zeros(2))



def _every_pair(checker: ExactChecker, q: np.ndarray) -> tuple[set, dict]:
    """Contacts as (link, other) and the distance (m) of every (link, other) pair, from coal on
    every pair of geometries."""
    import coal

    from prehensile.collision.exact import coal_geometry
    from prehensile.kinematics.forward import forward_kinematics

    model, poses = checker.model, forward_kinematics(checker.model, q)

    def placed(i):
        return [(coal_geometry(g.shape), poses[i] @ g.T_link_geom) for g in model.collisions[i]]

    def transform(T):
        return coal.Transform3s(T[:3, :3].copy(), T[:3, 3].copy())

    pairs = [(model.link_names[i], o.name, placed(i), [(coal_geometry(o.shape), o.T_world_shape)])
             for i in range(model.n_links) for o in checker.obstacles]
    pairs += [(model.link_names[i], model.link_names[j], placed(i), placed(j))
              for i in range(model.n_links) for j in range(i + 1, model.n_links) if not checker.acm[i, j]]
    contacts, distances = set(), {}
    for a, b, parts_a, parts_b in pairs:
        for ga, Ta in parts_a:
            for gb, Tb in parts_b:
                if coal.collide(ga, transform(Ta), gb, transform(Tb), coal.CollisionRequest(), coal.CollisionResult()):
                    contacts.add((a, b))
                d = coal.distance(ga, transform(Ta), gb, transform(Tb), coal.DistanceRequest(), coal.DistanceResult())
                distances[a, b] = min(distances.get((a, b), np.inf), d)
    return contacts, distances


def _box_mesh(size) -> Mesh:
    """A box (full sides, m) as a 12-triangle mesh."""
    box = trimesh.creation.box(extents=size)
    return Mesh.from_arrays(box.vertices, box.faces)


BROADPHASE_CASES = {  # robot, planned chain, obstacles: ARMAR-III's primitives, the Panda's meshes
    "armar3": ("TorsoRightArm", [Obstacle("table", Box((0.8, 0.5, 0.04)), make_pose(position=[0.2, 0.6, 0.95])),
                                 Obstacle("post", Cylinder(0.04, 0.8), make_pose(position=[0.45, 0.5, 1.2]))]),
    "panda": ("arm", [Obstacle("table", Box((0.6, 0.8, 0.04)), make_pose(position=[0.5, 0.0, 0.3])),
                      Obstacle("post", Cylinder(0.04, 0.8), make_pose(position=[0.3, 0.3, 0.4])),
                      Obstacle("board", _box_mesh((0.3, 0.02, 0.4)), make_pose(rpy_to_matrix([0.3, 0.0, 0.5]),
                                                                               position=[-0.3, -0.4, 0.5]))]),
}


@pytest.mark.parametrize("robot", sorted(BROADPHASE_CASES))
def test_bounding_ball_and_hull_broadphase_answers_as_every_pair(robot):
    from prehensile import robots

    if robot not in robots.available():
        pytest.skip(f"robot {robot} is not installed")
    model = robots.load(robot)
    chain, obstacles = BROADPHASE_CASES[robot]
    arm = model.chain_q_indices(chain)
    checker = ExactChecker(model, obstacles)
    rng = np.random.default_rng(4)
    q = np.repeat(model.neutral_configuration()[None], 20, axis=0)
    q[:, arm] = model.random_configurations(rng, 20)[:, arm]
    free = checker.is_free(q)
    assert 0 < free.sum() < len(q)  # both answers occur
    # each colliding configuration and a free one just beside it, on the segment to a free one
    a, b = q[free][0], q[~free][0]
    for _ in range(30):
        mid = 0.5 * (a + b)
        a, b = (mid, b) if checker.is_free(mid) else (a, mid)
    near = [a, b]
    if robot == "panda":  # meshes 1 um apart, that coal's mesh test finds touching and GJK on their hulls not
        near.append([0.15939619470527464, -1.1684146145357257, 0.41347145329851775, -3.008682989905674,
                     0.8946220803395516, 1.048506351947098, -1.054567030206134, 0.03373407196459879])
    for x in [*q, *np.array(near)]:
        contacts, distances = _every_pair(checker, x)
        assert checker.is_free(x) == (not contacts)
        assert {(link, other) for link, other, _ in checker.collisions(x)} == contacts
        if contacts:  # a touching mesh is measured by its hull's penetration, coal's mesh distance is 0 there
            assert checker.min_distance(x) <= min(distances.values()) + 1e-9
        else:
            assert checker.min_distance(x) == pytest.approx(min(distances.values()), abs=1e-9)
        near = {(p.link, p.other): p.distance for p in checker.closest_points(x, max_distance=0.1)}
        world = {o.name for o in obstacles}
        assert near == pytest.approx({k: d for k, d in distances.items() if k[1] in world and d <= 0.1}, abs=1e-9)


def test_flat_mesh_obstacle_is_checked_on_its_triangles():
    """qhull cannot take a flat vertex set (coal's call crashed the interpreter): no hull then."""
    from prehensile.model.geometry import Mesh

    model = _arm()
    plate = Mesh.from_arrays([[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], [[0, 1, 2], [0, 2, 3]])
    for height, free in ((0.3, False), (0.5, True)):  # through the upper link's ball (z 0.3, radius 0.1), or above
        checker = ExactChecker(model, [Obstacle("plate", plate, make_pose(position=[0.0, 0.0, height]))])
        assert checker.is_free(np.zeros(2)) == free
        assert (checker.min_distance(np.zeros(2)) <= 0) == (not free)


def test_a_flat_mesh_floor_is_bounded_by_a_flat_box():
    """The broadphase bounds a mesh obstacle by its oriented box: under a floor of many
    triangles every geometry's lower bound is its enclosing ball's height above the floor."""
    floor = Obstacle("floor", _box_mesh((4.0, 4.0, 0.0)),
                     make_pose(rpy_to_matrix([0.0, 0.0, 0.4]), position=[0.0, 0.0, -0.2]))
    checker = ExactChecker(_arm(), [floor])
    centers = checker._centers(checker._poses(np.array([0.3, -0.5])))
    expected = centers[0, checker._world_pairs[:, 0], 2] + 0.2 - checker._part_radius[checker._world_pairs[:, 0]]
    assert checker._world_gaps(centers)[0] == pytest.approx(expected, abs=1e-9)
    assert checker.is_free(np.array([0.3, -0.5]))


@pytest.mark.parametrize("obstacles, message", [
    ([Obstacle("box", Box((0.1, 0.1, 0.1)), np.full((4, 4), np.nan))], "'box': T_world_shape"),
    (Obstacle("box", Box((0.1, 0.1, 0.1)), np.eye(4)), "got one Obstacle"),
    ([Obstacle("box", Box((0.1, 0.1, 0.1)), np.eye(3))], "T_world_shape"),
    ([Obstacle("empty", Mesh.from_arrays(np.zeros((0, 3)), np.zeros((0, 3))), np.eye(4))], r"Mesh \(with triangles\)"),
])
def test_bad_obstacles_are_errors_naming_them(obstacles, message):
    for checker in (ExactChecker, SphereChecker):
        with pytest.raises(PrehensileError, match=message):
            checker(_arm(), obstacles)


@pytest.mark.parametrize("scale", [(1.0, -1.0, 1.0), (-1.0, -1.0, -1.0)])
def test_a_mirrored_urdf_mesh_collides_where_its_mirror_image_is(tmp_path, scale):
    """The wedge fills a corner of its frame; mirrored by the URDF scale it fills the mirrored
    corner. A ball crossing the slanted face there touches it (the hull depth is exact: the
    wedge is convex); the same ball beside the unmirrored wedge does not."""
    model = load_path(part_urdf(tmp_path, f'<mesh filename="{WEDGE}" scale="{" ".join(map(str, scale))}"/>'))
    q, centre, radius = np.zeros(1), np.array([0.03, 0.05, 0.03]), 0.02
    depth = radius - (centre.sum() - 0.1) / np.sqrt(3.0)  # beyond the face x + y + z = 0.1 m
    mirrored = ExactChecker(model, [Obstacle("ball", Sphere(radius), make_pose(position=centre * scale))])
    assert not mirrored.is_free(q) and mirrored.min_distance(q) == pytest.approx(-depth)
    assert mirrored.collisions(q) == [("part", "ball", pytest.approx(depth))]
    plain = ExactChecker(model, [Obstacle("ball", Sphere(radius), make_pose(position=centre))])
    nearest = np.where(np.asarray(scale) > 0, centre, 0.0)  # on the wedge's face in the plane y = 0, or its tip
    assert plain.is_free(q) and plain.min_distance(q) == pytest.approx(np.linalg.norm(centre - nearest) - radius)


def test_a_mirrored_mesh_obstacle_is_checked_where_its_mirror_image_is():
    """A wedge (sides 0.2 m) beside the upper link's ball (centre (0.5, 0, 0.3), radius 0.1):
    mirrored in y it reaches into the ball, unmirrored it stays 0.05 m away."""
    q, pose = np.zeros(2), make_pose(position=[0.45, 0.15, 0.25])
    depth = 0.1 - (0.05 + 0.15 + 0.05 - 0.2) / np.sqrt(3.0)  # the ball's centre is beyond the slanted face
    for scale, free, distance in (((2.0, 2.0, 2.0), True, 0.05), ((2.0, -2.0, 2.0), False, -depth)):
        obstacles = [Obstacle("wedge", Mesh(WEDGE, scale), pose)]
        exact = ExactChecker(_arm(), obstacles)
        assert exact.is_free(q) == free and SphereChecker(_arm(), obstacles).is_free(q) == free
        assert exact.min_distance(q) == pytest.approx(distance)


def test_a_pose_given_as_nested_lists_is_a_pose():
    pose = make_pose(position=[0.5, 0.0, 0.3]).tolist()
    for checker in (ExactChecker, SphereChecker):
        assert not checker(_arm(), [Obstacle("ball", Sphere(0.15), pose)]).is_free(np.zeros(2))


def test_single_configuration_queries_reject_a_batch():
    checker = ExactChecker(_arm(), [])
    for query in (checker.collisions, checker.closest_points, checker.self_contacts):
        with pytest.raises(PrehensileError, match=r"expected one configuration \(2,\)"):
            query(np.zeros((3, 2)))


@pytest.mark.parametrize("shape", [Box((0.3, 0.2, 0.1)), Sphere(0.1), Cylinder(0.1, 0.3), Capsule(0.05, 0.3)],
                         ids=lambda s: type(s).__name__)
def test_point_distance_matches_coal(shape):
    import coal

    from prehensile.collision.exact import coal_geometry, coal_transform, point_distance
    from scipy.spatial.transform import Rotation

    T = make_pose(Rotation.from_rotvec([0.3, -0.5, 0.8]).as_matrix(), [0.2, -0.1, 0.4])
    points = np.random.default_rng(2).normal([0.2, -0.1, 0.4], 0.25, size=(50, 3))
    ours = point_distance(shape, T, points)
    point = coal.Sphere(1e-9)
    theirs = [coal.distance(coal_geometry(shape), coal_transform(T), point, coal_transform(make_pose(position=p)),
                            coal.DistanceRequest(), coal.DistanceResult()) for p in points]
    outside = ours > 1e-6  # inside, primitives differ in sign conventions; a lower bound only needs <= 0
    assert outside.sum() > 25
    np.testing.assert_allclose(ours[outside], np.array(theirs)[outside], atol=1e-6)
    assert np.all(ours[~outside] <= 1e-6) and np.all(np.array(theirs)[~outside] <= 1e-6)


def test_robot_parts_are_prepared_once_per_model_and_enclose_their_geometry():
    import gc
    import weakref

    from prehensile.collision.exact import robot_parts
    from prehensile.planning.certify import ExactCertifier

    model = _arm()
    parts = robot_parts(model)
    assert [p.link for p in parts] == [0, 0, 1, 2, 3]  # every geometry, in link order
    checker = ExactChecker(model, [])
    certifier = ExactCertifier(model, [], np.eye(4), allowed_collision_matrix(model))
    assert checker._parts is parts and certifier._parts is parts
    capsule = parts[-1]  # length 0.6 + 2 radii 0.05 along x, centred at x 0.4 of fore
    assert np.allclose(capsule.center, [0.4, 0, 0]) and capsule.radius == pytest.approx(0.35)
    released = weakref.ref(model)
    del model, checker, certifier
    gc.collect()
    assert released() is None  # the cache does not keep a model alive


def test_a_mesh_reports_the_depth_of_the_box_it_is():
    """coal's mesh contacts carry no meaningful depth: a box-shaped mesh reports its hull's."""

    pose = make_pose(position=[0.5, 0.0, 0.32])  # through the upper link's ball (r 0.1 at z 0.3)
    reports = []
    for shape in (Box((0.3, 0.3, 0.06)), _box_mesh((0.3, 0.3, 0.06))):
        checker = ExactChecker(_arm(), [Obstacle("slab", shape, pose)])
        reports.append((checker.collisions(np.zeros(2)), float(checker.min_distance(np.zeros(2)))))
    (box_contacts, box_distance), (mesh_contacts, mesh_distance) = reports
    assert [(link, other) for link, other, _ in box_contacts] == [("upper", "slab")]
    assert box_contacts[0][2] == pytest.approx(0.11, abs=1e-6)  # the ball's top is 0.11 m above the slab's bottom
    assert [c[:2] for c in mesh_contacts] == [c[:2] for c in box_contacts]
    assert mesh_contacts[0][2] == pytest.approx(box_contacts[0][2], abs=1e-6)
    assert mesh_distance == pytest.approx(box_distance, abs=1e-6) and box_distance < 0


def test_a_body_wholly_inside_a_closed_mesh_collides_an_open_mesh_stays_a_surface():
    """coal finds only surfaces meeting; inside a closed mesh (winding number) is a collision too,
    whichever side holds the other. A crate whose closed surface has a cavity (outer and inner
    walls) does not hold what sits in the cavity; an open box (no lid) is a surface only."""
    model = _arm()
    tool = [0.8, 0.0, 0.3]  # the centre of the tool's 0.1 m box at q = 0
    shell = trimesh.creation.box(extents=(0.2, 0.2, 0.2))
    cavity = trimesh.creation.box(extents=(0.16, 0.16, 0.16))
    crate = trimesh.util.concatenate([shell, trimesh.Trimesh(cavity.vertices, cavity.faces[:, ::-1])])
    lidless = trimesh.Trimesh(shell.vertices, shell.faces[[f for f in range(12) if shell.face_normals[f][2] < 0.5]])
    for name, mesh, free in (("block", shell, False), ("crate", crate, True), ("lidless", lidless, True)):
        shape = Mesh.from_arrays(mesh.vertices, mesh.faces)
        checker = ExactChecker(model, [Obstacle(name, shape, make_pose(position=tool))])
        assert bool(checker.is_free(np.zeros(2))) == free, name
        assert bool(checker.collisions(np.zeros(2))) == (not free), name
    pebble = Obstacle("pebble", Sphere(0.005), np.eye(4))
    closed = build_model("closed", "test", [LinkSpec("base", collisions=[Geometry(_box_mesh((0.2, 0.2, 0.2)))])], [])
    assert [c[:2] for c in ExactChecker(closed, [pebble]).collisions(np.zeros(0))] == [("base", "pebble")]
