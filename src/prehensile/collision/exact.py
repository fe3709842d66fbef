"""Exact collision checking and distances with coal (hpp-fcl) on the true geometry.

Link meshes become ``coal.BVHModelOBBRSS``; boxes, spheres, cylinders and capsules become the
matching coal shapes (coal takes full box sides and full cylinder/capsule lengths, as our
:mod:`~prehensile.model.geometry` does). coal treats meshes as *surfaces*: it reports a
collision when a triangle meets the other body, not when one body lies wholly inside a closed
mesh. The checks of single configurations here (:meth:`ExactChecker.is_free`,
:meth:`ExactChecker.collisions`) add that case for closed (watertight) meshes: where the
convex hulls meet but the surfaces do not, a point of one body inside the other closed mesh
(winding number) is a collision, one point per connected piece of a mesh (a file may hold
several parts). Open meshes (a sheet, a crate's walls without thickness) stay
surfaces. Along a path, a body cannot get inside without crossing a surface, which the
certification finds; it tests containment at the path's start. This checker certifies paths;
planners use
:class:`~prehensile.collision.sphere_checker.SphereChecker`.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence
from weakref import WeakKeyDictionary

import coal
import numpy as np
import trimesh

from prehensile.collision.acm import allowed_collision_matrix, rigid_bodies
from prehensile.collision.sphere_fit import box_cover, geometry_triangles
from prehensile.collision.world import Obstacle, check_obstacles
from prehensile.errors import PrehensileError
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Shape, Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.spatial.transforms import check_one_pose


def coal_geometry(shape: Shape):
    """The coal collision geometry of ``shape`` (in the shape's own frame)."""
    if isinstance(shape, Box):
        return coal.Box(*(float(s) for s in shape.size))
    if isinstance(shape, Sphere):
        return coal.Sphere(float(shape.radius))
    if isinstance(shape, Cylinder):
        return coal.Cylinder(float(shape.radius), float(shape.length))
    if isinstance(shape, Capsule):
        return coal.Capsule(float(shape.radius), float(shape.length))
    if isinstance(shape, Mesh):
        mesh = shape.trimesh
        bvh = coal.BVHModelOBBRSS()
        bvh.beginModel(len(mesh.faces), len(mesh.vertices))
        bvh.addVertices(np.ascontiguousarray(mesh.vertices, dtype=float))
        bvh.addTriangles(np.ascontiguousarray(mesh.faces, dtype=np.int64))
        bvh.endModel()
        return bvh
    raise TypeError(f"unsupported shape {type(shape).__name__}; valid: Box, Sphere, Cylinder, Capsule, Mesh")


class ClosestPair(NamedTuple):
    """Closest points of one robot link and one obstacle, in world coordinates.

    Attributes:
        link: robot link name.
        other: obstacle name.
        distance: signed distance (m), negative when penetrating.
        point_on_robot: (3,) nearest point on the link's geometry (m).
        point_on_other: (3,) nearest point on the obstacle (m).
    """

    link: str
    other: str
    distance: float
    point_on_robot: np.ndarray
    point_on_other: np.ndarray


def convex_bound(shape: Shape, exact):
    """A convex coal geometry containing ``shape`` whose coal geometry is ``exact``: the convex
    hull for a mesh, ``exact`` for a primitive or a flat mesh (qhull needs a solid vertex set:
    coal's call crashes the interpreter on a flat one)."""
    if not isinstance(shape, Mesh):
        return exact
    vertices = np.asarray(shape.trimesh.vertices, dtype=float)
    if len(vertices) < 4:
        return exact
    spread = np.linalg.svd(vertices - vertices.mean(axis=0), compute_uv=False)
    if spread[2] <= 1e-9 * max(spread[0], 1e-12):
        return exact
    points = coal.StdVec_Vec3s()
    for p in vertices:
        points.append(p)
    try:
        return coal.Convex.convexHull(points, False, "")
    except Exception:  # qhull refused the vertex set
        return exact


def closed_triangles(shape: Shape) -> np.ndarray | None:
    """(F, 3, 3) the triangles of a closed (watertight, consistently wound) mesh ``shape`` in
    its own frame, to test points for being inside it (:func:`inside_closed_mesh`); None for a
    primitive or an open mesh."""
    if not isinstance(shape, Mesh):
        return None
    mesh = _merged(shape)
    return np.asarray(mesh.triangles, dtype=float) if mesh.is_watertight and mesh.is_winding_consistent else None


def _merged(shape: Mesh) -> trimesh.Trimesh:
    """The mesh of ``shape`` with repeated vertices merged (an STL file repeats each vertex for
    every triangle that has it)."""
    mesh = shape.trimesh.copy()
    mesh.merge_vertices()
    return mesh


def inside_closed_mesh(triangles: np.ndarray, point: np.ndarray) -> bool:
    """Whether ``point`` (3,) lies inside the closed mesh of ``triangles`` (F, 3, 3), both in
    one frame: its winding number, the triangles' solid angles seen from the point over 4 pi
    (Van Oosterom & Strackee 1983), is +-1 inside and 0 outside."""
    a, b, c = np.moveaxis(triangles - point, 1, 0)
    la, lb, lc = (np.linalg.norm(v, axis=1) for v in (a, b, c))
    numerator = np.einsum("ij,ij->i", a, np.cross(b, c))
    denominator = (la * lb * lc + np.einsum("ij,ij->i", a, b) * lc + np.einsum("ij,ij->i", b, c) * la
                   + np.einsum("ij,ij->i", c, a) * lb)
    return abs(float(np.sum(np.arctan2(numerator, denominator)))) > np.pi  # winding number above 1/2


def _anchors(shape: Shape) -> np.ndarray:
    """(k, 3) a point of each connected piece of ``shape`` in its own frame: a primitive's
    centre; a vertex of every connected set of a mesh's faces (a mesh file may merge parts, and
    hold vertices no face uses)."""
    if not isinstance(shape, Mesh):
        return np.zeros((1, 3))
    mesh = _merged(shape)
    pieces = trimesh.graph.connected_components(mesh.edges, nodes=np.unique(mesh.faces))
    return np.asarray(mesh.vertices[[piece[0] for piece in pieces]], dtype=float).reshape(-1, 3)


def coal_transform(T: np.ndarray):
    """The coal transform of the pose T (4, 4)."""
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


_SLACK = 1e-5  # m: bounds this far apart may still hold geometries that coal finds touching
# a placed geometry: (exact, convex bound, coal transform, pose (4, 4), closed triangles or None, anchors (k, 3))
_EXACT, _BOUND, _POSE, _MATRIX, _CLOSED, _ANCHORS = 0, 1, 2, 3, 4, 5


def _convex(placed: tuple) -> bool:
    """The placed geometry is its own convex bound (a primitive, or a flat mesh without a hull)."""
    return placed[_BOUND] is placed[_EXACT]


def enclosing_ball(shape: Shape, T: np.ndarray) -> tuple[np.ndarray, float]:
    """Centre (3,) and radius (m) of a ball containing ``shape`` placed at the pose T (4, 4)
    (the centre in T's parent frame)."""
    T = np.asarray(T, dtype=float)
    if isinstance(shape, Mesh):
        points = np.asarray(shape.trimesh.vertices, dtype=float) @ T[:3, :3].T + T[:3, 3]
        center = 0.5 * (points.min(axis=0) + points.max(axis=0))
        return center, float(np.max(np.linalg.norm(points - center, axis=1), initial=0.0))
    if isinstance(shape, Box):
        radius = 0.5 * float(np.linalg.norm(shape.size))
    elif isinstance(shape, Sphere):
        radius = float(shape.radius)
    elif isinstance(shape, Cylinder):
        radius = float(np.hypot(shape.radius, 0.5 * shape.length))
    elif isinstance(shape, Capsule):
        radius = float(shape.radius + 0.5 * shape.length)
    else:
        raise TypeError(f"unsupported shape {type(shape).__name__}; valid: Box, Sphere, Cylinder, Capsule, Mesh")
    return T[:3, 3].copy(), radius


def point_distance(shape: Shape, T: np.ndarray, points: np.ndarray) -> np.ndarray:
    """Distances (...,) (m; negative inside a sphere or capsule, 0 inside a box or cylinder) of
    world points (..., 3) to the primitive ``shape`` (not a mesh) at the pose T (4, 4)."""
    T = np.asarray(T, dtype=float)
    local = (points - T[:3, 3]) @ T[:3, :3]
    if isinstance(shape, Box):
        return np.linalg.norm(np.maximum(np.abs(local) - 0.5 * np.asarray(shape.size, dtype=float), 0.0), axis=-1)
    if isinstance(shape, Sphere):
        return np.linalg.norm(local, axis=-1) - shape.radius
    if isinstance(shape, Cylinder):
        radial = np.maximum(np.linalg.norm(local[..., :2], axis=-1) - shape.radius, 0.0)
        return np.hypot(radial, np.maximum(np.abs(local[..., 2]) - 0.5 * shape.length, 0.0))
    if isinstance(shape, Capsule):
        axis = np.zeros_like(local)
        axis[..., 2] = np.clip(local[..., 2], -0.5 * shape.length, 0.5 * shape.length)
        return np.linalg.norm(local - axis, axis=-1) - shape.radius
    raise TypeError(f"unsupported shape {type(shape).__name__}; valid: Box, Sphere, Cylinder, Capsule")


class RobotPart(NamedTuple):
    """One collision geometry of a robot link, prepared for coal.

    Attributes:
        link: index of the link.
        T_link_geom: (4, 4) pose of the geometry in the link frame.
        exact: coal geometry of the shape (:func:`coal_geometry`).
        bound: convex coal geometry containing it (:func:`convex_bound`).
        convex: ``exact`` is convex (a primitive): ``bound`` is ``exact``.
        center: (3,) centre of a ball containing the geometry, in the link frame (m).
        radius: that ball's radius (m).
        closed: (F, 3, 3) triangles of a closed mesh in the geometry's frame, else None
            (:func:`closed_triangles`).
        anchors: (k, 3) a point of each connected piece of the geometry, in its frame.
    """

    link: int
    T_link_geom: np.ndarray
    exact: object
    bound: object
    convex: bool
    center: np.ndarray
    radius: float
    closed: np.ndarray | None
    anchors: np.ndarray


_ROBOT_PARTS: WeakKeyDictionary = WeakKeyDictionary()


def robot_parts(model: RobotModel) -> tuple[RobotPart, ...]:
    """Every collision geometry of every link of ``model``, in link order, prepared once per
    model (mesh BVHs and convex hulls take tens of ms for a Panda) and shared by the exact
    checkers and certifiers of all its contexts."""
    if model not in _ROBOT_PARTS:
        parts = []
        for link, geometries in enumerate(model.collisions):
            for g in geometries:
                exact, T = coal_geometry(g.shape), np.asarray(g.T_link_geom, dtype=float)
                center, radius = enclosing_ball(g.shape, T)
                parts.append(RobotPart(link, T, exact, convex_bound(g.shape, exact), not isinstance(g.shape, Mesh),
                                       center, radius, closed_triangles(g.shape), _anchors(g.shape)))
        _ROBOT_PARTS[model] = tuple(parts)
    return _ROBOT_PARTS[model]


class ObstaclePart(NamedTuple):
    """One world obstacle, prepared for coal.

    Attributes:
        name: the obstacle's name.
        T_world_shape: (4, 4) its pose in the world.
        exact: coal geometry of the shape (:func:`coal_geometry`).
        bound: convex coal geometry containing it (:func:`convex_bound`).
        convex: ``exact`` is convex (a primitive): ``bound`` is ``exact``.
        transform: ``T_world_shape`` as a coal transform.
        closed: (F, 3, 3) triangles of a closed mesh in the shape's frame, else None.
        anchors: (k, 3) a point of each connected piece of the shape, in its frame.
    """

    name: str
    T_world_shape: np.ndarray
    exact: object
    bound: object
    convex: bool
    transform: object
    closed: np.ndarray | None
    anchors: np.ndarray


def obstacle_parts(obstacles: Sequence[Obstacle]) -> tuple[ObstaclePart, ...]:
    """The coal geometry of ``obstacles`` (mesh BVHs and hulls take a while for big meshes): build
    it once and give it to every exact checker and certifier of the same world."""
    parts = []
    for o in check_obstacles(obstacles):
        exact, T = coal_geometry(o.shape), np.asarray(o.T_world_shape, dtype=float)
        parts.append(ObstaclePart(o.name, T, exact, convex_bound(o.shape, exact), not isinstance(o.shape, Mesh),
                                  coal_transform(T), closed_triangles(o.shape), _anchors(o.shape)))
    return tuple(parts)


def contains(closed: np.ndarray | None, T_world_closed: np.ndarray, anchors: np.ndarray,
             T_world_anchors: np.ndarray) -> bool:
    """Whether the closed mesh ``closed`` (F, 3, 3, None: not a closed mesh) at pose
    ``T_world_closed`` (4, 4) holds one of the points ``anchors`` (k, 3) of another geometry at
    ``T_world_anchors``: a piece of that geometry lies wholly inside the mesh if their surfaces
    do not meet."""
    if closed is None:
        return False
    points = anchors @ T_world_anchors[:3, :3].T + T_world_anchors[:3, 3]
    local = (points - T_world_closed[:3, 3]) @ T_world_closed[:3, :3]
    return any(inside_closed_mesh(closed, point) for point in local)


def _contains(a: tuple, b: tuple) -> bool:
    """:func:`contains` for the placed geometries a (the closed one) and b."""
    return contains(a[_CLOSED], a[_MATRIX], b[_ANCHORS], b[_MATRIX])


class ExactChecker:
    """Exact robot-vs-world and self-collision checks of one robot.

    Every query first compares bounding balls (:func:`enclosing_ball`), then the convex hulls
    of meshes, and asks coal about a mesh only where both meet: the answers are those of
    testing every pair on the exact geometry.

    Args:
        model: the robot; every collision geometry of every link is used.
        obstacles: shapes fixed in the world.
        T_world_base: pose (4, 4) of the robot root; identity if None.
        acm: (L, L) bool allowed-collision matrix (True = skip the pair); default
            :func:`~prehensile.collision.acm.allowed_collision_matrix` of the model.
    """

    def __init__(self, model: RobotModel, obstacles: Sequence[Obstacle], T_world_base: np.ndarray | None = None,
                 acm: np.ndarray | None = None) -> None:
        self.model = model
        self.T_world_base = np.eye(4) if T_world_base is None else check_one_pose(T_world_base, "T_world_base")
        self.acm = allowed_collision_matrix(model) if acm is None else np.asarray(acm, dtype=bool)
        self.obstacles = check_obstacles(obstacles)
        self.obstacle_parts = obstacle_parts(self.obstacles)
        """The obstacles' coal geometry (:func:`obstacle_parts`), to share with certifiers of this world."""
        self._obstacle_bounds = []  # (primitive, pose): the obstacle, or the box holding a mesh
        for o in self.obstacles:
            T = np.asarray(o.T_world_shape, dtype=float)
            if isinstance(o.shape, Mesh):  # a flat mesh (a floor) gets a flat box, 1 pm thick (a Box needs sides > 0)
                (T_shape_box,), (half,) = box_cover(geometry_triangles(Geometry(o.shape)), 1)
                self._obstacle_bounds.append((Box(tuple(np.maximum(2.0 * half, 1e-12))), T @ T_shape_box))
            else:
                self._obstacle_bounds.append((o.shape, T))
        self._parts = robot_parts(model)
        links = [i for i, g in enumerate(model.collisions) if g]
        self_pairs = [(i, j) for a, i in enumerate(links) for j in links[a + 1:] if not self.acm[i, j]]
        self._part_link = np.array([p.link for p in self._parts], dtype=np.int64)
        self._part_center = np.array([p.center for p in self._parts]).reshape(-1, 3)
        self._part_radius = np.array([p.radius for p in self._parts])
        first = np.cumsum([0] + [len(g) for g in model.collisions])
        self._world_pairs = np.array([(p, o) for i in links for p in range(first[i], first[i + 1])
                                      for o in range(len(self.obstacle_parts))], dtype=np.int64).reshape(-1, 2)
        self._part_pairs = np.array([(a, b) for i, j in self_pairs for a in range(first[i], first[i + 1])
                                     for b in range(first[j], first[j + 1])], dtype=np.int64).reshape(-1, 2)
        self._request = coal.CollisionRequest()
        self._bound_request = coal.CollisionRequest()  # hulls within the slack "collide"
        self._bound_request.security_margin = _SLACK
        self._contact_request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, 1)
        self._distance_request = coal.DistanceRequest()

    def _poses(self, q: np.ndarray) -> np.ndarray:
        """Link poses (B, L, 4, 4) of the configurations q (*batch, dof), checked."""
        poses = forward_kinematics(self.model, self.model.check_configuration(q), self.T_world_base)
        return poses.reshape(-1, self.model.n_links, 4, 4)

    def _one(self, q: np.ndarray, what: str) -> np.ndarray:
        """Link poses (1, L, 4, 4) of one configuration q (dof,); PrehensileError otherwise."""
        return self._poses(self.model.check_one(q, f"ExactChecker.{what}"))

    def _centers(self, poses: np.ndarray) -> np.ndarray:
        """World centres (B, G, 3) of the geometries' enclosing balls for link poses (B, L, 4, 4)."""
        frames = poses[:, self._part_link]
        return np.einsum("bgij,gj->bgi", frames[..., :3, :3], self._part_center) + frames[..., :3, 3]

    def _world_gaps(self, centers: np.ndarray) -> np.ndarray:
        """Lower bounds (B, W) (m) on the distance of every world pair, from the geometries'
        enclosing balls (centres (B, G, 3)) against the obstacles' own primitives
        (:func:`point_distance`) or the oriented box holding a mesh."""
        to_obstacle = np.zeros(centers.shape[:2] + (len(self.obstacles),))
        for k, (shape, T) in enumerate(self._obstacle_bounds):
            to_obstacle[..., k] = point_distance(shape, T, centers)
        w = self._world_pairs
        return to_obstacle[:, w[:, 0], w[:, 1]] - self._part_radius[w[:, 0]]

    def _self_gaps(self, centers: np.ndarray) -> np.ndarray:
        """Lower bounds (B, S) (m) on the distance of every self pair, from the enclosing balls."""
        s = self._part_pairs
        return (np.linalg.norm(centers[:, s[:, 0]] - centers[:, s[:, 1]], axis=-1)
                - self._part_radius[s[:, 0]] - self._part_radius[s[:, 1]])

    def _gaps(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(:meth:`_world_gaps`, :meth:`_self_gaps`) for link poses (B, L, 4, 4)."""
        centers = self._centers(poses)
        return self._world_gaps(centers), self._self_gaps(centers)

    def _placer(self, poses: np.ndarray):
        """part(g) -> the placed geometry g (see ``_EXACT``) for link poses (L, 4, 4), each
        transform built once, on first use."""
        placed: dict[int, tuple] = {}

        def part(g: int) -> tuple:
            if g not in placed:
                p = self._parts[g]
                T = poses[p.link] @ p.T_link_geom
                placed[g] = (p.exact, p.bound, coal_transform(T), T, p.closed, p.anchors)
            return placed[g]

        return part

    def _world_candidates(self, part, gap: np.ndarray, within: float):
        """(link index, obstacle index, placed geometry, obstacle geometry) of the world pairs
        whose bounding balls are at most ``within`` m apart (``gap`` (W,) of one configuration)."""
        for g, o in self._world_pairs[gap <= within]:
            obstacle = self.obstacle_parts[o]
            yield self._parts[g].link, o, part(g), (obstacle.exact, obstacle.bound, obstacle.transform,
                                                    obstacle.T_world_shape, obstacle.closed, obstacle.anchors)

    def _self_candidates(self, part, gap: np.ndarray, within: float):
        """(link index, link index, placed geometry, placed geometry) of the self pairs whose
        bounding balls are at most ``within`` m apart (``gap`` (S,) of one configuration)."""
        for a, b in self._part_pairs[gap <= within]:
            yield self._parts[a].link, self._parts[b].link, part(a), part(b)

    def _candidates(self, poses: np.ndarray, world_gap: np.ndarray, self_gap: np.ndarray, within: float):
        """(link name, other name, geometry, geometry) of the world pairs, then the self pairs,
        of one configuration (link poses (L, 4, 4)) whose bounding balls are at most ``within`` m apart."""
        names, part = self.model.link_names, self._placer(poses)
        for link, o, a, b in self._world_candidates(part, world_gap, within):
            yield names[link], self.obstacle_parts[o].name, a, b
        for i, j, a, b in self._self_candidates(part, self_gap, within):
            yield names[i], names[j], a, b

    def _collide(self, a, b, request) -> tuple[bool, float]:
        """(whether the placed geometries a and b touch, penetration depth (m) if ``request`` asks for contacts)."""
        if (a[_BOUND] is not a[_EXACT] or b[_BOUND] is not b[_EXACT]) and not coal.collide(
                a[_BOUND], a[_POSE], b[_BOUND], b[_POSE], self._bound_request, coal.CollisionResult()):
            return False, 0.0
        result = coal.CollisionResult()
        hit = coal.collide(a[_EXACT], a[_POSE], b[_EXACT], b[_POSE], request, result) > 0
        if not hit and (_contains(a, b) or _contains(b, a)):
            return True, self._mesh_depth(a, b) if request.enable_contact else 0.0
        depth = 0.0
        if hit and request.enable_contact:
            depth = (max((abs(c.penetration_depth) for c in result.getContacts()), default=0.0)
                     if _convex(a) and _convex(b) else self._mesh_depth(a, b))
        return hit, depth

    def _mesh_depth(self, a, b) -> float:
        """Penetration depth (m) of touching placed geometries of which one is a mesh: that of
        their convex hulls (coal's mesh contacts carry no meaningful depth; exact for convex
        meshes)."""
        return max(-self._distance(a, b, _BOUND), 0.0)

    def is_free(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool: no non-allowed pair touches, for q (*batch, dof) (rad or m)."""
        q = np.asarray(q, dtype=float)
        poses = self._poses(q)
        world, own = self._gaps(poses)
        free = [not any(self._collide(a, b, self._request)[0] for _, _, a, b in self._candidates(p, w, s, _SLACK))
                for p, w, s in zip(poses, world, own)]
        return np.array(free, dtype=bool).reshape(q.shape[:-1])

    def collisions(self, q: np.ndarray, kind: str = "all") -> list[tuple[str, str, float]]:
        """Contacts of one configuration q (dof,): (link, other, penetration depth m >= 0; where a
        mesh touches, the depth of the convex hulls).

        ``other`` is an obstacle name or a link name; each pair of geometries reports once.
        ``kind``: "world" (robot against obstacles), "self" (link against link) or "all" (world
        contacts first); an obstacle may share a link's name.
        """
        if kind not in ("all", "world", "self"):
            raise PrehensileError(f"ExactChecker.collisions: kind must be 'all', 'world' or 'self', got {kind!r}")
        poses = self._one(q, "collisions")
        world, own = self._gaps(poses)
        if kind != "all":  # an infinite gap leaves a pair out
            (own if kind == "world" else world)[:] = np.inf
        out: list[tuple[str, str, float]] = []
        for link, other, a, b in self._candidates(poses[0], world[0], own[0], _SLACK):
            hit, depth = self._collide(a, b, self._contact_request)
            if hit:
                out.append((link, other, depth))
        return out

    def root_contacts(self, q: np.ndarray) -> list[tuple[str, str, float]]:
        """World contacts (link, obstacle, depth m) of the links rigid with the robot's root, at
        any configuration q (dof,): they never move, so these hold in every configuration."""
        body = rigid_bodies(self.model)
        root_body = body[np.flatnonzero(self.model.link_parent < 0)[0]]
        root = {self.model.link_names[i] for i in np.flatnonzero(body == root_body)}
        return [c for c in self.collisions(q, "world") if c[0] in root]

    def _distance(self, a, b, which: int = _EXACT) -> float:
        """Distance (m) of the placed geometries a and b: exact, or of their convex bounds (``_BOUND``)."""
        result = coal.DistanceResult()
        return float(coal.distance(a[which], a[_POSE], b[which], b[_POSE], self._distance_request, result))

    def min_distance(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) smallest distance (m) over all checked pairs; negative when penetrating
        (coal's signed distance; where a mesh touches, minus the depth of the convex hulls; +inf
        when nothing is checked)."""
        q = np.asarray(q, dtype=float)
        poses = self._poses(q)
        world, own = self._gaps(poses)
        out = np.full(len(poses), np.inf)
        for b, (p, w, s) in enumerate(zip(poses, world, own)):
            for _, _, x, y in self._candidates(p, w, s, np.inf):
                d = self._distance(x, y)
                if d <= 0.0 and not (_convex(x) and _convex(y)):  # a mesh touches: measure how deep
                    d = -self._mesh_depth(x, y)
                out[b] = min(out[b], d)
        return out.reshape(q.shape[:-1])

    def closest_points(self, q: np.ndarray, max_distance: float = np.inf) -> list[ClosestPair]:
        """Closest points of every robot link and every obstacle for one configuration q (dof,).

        A link with several geometries reports its closest one. Pairs farther apart than
        ``max_distance`` (m) are left out (a finite value skips geometries whose bounding ball
        or convex hull is farther, which is much faster for meshes); self pairs are not reported.

        Returns:
            One :class:`ClosestPair` per (link with geometry, obstacle) within ``max_distance``,
            in link then obstacle order.
        """
        poses = self._one(q, "closest_points")
        world = self._world_gaps(self._centers(poses))
        best: dict[tuple[int, int], ClosestPair] = {}
        within = max_distance + _SLACK
        for link, o, part, other in self._world_candidates(self._placer(poses[0]), world[0], within):
            hull_only = part[_BOUND] is not part[_EXACT]
            if np.isfinite(within) and hull_only and self._distance(part, other, _BOUND) > within:
                continue
            result = coal.DistanceResult()
            d = float(coal.distance(part[_EXACT], part[_POSE], other[_EXACT], other[_POSE], self._distance_request,
                                    result))
            if d <= max_distance and ((link, o) not in best or d < best[link, o].distance):
                best[link, o] = ClosestPair(self.model.link_names[link], self.obstacle_parts[o].name, d,
                                            np.array(result.getNearestPoint1(), dtype=float),
                                            np.array(result.getNearestPoint2(), dtype=float))
        return [best[key] for key in sorted(best)]

    def self_contacts(self, q: np.ndarray) -> np.ndarray:
        """(L, L) bool for one configuration q (dof,): which link pairs touch, over the pairs
        the checker's ACM does not skip (used by :func:`~prehensile.collision.acm.compute_acm`)."""
        poses = self._one(q, "self_contacts")
        own = self._self_gaps(self._centers(poses))
        contact = np.zeros((self.model.n_links, self.model.n_links), dtype=bool)
        for i, j, a, b in self._self_candidates(self._placer(poses[0]), own[0], _SLACK):
            if not contact[i, j] and self._collide(a, b, self._request)[0]:
                contact[i, j] = contact[j, i] = True
        return contact
