"""Exact certification of paths on the true geometry (coal), with per-pair free bubbles.

A path is certified when every configuration on it (straight segments between waypoints) is
collision-free for the exact collision geometry, up to the usual discrete fallback: the walk
along the path never steps farther than ``resolution`` (m, the most any part can move), so
where bodies are closer than that they are checked at configurations that far apart. A
contact shorter than that along the path can pass: two box edges grazing each other at 45
degrees passed the 2 mm default with up to 0.6 mm of overlap, a 0.5 mm plate through a 0.5 mm
wall passed. A finer ``certify_resolution`` of the context narrows this (at 0.5 mm each of
those box-edge overlaps, down to 0.14 mm deep, was caught).

Free bubbles (Quinlan 1995; Vahrenkamp 2011 C.2). For a pair (a robot part and an obstacle,
or two parts on different links) with exact distance d at some configuration, and a weight row
W (:func:`~prehensile.planning.context.motion_weights`, built here from balls enclosing the
exact geometry) bounding their relative motion by ``W @ |dq|``, the pair cannot touch while
its accumulated motion along the path stays below d. Self pairs need no halving of d: each
link moves (in the frame of their deepest common ancestor) only through the joints below that
ancestor on its own side, so W already bounds the *relative* motion of the two (the two sides
use disjoint joints; shared joints move both rigidly). Every pair therefore carries its own
"safe until" arc length; the walk stops where the first pair runs out and measures it again,
together with every pair that has used up half of its bubble (fewer stops). Far pairs are
measured a few times per path.

Distances are lower bounds, each from the cheapest source that suffices: enclosing balls of
the parts against the obstacles' bounding boxes (or against each other) while they are
farther apart than 5 cm; then, with a covering sphere model (every triangle of a link inside
one of its balls, :attr:`~prehensile.collision.spheres.SphereModel.covering`), the distance
of the link's balls to the obstacle's shape (or to the other link's balls) while they do not
touch; else coal on convex bounds (the convex hull of a mesh, the primitive itself),
which contain the geometry; and only where a hull overlaps, the exact mesh
(``coal.collide``, then the exact distance for the bubble). Every bound comes from shapes that
contain the geometry, and a collision is only ever declared by the exact geometry. Along the
path meshes are surfaces (a body entering a mesh crosses it); at the path's start a geometry
wholly inside a closed mesh collides, as in :class:`~prehensile.collision.exact.ExactChecker`
(:class:`_Nesting`, for every pair with a closed mesh).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, replace
from typing import Callable, Sequence
from weakref import WeakKeyDictionary

import coal
import numpy as np
from numba import njit

from prehensile.clock import clock
from prehensile.collision import sphere_kernels as SK
from prehensile.collision.exact import ObstaclePart, contains, obstacle_parts, robot_parts
from prehensile.collision.sphere_checker import obstacle_arrays
from prehensile.collision.spheres import SphereModel
from prehensile.collision.world import Obstacle
from prehensile.errors import PrehensileError
from prehensile.kinematics.kernels import fk_into
from prehensile.model.robot_model import RobotModel
from prehensile.planning.context import PlanningContext, ball_joint_weights, check_resolution, motion_weights

log = logging.getLogger(__name__)

_TOLERANCE = 1e-6  # m taken off every coal distance (GJK converges to about this)
ESCAPE_ATTEMPTS = 64  # escape directions tried by default (drawn this many at a time until a deadline)
_FAR = 0.05  # m: pairs whose enclosing balls are this far apart are not measured exactly
_COVER_NEAR = 0.0  # m: pairs whose covering balls are apart are not measured exactly


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
        time_s: wall time (s) without numba compilation (:func:`prehensile.clock.clock`).
        colliding_links: the robot link(s) of the first colliding pair (two for a self
            collision), empty if ok or if a waypoint left the limits.
    """

    ok: bool
    first_bad_segment: int = -1
    configurations_checked: int = 0
    distance_queries: int = 0
    min_distance: float = np.inf
    time_s: float = 0.0
    colliding_links: tuple[str, ...] = ()


_LINK_WEIGHTS: WeakKeyDictionary = WeakKeyDictionary()


def _link_weights(model: RobotModel) -> np.ndarray:
    """(L, L) :func:`~prehensile.planning.context.ball_joint_weights` of a ball per link that
    contains the enclosing balls of its parts (:func:`~prehensile.collision.exact.robot_parts`;
    rows 0 for links without geometry). Prepared once per model, like the parts: they do not
    depend on the scene, and computing them took half of a context's construction."""
    if model not in _LINK_WEIGHTS:
        parts = robot_parts(model)
        links = sorted({p.link for p in parts})
        centers, radii = np.zeros((len(links), 3)), np.zeros(len(links))
        for row, link in enumerate(links):
            balls = [(p.center, p.radius) for p in parts if p.link == link]
            c = np.array([center for center, _ in balls])
            centers[row] = 0.5 * (c.min(axis=0) + c.max(axis=0))
            radii[row] = max(float(np.linalg.norm(center - centers[row])) + radius for center, radius in balls)
        weights = np.zeros((model.n_links, model.n_links))
        weights[links] = ball_joint_weights(model, np.array(links, dtype=np.int64), centers, radii)
        _LINK_WEIGHTS[model] = weights
    return _LINK_WEIGHTS[model]


class ExactCertifier:
    """Certifies paths of one robot (objects attached as links) in one world; see the module doc.

    Args:
        model: the robot (with attached objects as links, see
            :func:`~prehensile.collision.attached.attach_objects`).
        obstacles: shapes fixed in the world.
        T_world_base: (4, 4) pose of the robot root.
        acm: (L, L) allowed-collision matrix (True = pair not checked).
        cover: balls covering every link's geometry (``covering``) for cheap lower bounds.
        parts: the obstacles' coal geometry if already built
            (:attr:`~prehensile.collision.exact.ExactChecker.obstacle_parts`).
    """

    def __init__(self, model: RobotModel, obstacles: Sequence[Obstacle], T_world_base: np.ndarray,
                 acm: np.ndarray, cover: SphereModel | None = None,
                 parts: tuple[ObstaclePart, ...] | None = None) -> None:
        self.model = model
        self.T_world_base = np.asarray(T_world_base, dtype=float)
        self._parts = robot_parts(model)
        parts = obstacle_parts(obstacles) if parts is None else parts
        if len(parts) != len(obstacles):
            raise PrehensileError(f"ExactCertifier: {len(parts)} obstacle parts for {len(obstacles)} obstacles")
        self._obstacles = parts
        boxes = []  # per obstacle: world AABB (min xyz, max xyz)
        for o in parts:
            o.exact.computeLocalAABB()
            T, lo, hi = o.T_world_shape, np.asarray(o.exact.aabb_local.min_), np.asarray(o.exact.aabb_local.max_)
            center, half = T[:3, :3] @ (0.5 * (lo + hi)) + T[:3, 3], np.abs(T[:3, :3]) @ (0.5 * (hi - lo))
            boxes.append(np.concatenate([center - half, center + half]))
        pairs, links = [], []  # (part, obstacle or -1, other part or -1); (link a, link b or -1)
        for a, part in enumerate(self._parts):
            la = part.link
            for o in range(len(self._obstacles)):
                pairs.append((a, o, -1)), links.append((la, -1))
            for b in range(a + 1, len(self._parts)):
                lb = self._parts[b].link
                if la != lb and not acm[la, lb]:
                    pairs.append((a, -1, b)), links.append((la, lb))
        self._pairs = pairs
        table = np.array(pairs, dtype=np.int64).reshape(-1, 3)
        self._pair_a, self._pair_o, self._pair_b = table[:, 0], table[:, 1], table[:, 2]
        self._ball_center = np.array([p.center for p in self._parts]).reshape(-1, 3)
        self._ball_radius = np.array([p.radius for p in self._parts])
        self._part_link = np.array([p.link for p in self._parts], dtype=np.int64)
        self._boxes = np.array(boxes).reshape(-1, 6)
        self._nesting = _Nesting(self._parts, parts, self._boxes, table)
        link_weights = _link_weights(model)
        self._weights = motion_weights(model, link_weights, np.array(links, dtype=np.int64).reshape(-1, 2))
        # resolution metric: how far any part can move per unit of each variable
        self._reach = np.max(motion_weights(model, link_weights, np.column_stack(
            [np.arange(model.n_links), np.full(model.n_links, -1)])), axis=0)
        self._cover = _cover_arrays(cover, model.n_links, obstacles)
        self._near = _FAR if cover is None else _COVER_NEAR
        self._tf = [coal.Transform3s() for _ in self._parts]
        self._request = coal.DistanceRequest()
        self._collision_request = coal.CollisionRequest()

    def _lower_bound(self, p: int, placed: list) -> tuple[float, int]:
        """(lower bound of the exact distance of pair p (<= 0 only on an exact collision),
        queries used) with the parts placed at the current configuration."""
        a, o, b = self._pairs[p]
        part_a, Ta = self._parts[a], placed[a]
        exact_a, bound_a, convex_a = part_a.exact, part_a.bound, part_a.convex
        if o >= 0:
            obstacle = self._obstacles[o]
            Tb, exact_b, bound_b, convex_b = obstacle.transform, obstacle.exact, obstacle.bound, obstacle.convex
        else:
            part_b, Tb = self._parts[b], placed[b]
            exact_b, bound_b, convex_b = part_b.exact, part_b.bound, part_b.convex
        d = coal.distance(bound_a, Ta, bound_b, Tb, self._request, coal.DistanceResult()) - _TOLERANCE
        if d > 0.0 or (convex_a and convex_b):
            return d, 1
        if coal.collide(exact_a, Ta, exact_b, Tb, self._collision_request, coal.CollisionResult()) > 0:
            return -1.0, 2
        return max(coal.distance(exact_a, Ta, exact_b, Tb, self._request, coal.DistanceResult()) - _TOLERANCE, 0.0), 3

    def nested(self, q: np.ndarray) -> bool:
        """Whether at q (dof,) some geometry lies wholly inside a closed mesh it may not touch
        (no distance shows it; see :class:`_Nesting`)."""
        poses = np.empty((self.model.n_links, 4, 4))
        fk_into(q, self.T_world_base, self.model.joint_table, poses)
        return self._nesting.first_pair(poses) >= 0

    def _links_of(self, p: int) -> tuple[str, ...]:
        """Names of the robot links in pair p."""
        a, _, b = self._pairs[p]
        return tuple(self.model.link_names[self._parts[k].link] for k in (a, b) if k >= 0)

    def _place(self, poses: np.ndarray, parts) -> list:
        """coal transforms of ``parts`` with the link poses (L, 4, 4)."""
        placed = [None] * len(self._parts)
        for k in parts:
            T = poses[self._parts[k].link] @ self._parts[k].T_link_geom
            self._tf[k].setTransform(np.ascontiguousarray(T[:3, :3]), np.ascontiguousarray(T[:3, 3]))
            placed[k] = self._tf[k]
        return placed

    def certify(self, path: np.ndarray, resolution: float) -> CertifyReport:
        """Certify the piecewise-linear path (N, dof); see :func:`certify_path`."""
        start = clock()
        path = np.ascontiguousarray(self.model.check_configuration(path, "path").reshape(-1, self.model.dof))
        inside = self.model.within_limits(path)
        if not inside.all():
            bad = int(np.argmin(inside))
            return CertifyReport(False, max(bad - 1, 0), time_s=clock() - start)
        n, count = len(path), len(self._pairs)
        delta = np.abs(np.diff(path, axis=0))
        seg = np.zeros((count, n))  # per pair, motion bound of each segment (last: 0)
        seg[:, :-1] = (self._weights @ delta.T) if n > 1 else 0.0
        arc = np.ascontiguousarray(np.concatenate([np.zeros((count, 1)), np.cumsum(seg[:, :-1], axis=1)], axis=1))
        walk = (path, arc, seg, np.append(delta @ self._reach, 0.0), np.full(count, -np.inf), np.zeros(count),
                float(resolution), np.zeros(3), np.empty((self.model.n_links, 4, 4)), self.T_world_base,
                self.model.joint_table, self._pair_a, self._pair_o, self._pair_b, self._part_link, self._ball_center,
                self._ball_radius, self._boxes, *self._cover, self._near, np.array([0.0, np.inf]),
                np.empty(count, dtype=np.int64), np.empty(count), np.empty(count), np.empty(self.model.dof))
        safe, early, position, poses, stats = walk[4], walk[5], walk[7], walk[8], walk[-5]
        due, here, bound = walk[-4], walk[-3], walk[-2]
        fk_into(path[0], self.T_world_base, self.model.joint_table, poses)
        nested = self._nesting.first_pair(poses)
        if nested >= 0:
            return CertifyReport(False, 0, min_distance=0.0, time_s=clock() - start,
                                 colliding_links=self._links_of(nested))
        queries = 0
        while True:
            m = _next_due(*walk)
            if m < 0:
                return CertifyReport(True, -1, int(stats[0]), queries, float(stats[1]), clock() - start)
            d = bound[:m].copy()
            near = np.flatnonzero(d < self._near)  # far pairs keep the ball bound; the near ones ask coal
            close = due[near]
            placed = self._place(poses, set(self._pair_a[close]) | (set(self._pair_b[close]) - {-1}))
            for k in near:
                d[k], used_queries = self._lower_bound(int(due[k]), placed)
                queries += used_queries
                if d[k] < 0.0:
                    i, t = int(position[0]), position[1]
                    bad = i - 1 if (t == 0.0 and i > 0) else i
                    return CertifyReport(False, bad, int(stats[0]), queries, float(d[k]), clock() - start,
                                         self._links_of(int(due[k])))
            stats[1] = min(stats[1], float(d.min()))
            safe[due[:m]], early[due[:m]] = here[:m] + d, 0.5 * d + 1e-12  # (rounding: reached exactly is due)


class _Nesting:
    """Which pair of a certifier (robot parts against obstacles or each other) has a geometry
    with a point inside the other's closed mesh: they overlap, and if no surfaces meet (one
    wholly inside the other) no distance along the path shows it. Tested at a path's start, one
    point per connected piece of each geometry; from there on, getting inside means crossing a
    surface.

    Args:
        parts: the robot's parts; obstacles: the obstacles' parts; boxes: (O, 6) their world
            AABBs (min xyz, max xyz); pairs: (K, 3) per pair (part, obstacle or -1, part or -1).
    """

    def __init__(self, parts, obstacles, boxes: np.ndarray, pairs: np.ndarray) -> None:
        n = len(parts)  # geometries: the parts, then the obstacles
        self._closed = [p.closed for p in parts] + [o.closed for o in obstacles]
        anchors = [p.anchors for p in parts] + [o.anchors for o in obstacles]  # a point per connected piece
        self._anchor = np.concatenate(anchors).reshape(-1, 3)  # (A, 3) in their geometries' frames
        self._owner = np.repeat(np.arange(len(anchors)), [len(a) for a in anchors])  # (A,) their geometries
        self._part_link = np.array([p.link for p in parts], dtype=np.int64)
        self._part_geom = np.array([p.T_link_geom for p in parts]).reshape(-1, 4, 4)
        self._part_center = np.array([p.center for p in parts]).reshape(-1, 3)
        self._obstacle_pose = np.array([o.T_world_shape for o in obstacles]).reshape(-1, 4, 4)
        self._obstacle_center = 0.5 * (boxes[:, :3] + boxes[:, 3:])
        self._radius = np.concatenate([[p.radius for p in parts], 0.5 * np.linalg.norm(boxes[:, 3:] - boxes[:, :3],
                                                                                       axis=1)])
        points = np.split(np.arange(len(self._owner)), np.cumsum([len(a) for a in anchors])[:-1])  # per geometry
        tests = []  # (outer geometry, closed; anchor of the inner geometry; pair)
        for k, (a, o, b) in enumerate(pairs):
            other = n + o if o >= 0 else b
            tests += [(outer, point, k) for outer, inner in ((a, other), (other, a)) if self._closed[outer] is not None
                      for point in points[inner]]
        self._outer, self._point, self._pair = np.array(tests, dtype=np.int64).reshape(-1, 3).T

    def first_pair(self, poses: np.ndarray) -> int:
        """The first pair nested with the links at ``poses`` (L, 4, 4), or -1."""
        if not len(self._pair):
            return -1
        link = poses[self._part_link]
        T = np.concatenate([link @ self._part_geom, self._obstacle_pose])  # (G, 4, 4) geometry poses
        center = np.concatenate([np.einsum("gij,gj->gi", link[:, :3, :3], self._part_center) + link[:, :3, 3],
                                 self._obstacle_center])
        owner = T[self._owner]
        anchor = np.einsum("aij,aj->ai", owner[:, :3, :3], self._anchor) + owner[:, :3, 3]
        near = np.linalg.norm(anchor[self._point] - center[self._outer], axis=1) <= self._radius[self._outer]
        for outer, point, pair in zip(self._outer[near], self._point[near], self._pair[near]):
            if contains(self._closed[outer], T[outer], self._anchor[point, None], T[self._owner[point]]):
                return int(pair)
        return -1


@njit(cache=True, _nrt=False)
def _next_due(path, arc, seg, step, safe, early, res, position, poses, T_world_base, table, pair_a, pair_o, pair_b,
              part_link, ball_center, ball_radius, boxes, lrange, ccenter, cradius, otype, opose, oparam, orange,
              near, stats, due, here, bound, q):
    """Walk to the next configuration on the path where some due pair is nearer than ``near``
    (m); returns how many pairs are due there (-1 at the end of the path).

    A pair p is due once its arc (``arc[p, i] + t * seg[p, i]`` on segment i at t) reaches
    ``safe[p] - early[p]``. ``position`` = (segment, t, 1 if that configuration is done): the
    walk moves on to the nearest expiry of a pair, but at least ``res / step[i]`` and at most to
    the next waypoint. There it fills ``due[:m]``, ``here[:m]`` (their arcs), ``poses`` (link
    poses, via FK) and ``bound[:m]`` (lower bounds of their distances from enclosing balls:
    part ball vs obstacle AABB, or part ball vs part ball; closer than ``_FAR``, the covering
    balls' distance if that is larger, see :func:`_cover_distance`). Configurations where every
    due pair is at least ``near`` apart renew those pairs' bubbles here and the walk goes on.
    ``stats`` = (configurations measured, least bound seen) is updated.
    """
    n, count = path.shape[0], arc.shape[0]
    i, t = int(position[0]), position[1]
    while True:
        while True:
            if position[2] != 0.0:  # done here: move on
                if i == n - 1:
                    return -1
                t_next = t + res / step[i] if step[i] > 0.0 else np.inf
                expire = np.inf
                for p in range(count):
                    if seg[p, i] > 0.0:
                        expire = min(expire, (safe[p] - 1e-12 - arc[p, i]) / seg[p, i])
                t_next = max(t_next, expire)
                if t_next >= 1.0:
                    i, t = i + 1, 0.0
                else:
                    t = t_next
            position[0], position[1], position[2] = i, t, 1.0
            m = 0
            for p in range(count):
                at = arc[p, i] + t * seg[p, i]
                if at >= safe[p] - early[p]:
                    due[m], here[m] = p, at
                    m += 1
            if m > 0:
                break
        for k in range(q.shape[0]):
            q[k] = path[i, k] + t * (path[i + 1, k] - path[i, k]) if t > 0.0 else path[i, k]
        fk_into(q, T_world_base, table, poses)
        for k in range(m):
            p = due[k]
            a, o, b = pair_a[p], pair_o[p], pair_b[p]
            gap = 0.0
            for x in range(3):
                ca = _place(poses[part_link[a]], ball_center[a], x)
                if o >= 0:
                    e = max(boxes[o, x] - ca, ca - boxes[o, 3 + x], 0.0)
                else:
                    e = ca - _place(poses[part_link[b]], ball_center[b], x)
                gap += e * e
            bound[k] = np.sqrt(gap) - ball_radius[a] - (ball_radius[b] if o < 0 else 0.0)
            if bound[k] < _FAR:
                lb = part_link[b] if o < 0 else -1
                bound[k] = max(bound[k], _cover_distance(poses, part_link[a], lb, o, lrange, ccenter, cradius, otype,
                                                         opose, oparam, orange))
        stats[0] += 1
        for k in range(m):
            if bound[k] < near:
                return m
        for k in range(m):  # every due pair is far: renew its bubble here (rounding: reached exactly is due)
            safe[due[k]], early[due[k]] = here[k] + bound[k], 0.5 * bound[k] + 1e-12
            stats[1] = min(stats[1], bound[k])


@njit(cache=True, _nrt=False)
def _cover_distance(poses, la, lb, o, lrange, ccenter, cradius, otype, opose, oparam, orange):
    """Lower bound (m) of the distance of link la's geometry to obstacle o (o >= 0), or to link
    lb's geometry: the least distance between their covering balls (link balls ``lrange``
    (L, 2) into ``ccenter`` (S, 3), ``cradius`` (S,); obstacle o's shapes ``orange`` (O, 2)
    into the kernel arrays ``otype``, ``opose``, ``oparam``); -inf without covering balls."""
    if lrange[la, 1] == lrange[la, 0] or (o < 0 and lrange[lb, 1] == lrange[lb, 0]):
        return -np.inf
    best = np.inf
    for s in range(lrange[la, 0], lrange[la, 1]):
        x, y, z = _place(poses[la], ccenter[s], 0), _place(poses[la], ccenter[s], 1), _place(poses[la], ccenter[s], 2)
        if o >= 0:
            for e in range(orange[o, 0], orange[o, 1]):
                d2, grow = SK._core_distance2(otype, opose, oparam, e, x, y, z)
                best = min(best, np.sqrt(d2) - grow - cradius[s])
        else:
            for t in range(lrange[lb, 0], lrange[lb, 1]):
                dx, dy, dz = x - _place(poses[lb], ccenter[t], 0), y - _place(poses[lb], ccenter[t], 1), \
                    z - _place(poses[lb], ccenter[t], 2)
                best = min(best, np.sqrt(dx * dx + dy * dy + dz * dz) - cradius[s] - cradius[t])
    return best


def _cover_arrays(cover: SphereModel | None, n_links: int, obstacles: Sequence[Obstacle]) -> tuple:
    """Arrays of :func:`_cover_distance`: the covering balls of the n_links links and the
    obstacles' kernel shapes (a mesh obstacle becomes balls covering it); no balls without a cover."""
    if cover is None:
        lrange, ccenter, cradius = np.zeros((n_links, 2), dtype=np.int64), np.zeros((0, 3)), np.zeros(0)
    else:
        lrange, ccenter, cradius = cover.link_ranges(), np.ascontiguousarray(cover.centers), cover.radii
    shapes = [obstacle_arrays([o]) for o in obstacles]
    counts = np.array([len(a["otype"]) for a in shapes], dtype=np.int64)
    orange = np.column_stack([np.cumsum(counts) - counts, np.cumsum(counts)]).reshape(-1, 2)
    joined = {key: np.concatenate([a[key] for a in shapes]) if shapes else empty
              for key, empty in (("otype", np.zeros(0, np.int64)), ("opose", np.zeros((0, 3, 4))),
                                 ("oparam", np.zeros((0, 3))))}
    return lrange, ccenter, cradius, joined["otype"], np.ascontiguousarray(joined["opose"]), joined["oparam"], orange


@njit(cache=True, inline="always")
def _place(T, c, x):
    """Coordinate x of the point T (4, 4) @ c (3,)."""
    return T[x, 0] * c[0] + T[x, 1] * c[1] + T[x, 2] * c[2] + T[x, 3]


def certify_path(ctx: PlanningContext, path: np.ndarray, resolution: float | None = None) -> CertifyReport:
    """Check a path (N, dof) of full configurations against the exact geometry (coal).

    Waypoints must lie within the joint limits; every segment is proven free by per-pair
    free bubbles and sampled at ``resolution`` (m, default ``ctx.certify_resolution``) where
    a pair is closer than that (see the module doc). Attached objects are included.
    """
    start = clock()
    path = ctx.model.check_configuration(path, "path")
    if path.ndim != 2 or len(path) < 1:
        raise PrehensileError(f"certify_path: path must have shape (N >= 1, {ctx.model.dof}), got {path.shape}")
    res = ctx.certify_resolution if resolution is None else check_resolution(resolution, "certify_path: resolution")
    return replace(ctx.certifier.certify(path, res), time_s=clock() - start)  # the whole call


def refine_after_failure(ctx: PlanningContext, context: PlanningContext, links: frozenset, resolution: float,
                         report: CertifyReport, last: bool) -> tuple[PlanningContext, frozenset, float]:
    """Where to try again after a path made in ``context`` (``ctx`` with covering balls on
    ``links``, or ``ctx`` itself) at ``resolution`` (m) failed certification (``report``):
    (context, links, resolution) with covering balls also on the links that collided, on every
    link with balls if ``last`` (each failure may show one more link), else, without a cover
    (:meth:`PlanningContext.refined`) or with nothing left to cover, at half the resolution."""
    wider = set(links) | set(report.colliding_links)
    if last:
        balls = ctx.sphere_model
        wider |= {balls.link_names[i] for i in np.unique(balls.sphere_link)}
    finer = ctx.refined(wider)
    if finer is None or finer is context:
        return context, links, 0.5 * resolution
    return finer, frozenset(wider), resolution


def rework_certified(ctx: PlanningContext, path: np.ndarray, rework: Callable[[PlanningContext, float], np.ndarray],
                     resolution: float, retries: int,
                     who: str | None = None) -> tuple[np.ndarray, CertifyReport, float]:
    """The first result of ``rework(context, resolution)`` (a changed copy of ``path`` (N, dof),
    made with the sphere checks of that context at that resolution (m)) that passes
    :func:`certify_path`; after each failure it is made again as :func:`refine_after_failure`
    says, at most ``retries`` times, and then ``path`` itself is returned. Balls that do not
    cover the geometry (a spherized URDF) let a shortcut or a band pass where the geometry
    collides; this keeps a certified path certified. If ``who`` is given, returning a ``path``
    that fails the certification itself is logged as a warning naming ``who``.

    Returns:
        (path, its :class:`CertifyReport`, time (s) spent certifying).
    """
    context, links, spent = ctx, frozenset(), 0.0
    for attempt in range(retries + 1):
        candidate = rework(context, resolution)
        report = certify_path(context, candidate)
        spent += report.time_s
        if report.ok:
            return candidate, report, spent
        if candidate is path or attempt == retries:
            break
        context, links, resolution = refine_after_failure(ctx, context, links, resolution, report,
                                                          last=attempt + 1 == retries)
    if candidate is not path:
        log.info("none of %d reworked paths passed the exact certification; keeping the path as it was", attempt + 1)
        report = certify_path(ctx, path)
        spent += report.time_s
    if who is not None and not report.ok:
        log.warning("%s: the input path fails the exact certification (segment %d: %s) and is returned unchanged",
                    who, report.first_bad_segment, _failure(report))
    return path, report, spent


def _failure(report: CertifyReport) -> str:
    """What made a failed certification fail, in words."""
    links = report.colliding_links
    return ("it leaves the joint limits" if not links else f"link {links[0]} hits an obstacle" if len(links) == 1
            else f"links {links[0]} and {links[1]} collide")


def check_valid_path(ctx: PlanningContext, path: np.ndarray, who: str) -> np.ndarray:
    """``path`` (N >= 1, dof) as float64 if it is a valid input path for ``ctx``; else a
    PrehensileError naming ``who`` and what is wrong.

    Valid: finite, the joints ``ctx`` does not plan constant, and every edge free on the
    sphere model, or (where the balls reject it: an end in contact range) certified on the
    exact geometry (:func:`certify_path`).
    """
    path = ctx.model.check_configuration(path, f"{who}: path")
    if path.ndim != 2 or len(path) < 1:
        raise PrehensileError(f"{who}: path must have shape (N >= 1, {ctx.model.dof}), got {path.shape}")
    fixed = ctx.space.fixed
    moved = fixed[np.any(np.abs(path[:, fixed] - path[0, fixed]) > 1e-9, axis=0)]
    if len(moved):
        raise PrehensileError(f"{who}: the path moves joints the context does not plan "
                              f"({', '.join(ctx.model.joint_names[i] for i in moved)}; planned: "
                              f"{', '.join(ctx.space.joint_names)})")
    for i in np.flatnonzero(~ctx.check_motions(path[:-1], path[1:])) if len(path) > 1 else ():
        report = certify_path(ctx, path[i:i + 2])
        if not report.ok:
            raise PrehensileError(f"{who}: the input path must be valid; its edge {i} (waypoint {i} to {i + 1}) "
                                  f"is not: {_failure(report)}")
    return path


def certified_escape(ctx: PlanningContext, q: np.ndarray, toward: np.ndarray, rng: np.random.Generator,
                     clearance: float, reach: float = 0.3, attempts: int | None = ESCAPE_ATTEMPTS,
                     samples: int = 32, deadline: float = np.inf) -> np.ndarray | None:
    """A configuration the sphere model accepts, at least ``clearance`` (m) from the world,
    joined to q (dof,) by a straight segment certified on the exact geometry; None if there is none.

    For endpoints that only the conservative sphere model rejects, or holds in a pocket
    narrower than the resolution (a grasp in contact range of the object): planners start
    from the escape configuration instead. Directions (planned joints only): toward ``toward``
    (dof,) first, then random ones from ``rng``, ``attempts`` in all (None: until ``deadline``,
    which must then be finite); along each, the first of ``samples`` configurations up to
    ``reach`` m (workspace-weighted) within the limits, free and clear enough is tried. No new
    direction is tried after ``deadline`` (s, :func:`~prehensile.clock.clock`).
    """
    if attempts is None and not np.isfinite(deadline):
        raise PrehensileError("certified_escape: attempts=None needs a finite deadline")
    idx, w = ctx.space.indices, ctx.space.weights
    if clock() >= deadline or not ctx.certifier.certify(q[None], ctx.certify_resolution).ok:
        return None
    batch = ESCAPE_ATTEMPTS if attempts is None else attempts
    directions = np.vstack([toward[idx] - q[idx], rng.normal(size=(batch - 1, len(idx)))])
    steps = reach * np.arange(1, samples + 1) / samples
    while True:
        for d in directions:
            if clock() >= deadline:
                return None
            length = float(w @ np.abs(d))
            if length <= 0.0:
                continue
            candidates = np.repeat(q[None], samples, axis=0)
            candidates[:, idx] += steps[:, None] * (d / length)
            good = np.flatnonzero(ctx.model.within_limits(candidates) & ctx.spheres.is_free(candidates)
                                  & (ctx.spheres.clearance(candidates, clearance, self_pairs=False) >= clearance))
            if len(good) and certify_path(ctx, np.stack([q, candidates[good[0]]])).ok:
                return candidates[good[0]]
        if attempts is not None:
            return None
        directions = rng.normal(size=(batch, len(idx)))
