"""Exact collision checking and distances with coal (hpp-fcl) on the true geometry.

Link meshes become ``coal.BVHModelOBBRSS``; boxes, spheres, cylinders and capsules become the
matching coal shapes (coal takes full box sides and full cylinder/capsule lengths, as our
:mod:`~prehensile.model.geometry` does). Meshes are *surfaces*: coal reports a collision when a
triangle meets the other body, not when one body lies wholly inside a closed mesh. This
checker certifies paths; planners use :class:`~prehensile.collision.sphere_checker.SphereChecker`.
"""

from __future__ import annotations

from typing import NamedTuple, Sequence

import coal
import numpy as np

from prehensile.collision.acm import allowed_collision_matrix
from prehensile.collision.world import Obstacle
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Box, Capsule, Cylinder, Mesh, Shape, Sphere
from prehensile.model.robot_model import RobotModel


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


_TOUCH = 1e-6  # bounding balls farther apart than this (m) cannot hold touching geometries


def _transform(T: np.ndarray):
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


def _bounding_balls(placed: Sequence[tuple]) -> tuple[np.ndarray, np.ndarray]:
    """Centres (N, 3) in the frame of each pose and radii (N,) (m) of the balls around the
    local AABBs of coal geometries given as (geometry, pose (4, 4) of the geometry)."""
    centers, radii = np.zeros((len(placed), 3)), np.zeros(len(placed))
    for k, (geom, T) in enumerate(placed):
        geom.computeLocalAABB()
        centers[k] = T[:3, :3] @ geom.aabb_center + T[:3, 3]
        radii[k] = geom.aabb_radius
    return centers, radii


class ExactChecker:
    """Exact robot-vs-world and self-collision checks of one robot.

    Every query first compares bounding balls (coal's local AABB of each geometry, as a ball)
    and calls coal only on pairs whose balls meet: the answers are those of testing every pair.

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
        self.T_world_base = np.eye(4) if T_world_base is None else np.asarray(T_world_base, dtype=float)
        self.acm = allowed_collision_matrix(model) if acm is None else np.asarray(acm, dtype=bool)
        link_geoms = [[(coal_geometry(g.shape), np.asarray(g.T_link_geom, dtype=float)) for g in geoms]
                            for geoms in model.collisions]
        self.obstacles = list(obstacles)
        self._obstacles = [(o.name, coal_geometry(o.shape), _transform(np.asarray(o.T_world_shape, dtype=float)))
                           for o in self.obstacles]
        links = [i for i, g in enumerate(link_geoms) if g]
        self_pairs = [(i, j) for a, i in enumerate(links) for j in links[a + 1:] if not self.acm[i, j]]
        self._parts = [(i, geom, T) for i in range(len(link_geoms)) for geom, T in link_geoms[i]]
        self._part_link = np.array([i for i, _, _ in self._parts], dtype=np.int64)
        self._part_center, self._part_radius = _bounding_balls([(g, T) for _, g, T in self._parts])
        self._obstacle_center, self._obstacle_radius = _bounding_balls(
            [(geom, np.asarray(o.T_world_shape, dtype=float)) for o, (_, geom, _) in zip(self.obstacles, self._obstacles)])
        first = np.cumsum([0] + [len(g) for g in link_geoms])
        self._world_pairs = np.array([(p, o) for i in links for p in range(first[i], first[i + 1])
                                      for o in range(len(self._obstacles))], dtype=np.int64).reshape(-1, 2)
        self._part_pairs = np.array([(a, b) for i, j in self_pairs for a in range(first[i], first[i + 1])
                                     for b in range(first[j], first[j + 1])], dtype=np.int64).reshape(-1, 2)
        self._request = coal.CollisionRequest()
        self._contact_request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, 1)
        self._distance_request = coal.DistanceRequest()

    def _poses(self, q: np.ndarray) -> np.ndarray:
        """Link poses (B, L, 4, 4) of the configurations q (*batch, dof), checked."""
        poses = forward_kinematics(self.model, self.model.check_configuration(q), self.T_world_base)
        return poses.reshape(-1, self.model.n_links, 4, 4)

    def _gaps(self, poses: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Lower bounds (m) on the distance of every world pair (B, W) and self pair (B, S) of
        geometries, from their bounding balls, for link poses (B, L, 4, 4)."""
        frames = poses[:, self._part_link]
        centers = np.einsum("bgij,gj->bgi", frames[..., :3, :3], self._part_center) + frames[..., :3, 3]
        w, s = self._world_pairs, self._part_pairs
        world = (np.linalg.norm(centers[:, w[:, 0]] - self._obstacle_center[w[:, 1]], axis=-1)
                 - self._part_radius[w[:, 0]] - self._obstacle_radius[w[:, 1]])
        own = (np.linalg.norm(centers[:, s[:, 0]] - centers[:, s[:, 1]], axis=-1)
               - self._part_radius[s[:, 0]] - self._part_radius[s[:, 1]])
        return world, own

    def _placer(self, poses: np.ndarray):
        """part(g) -> (coal geometry, world transform) of geometry g for link poses (L, 4, 4),
        each transform built once, on first use."""
        placed: dict[int, tuple] = {}

        def part(g: int) -> tuple:
            if g not in placed:
                link, geom, T = self._parts[g]
                placed[g] = (geom, _transform(poses[link] @ T))
            return placed[g]

        return part

    def _world_candidates(self, part, gap: np.ndarray, within: float):
        """(link index, obstacle index, placed geometry, obstacle geometry) of the world pairs
        whose bounding balls are at most ``within`` m apart (``gap`` (W,) of one configuration)."""
        for g, o in self._world_pairs[gap <= within]:
            _, geom, T = self._obstacles[o]
            yield self._parts[g][0], o, part(g), (geom, T)

    def _self_candidates(self, part, gap: np.ndarray, within: float):
        """(link index, link index, placed geometry, placed geometry) of the self pairs whose
        bounding balls are at most ``within`` m apart (``gap`` (S,) of one configuration)."""
        for a, b in self._part_pairs[gap <= within]:
            yield self._parts[a][0], self._parts[b][0], part(a), part(b)

    def _candidates(self, poses: np.ndarray, world_gap: np.ndarray, self_gap: np.ndarray, within: float):
        """(link name, other name, geometry, geometry) of the world pairs, then the self pairs,
        of one configuration (link poses (L, 4, 4)) whose bounding balls are at most ``within`` m apart."""
        names, part = self.model.link_names, self._placer(poses)
        for link, o, a, b in self._world_candidates(part, world_gap, within):
            yield names[link], self._obstacles[o][0], a, b
        for i, j, a, b in self._self_candidates(part, self_gap, within):
            yield names[i], names[j], a, b

    def _collide(self, a, b, request) -> tuple[bool, float]:
        result = coal.CollisionResult()
        hit = coal.collide(a[0], a[1], b[0], b[1], request, result) > 0
        depth = 0.0
        if hit and request.enable_contact:
            depth = max((abs(c.penetration_depth) for c in result.getContacts()), default=0.0)
        return hit, depth

    def is_free(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool: no non-allowed pair touches, for q (*batch, dof) (rad or m)."""
        q = np.asarray(q, dtype=float)
        poses = self._poses(q)
        world, own = self._gaps(poses)
        free = [not any(self._collide(a, b, self._request)[0] for _, _, a, b in self._candidates(p, w, s, _TOUCH))
                for p, w, s in zip(poses, world, own)]
        return np.array(free, dtype=bool).reshape(q.shape[:-1])

    def collisions(self, q: np.ndarray) -> list[tuple[str, str, float]]:
        """All contacts of one configuration q (dof,): (link, other, penetration depth m >= 0).

        ``other`` is an obstacle name or a link name; each pair of geometries reports once.
        """
        poses = self._poses(q)
        world, own = self._gaps(poses)
        out: list[tuple[str, str, float]] = []
        for link, other, a, b in self._candidates(poses[0], world[0], own[0], _TOUCH):
            hit, depth = self._collide(a, b, self._contact_request)
            if hit:
                out.append((link, other, depth))
        return out

    def _distance(self, a, b) -> float:
        result = coal.DistanceResult()
        return float(coal.distance(a[0], a[1], b[0], b[1], self._distance_request, result))

    def min_distance(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) smallest distance (m) over all checked pairs; negative when penetrating
        (coal's signed distance; +inf when nothing is checked)."""
        q = np.asarray(q, dtype=float)
        poses = self._poses(q)
        world, own = self._gaps(poses)
        out = np.full(len(poses), np.inf)
        for b, (p, w, s) in enumerate(zip(poses, world, own)):
            for _, _, x, y in self._candidates(p, w, s, np.inf):
                out[b] = min(out[b], self._distance(x, y))
        return out.reshape(q.shape[:-1])

    def closest_points(self, q: np.ndarray, max_distance: float = np.inf) -> list[ClosestPair]:
        """Closest points of every robot link and every obstacle for one configuration q (dof,).

        A link with several geometries reports its closest one. Pairs farther apart than
        ``max_distance`` (m) are left out (a finite value skips geometries whose bounding ball
        is farther, which is much faster for meshes); self pairs are not reported.

        Returns:
            One :class:`ClosestPair` per (link with geometry, obstacle) within ``max_distance``,
            in link then obstacle order.
        """
        poses = self._poses(q)
        world, _ = self._gaps(poses)
        best: dict[tuple[int, int], ClosestPair] = {}
        for link, o, part, other in self._world_candidates(self._placer(poses[0]), world[0], max_distance):
            result = coal.DistanceResult()
            d = float(coal.distance(part[0], part[1], other[0], other[1], self._distance_request, result))
            if d <= max_distance and ((link, o) not in best or d < best[link, o].distance):
                best[link, o] = ClosestPair(self.model.link_names[link], self._obstacles[o][0], d,
                                            np.array(result.getNearestPoint1(), dtype=float),
                                            np.array(result.getNearestPoint2(), dtype=float))
        return [best[key] for key in sorted(best)]

    def self_contacts(self, q: np.ndarray) -> np.ndarray:
        """(L, L) bool for one configuration q (dof,): which link pairs touch, over the pairs
        the checker's ACM does not skip (used by :func:`~prehensile.collision.acm.compute_acm`)."""
        poses = self._poses(q)
        _, own = self._gaps(poses)
        contact = np.zeros((self.model.n_links, self.model.n_links), dtype=bool)
        for i, j, a, b in self._self_candidates(self._placer(poses[0]), own[0], _TOUCH):
            if not contact[i, j] and self._collide(a, b, self._request)[0]:
                contact[i, j] = contact[j, i] = True
        return contact
