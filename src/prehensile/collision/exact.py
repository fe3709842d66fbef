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


def _transform(T: np.ndarray):
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


class ExactChecker:
    """Exact robot-vs-world and self-collision checks of one robot.

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
        self._link_geoms = [[(coal_geometry(g.shape), np.asarray(g.T_link_geom, dtype=float)) for g in geoms]
                            for geoms in model.collisions]
        self.obstacles = list(obstacles)
        self._obstacles = [(o.name, coal_geometry(o.shape), _transform(np.asarray(o.T_world_shape, dtype=float)))
                           for o in self.obstacles]
        links = [i for i, g in enumerate(self._link_geoms) if g]
        self._links = links
        self._self_pairs = [(i, j) for a, i in enumerate(links) for j in links[a + 1:] if not self.acm[i, j]]
        self._request = coal.CollisionRequest()
        self._contact_request = coal.CollisionRequest(coal.CollisionRequestFlag.CONTACT, 1)
        self._distance_request = coal.DistanceRequest()

    def _placed(self, poses: np.ndarray) -> list[list]:
        """Per link, its coal geometries with world transforms for link poses (L, 4, 4)."""
        return [[(geom, _transform(poses[i] @ T)) for geom, T in self._link_geoms[i]] for i in range(len(poses))]

    def _collide(self, a, b, request) -> tuple[bool, float]:
        result = coal.CollisionResult()
        hit = coal.collide(a[0], a[1], b[0], b[1], request, result) > 0
        depth = 0.0
        if hit and request.enable_contact:
            depth = max((abs(c.penetration_depth) for c in result.getContacts()), default=0.0)
        return hit, depth

    def _first_hit(self, placed) -> bool:
        for i in self._links:
            for part in placed[i]:
                for _, geom, T in self._obstacles:
                    if self._collide(part, (geom, T), self._request)[0]:
                        return True
        for i, j in self._self_pairs:
            for a in placed[i]:
                for b in placed[j]:
                    if self._collide(a, b, self._request)[0]:
                        return True
        return False

    def is_free(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool: no non-allowed pair touches, for q (*batch, dof) (rad or m)."""
        q = self.model.check_configuration(q)
        poses = forward_kinematics(self.model, q, self.T_world_base).reshape(-1, self.model.n_links, 4, 4)
        free = np.array([not self._first_hit(self._placed(p)) for p in poses], dtype=bool)
        return free.reshape(q.shape[:-1])

    def collisions(self, q: np.ndarray) -> list[tuple[str, str, float]]:
        """All contacts of one configuration q (dof,): (link, other, penetration depth m >= 0).

        ``other`` is an obstacle name or a link name; each pair of geometries reports once.
        """
        q = self.model.check_configuration(q)
        placed = self._placed(forward_kinematics(self.model, q, self.T_world_base))
        names = self.model.link_names
        out: list[tuple[str, str, float]] = []
        for i in self._links:
            for part in placed[i]:
                for name, geom, T in self._obstacles:
                    hit, depth = self._collide(part, (geom, T), self._contact_request)
                    if hit:
                        out.append((names[i], name, depth))
        for i, j in self._self_pairs:
            for a in placed[i]:
                for b in placed[j]:
                    hit, depth = self._collide(a, b, self._contact_request)
                    if hit:
                        out.append((names[i], names[j], depth))
        return out

    def _distance(self, a, b) -> float:
        result = coal.DistanceResult()
        return float(coal.distance(a[0], a[1], b[0], b[1], self._distance_request, result))

    def min_distance(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) smallest distance (m) over all checked pairs; negative when penetrating
        (coal's signed distance; +inf when nothing is checked)."""
        q = self.model.check_configuration(q)
        poses = forward_kinematics(self.model, q, self.T_world_base).reshape(-1, self.model.n_links, 4, 4)
        out = np.full(len(poses), np.inf)
        for b, p in enumerate(poses):
            placed = self._placed(p)
            best = np.inf
            for i in self._links:
                for part in placed[i]:
                    for _, geom, T in self._obstacles:
                        best = min(best, self._distance(part, (geom, T)))
            for i, j in self._self_pairs:
                for a in placed[i]:
                    for c in placed[j]:
                        best = min(best, self._distance(a, c))
            out[b] = best
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
        q = self.model.check_configuration(q)
        placed = self._placed(forward_kinematics(self.model, q, self.T_world_base))
        names = self.model.link_names
        out: list[ClosestPair] = []
        for i in self._links:
            for name, geom, T in self._obstacles:
                best = None
                for part in placed[i]:
                    if np.isfinite(max_distance) and self._ball_distance(part, (geom, T)) > max_distance:
                        continue
                    result = coal.DistanceResult()
                    d = float(coal.distance(part[0], part[1], geom, T, self._distance_request, result))
                    if best is None or d < best.distance:
                        best = ClosestPair(names[i], name, d, np.array(result.getNearestPoint1(), dtype=float),
                                           np.array(result.getNearestPoint2(), dtype=float))
                if best is not None and best.distance <= max_distance:
                    out.append(best)
        return out

    def _ball_distance(self, part, other) -> float:
        """Lower bound (m) on the distance of a placed geometry to another: its bounding ball's distance."""
        geom, T = part
        if geom.aabb_radius < 0:
            geom.computeLocalAABB()  # once per geometry; coal leaves it unset until asked
        center = T.getRotation() @ geom.aabb_center + T.getTranslation()
        ball = (coal.Sphere(geom.aabb_radius), coal.Transform3s(np.eye(3), center))
        return self._distance(ball, other)

    def self_contacts(self, q: np.ndarray) -> np.ndarray:
        """(L, L) bool for one configuration q (dof,): which link pairs touch, over the pairs
        the checker's ACM does not skip (used by :func:`~prehensile.collision.acm.compute_acm`)."""
        q = self.model.check_configuration(q)
        placed = self._placed(forward_kinematics(self.model, q, self.T_world_base))
        contact = np.zeros((self.model.n_links, self.model.n_links), dtype=bool)
        for a, i in enumerate(self._links):
            for j in self._links[a + 1:]:
                if self.acm[i, j]:
                    continue
                hit = any(self._collide(x, y, self._request)[0] for x in placed[i] for y in placed[j])
                contact[i, j] = contact[j, i] = hit
        return contact
