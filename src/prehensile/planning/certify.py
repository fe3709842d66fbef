"""Exact certification of paths on the true geometry (coal), with per-pair free bubbles.

A path is certified when every configuration on it (straight segments between waypoints) is
collision-free for the exact collision geometry, up to the usual discrete fallback: where a
pair of bodies is closer than ``resolution``, it is checked at configurations no more than
``resolution`` apart in its own motion bound.

Free bubbles (Quinlan 1995; Vahrenkamp 2011 C.2). For a pair (a robot part and an obstacle,
or two parts on different links) with exact distance d at some configuration, and a weight row
W (:func:`~prehensile.planning.context.motion_weights`, built here from balls enclosing the
exact geometry) bounding their relative motion by ``W @ |dq|``, the pair cannot touch while
its accumulated motion along the path stays below d. Self pairs need no halving of d: each
link moves (in the frame of their deepest common ancestor) only through the joints below that
ancestor on its own side, so W already bounds the *relative* motion of the two (the two sides
use disjoint joints; shared joints move both rigidly). Every pair therefore carries its own
"safe until" arc length and is measured again only when the walk along the path reaches it;
far pairs are measured once per path.

Distances come first from convex bounds (the convex hull of a mesh, the primitive itself),
which contain the geometry, so their distance is a lower bound of the exact one. Only when a
hull overlaps does the exact mesh decide (``coal.collide``, then the exact distance for the
bubble). Meshes are surfaces, as in :class:`~prehensile.collision.exact.ExactChecker`.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Sequence

import coal
import numpy as np

from prehensile.collision.exact import coal_geometry
from prehensile.collision.world import Obstacle
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.robot_model import RobotModel
from prehensile.planning.context import PlanningContext, motion_weights

_TOLERANCE = 1e-6  # m taken off every coal distance (GJK converges to about this)


@dataclass(frozen=True)
class CertifyReport:
    """Outcome of :func:`certify_path`.

    Attributes:
        ok: every configuration checked is within the limits and collision-free (exact).
        first_bad_segment: index of the first segment (waypoint i to i + 1) that collides or
            leaves the limits, -1 if ok (a colliding waypoint i > 0 reports segment i - 1).
        configurations_checked: configurations at which some pair was measured.
        distance_queries: coal distance and collision queries.
        min_distance: smallest lower bound of the exact clearance seen (m); <= 0 on a collision.
        time_s: wall time (s).
    """

    ok: bool
    first_bad_segment: int = -1
    configurations_checked: int = 0
    distance_queries: int = 0
    min_distance: float = np.inf
    time_s: float = 0.0


def _enclosing_ball(geometry: Geometry) -> tuple[np.ndarray, float]:
    """Centre (3,) in the link frame and radius (m) of a ball containing the geometry."""
    shape, T = geometry.shape, np.asarray(geometry.T_link_geom, dtype=float)
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
        raise TypeError(f"unsupported shape {type(shape).__name__}")
    return T[:3, 3].copy(), radius


def _link_balls(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    """Per link a ball (centre (L, 3), radius (L,)) containing all its collision geometry;
    radius -1 for links without geometry."""
    centers, radii = np.zeros((model.n_links, 3)), np.full(model.n_links, -1.0)
    for link, geometries in enumerate(model.collisions):
        balls = [_enclosing_ball(g) for g in geometries]
        if balls:
            c = np.array([b[0] for b in balls])
            centers[link] = 0.5 * (c.min(axis=0) + c.max(axis=0))
            radii[link] = max(float(np.linalg.norm(b[0] - centers[link])) + b[1] for b in balls)
    return centers, radii


def _convex_bound(shape, exact):
    """A convex coal geometry containing ``shape``: its convex hull for a mesh (the exact
    geometry if qhull fails), the primitive itself otherwise."""
    if not isinstance(shape, Mesh):
        return exact
    points = coal.StdVec_Vec3s()
    for p in np.asarray(shape.trimesh.vertices, dtype=float):
        points.append(p)
    try:
        return coal.Convex.convexHull(points, False, "")
    except Exception:  # flat or degenerate vertex set
        return exact


def _transform(T: np.ndarray):
    return coal.Transform3s(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))


class ExactCertifier:
    """Certifies paths of one robot (objects attached as links) in one world; see the module doc.

    Args:
        model: the robot (with attached objects as links, see
            :func:`~prehensile.planning.context.attach_objects`).
        obstacles: shapes fixed in the world.
        T_world_base: (4, 4) pose of the robot root.
        acm: (L, L) allowed-collision matrix (True = pair not checked).
    """

    def __init__(self, model: RobotModel, obstacles: Sequence[Obstacle], T_world_base: np.ndarray,
                 acm: np.ndarray) -> None:
        self.model = model
        self.T_world_base = np.asarray(T_world_base, dtype=float)
        self._parts = []  # (link, T_link_geom, exact, convex bound, exact is convex)
        for link, geometries in enumerate(model.collisions):
            for g in geometries:
                exact = coal_geometry(g.shape)
                self._parts.append((link, np.asarray(g.T_link_geom, dtype=float), exact,
                                    _convex_bound(g.shape, exact), not isinstance(g.shape, Mesh)))
        self._obstacles = []
        for o in obstacles:
            exact = coal_geometry(o.shape)
            self._obstacles.append((_transform(np.asarray(o.T_world_shape, dtype=float)), exact,
                                    _convex_bound(o.shape, exact), not isinstance(o.shape, Mesh)))
        pairs, links = [], []  # (part, obstacle or -1, other part or -1); (link a, link b or -1)
        for a, (la, *_) in enumerate(self._parts):
            for o in range(len(self._obstacles)):
                pairs.append((a, o, -1)), links.append((la, -1))
            for b in range(a + 1, len(self._parts)):
                lb = self._parts[b][0]
                if la != lb and not acm[la, lb]:
                    pairs.append((a, -1, b)), links.append((la, lb))
        self._pairs = pairs
        centers, radii = _link_balls(model)
        self._weights = motion_weights(model, centers, radii, np.array(links, dtype=np.int64).reshape(-1, 2))
        # resolution metric: how far any part can move per unit of each variable
        self._reach = np.max(motion_weights(model, centers, radii, np.column_stack(
            [np.arange(model.n_links), np.full(model.n_links, -1)])), axis=0)
        self._tf = [coal.Transform3s() for _ in self._parts]
        self._request = coal.DistanceRequest()
        self._collision_request = coal.CollisionRequest()

    def _lower_bound(self, p: int, placed: list) -> tuple[float, int]:
        """(lower bound of the exact distance of pair p (<= 0 only on an exact collision),
        queries used) with the parts placed at the current configuration."""
        a, o, b = self._pairs[p]
        _, _, exact_a, bound_a, convex_a = self._parts[a]
        Ta = placed[a]
        if o >= 0:
            Tb, exact_b, bound_b, convex_b = self._obstacles[o]
        else:
            Tb, (_, _, exact_b, bound_b, convex_b) = placed[b], self._parts[b]
        d = coal.distance(bound_a, Ta, bound_b, Tb, self._request, coal.DistanceResult()) - _TOLERANCE
        if d > 0.0 or (convex_a and convex_b):
            return d, 1
        if coal.collide(exact_a, Ta, exact_b, Tb, self._collision_request, coal.CollisionResult()) > 0:
            return -1.0, 2
        return max(coal.distance(exact_a, Ta, exact_b, Tb, self._request, coal.DistanceResult()) - _TOLERANCE, 0.0), 3

    def _place(self, q: np.ndarray, parts: np.ndarray) -> list:
        """Transforms of the parts used by the pairs ``parts`` at configuration q."""
        poses = forward_kinematics(self.model, q, self.T_world_base)
        placed = [None] * len(self._parts)
        for k in parts:
            link, T_link_geom = self._parts[k][:2]
            T = poses[link] @ T_link_geom
            self._tf[k].setTransform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
            placed[k] = self._tf[k]
        return placed

    def certify(self, path: np.ndarray, resolution: float) -> CertifyReport:
        """Certify the piecewise-linear path (N, dof); see :func:`certify_path`."""
        start = time.perf_counter()
        path = self.model.check_configuration(path, "path").reshape(-1, self.model.dof)
        inside = self.model.within_limits(path)
        if not inside.all():
            bad = int(np.argmin(inside))
            return CertifyReport(False, max(bad - 1, 0), time_s=time.perf_counter() - start)
        n = len(path)
        delta = np.abs(np.diff(path, axis=0))
        seg = np.zeros((len(self._pairs), n))  # per pair, motion bound of each segment (last: 0)
        seg[:, :-1] = (self._weights @ delta.T) if n > 1 else 0.0
        arc = np.concatenate([np.zeros((len(self._pairs), 1)), np.cumsum(seg[:, :-1], axis=1)], axis=1)
        step = np.append(delta @ self._reach, 0.0)  # farthest any part moves on each segment
        safe = np.full(len(self._pairs), -np.inf)  # a pair is measured again once its arc reaches this
        i, t, checked, queries, lowest = 0, 0.0, 0, 0, np.inf
        while True:
            here = arc[:, i] + t * seg[:, i]
            due = np.flatnonzero(here >= safe - 1e-12)  # rounding: a pair reached exactly is due
            if len(due):
                q = path[i] + t * (path[i + 1] - path[i]) if t > 0.0 else path[i]
                used = {self._pairs[p][0] for p in due} | ({self._pairs[p][2] for p in due} - {-1})
                placed = self._place(q, np.fromiter(used, dtype=np.int64))
                checked += 1
                for p in due:
                    d, used_queries = self._lower_bound(int(p), placed)
                    queries += used_queries
                    lowest = min(lowest, d)
                    if d < 0.0:
                        bad = i - 1 if (t == 0.0 and i > 0) else i
                        return CertifyReport(False, bad, checked, queries, lowest, time.perf_counter() - start)
                    safe[p] = here[p] + d
            if i == n - 1:
                return CertifyReport(True, -1, checked, queries, lowest, time.perf_counter() - start)
            moving = seg[:, i] > 0.0
            expire = (safe[moving] - arc[moving, i]) / seg[moving, i]
            t_next = max(np.min(expire, initial=np.inf), t + resolution / step[i] if step[i] > 0 else np.inf)
            if t_next >= 1.0:
                i, t = i + 1, 0.0
            else:
                t = t_next


def certify_path(ctx: PlanningContext, path: np.ndarray, resolution: float | None = None) -> CertifyReport:
    """Check a path (N, dof) of full configurations against the exact geometry (coal).

    Waypoints must lie within the joint limits; every segment is proven free by per-pair
    free bubbles and sampled at ``resolution`` (m, default ``ctx.certify_resolution``) where
    a pair is closer than that (see the module doc). Attached objects are included.
    """
    return ctx.certifier.certify(path, ctx.certify_resolution if resolution is None else float(resolution))
