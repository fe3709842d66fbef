"""Sphere covers of collision geometry: exact covers of primitives, clustered covers of meshes.

Every cover here is *conservative by construction*: a ball that contains the three vertices of
a triangle contains the whole triangle (balls are convex), so a set of balls that each contain
every vertex of their assigned triangles covers the triangulated surface. Primitives get
closed-form covers of the solid shape (not of a tessellation, which would lie inside it).
"""

from __future__ import annotations

import logging

import numpy as np

from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere, shape_to_trimesh

log = logging.getLogger(__name__)

PRIMITIVE_OVERSHOOT = 0.02  # m: how far a primitive's balls may reach out of it by default (a box of 0.5 m
# covered by 8 balls bulges 0.1 m: ARMAR-III's torso balls then met its hanging arms)


def geometry_triangles(geometry: Geometry, max_edge: float | None = None) -> np.ndarray:
    """Triangles of ``geometry`` in the link frame, shape (T, 3, 3) (m).

    Primitives are tessellated with :func:`~prehensile.model.geometry.shape_to_trimesh`; the
    tessellation of round shapes lies inside the true surface, so use it for sampling, not
    for covering (see :func:`cover_geometry`).

    Args:
        geometry: the shape and its pose in the link.
        max_edge: if given, triangles are subdivided until no edge is longer (m).
    """
    mesh = shape_to_trimesh(geometry.shape)
    vertices = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces, dtype=np.int64)
    if max_edge is not None and len(faces):
        import trimesh

        vertices, faces = trimesh.remesh.subdivide_to_size(vertices, faces, max_edge=max_edge, max_iter=20)
    T = np.asarray(geometry.T_link_geom, dtype=float)
    vertices = vertices @ T[:3, :3].T + T[:3, 3]
    return vertices[faces]


def enclosing_ball(points: np.ndarray, iterations: int = 200) -> tuple[np.ndarray, float]:
    """A near-minimal ball containing every point of ``points`` (N, 3).

    The centre follows the Badoiu-Clarkson iteration (step towards the farthest point with
    step 1/(k+1)), which converges to the minimum enclosing ball; the radius is then the exact
    largest distance from that centre, so the ball always contains all points.

    Returns:
        (centre (3,), radius) in the units of ``points``.
    """
    points = np.asarray(points, dtype=float)
    center = 0.5 * (points.min(axis=0) + points.max(axis=0))
    for k in range(1, iterations + 1):
        far = points[np.argmax(np.einsum("ij,ij->i", points - center, points - center))]
        center = center + (far - center) / (k + 1)
    radius = float(np.sqrt(np.max(np.einsum("ij,ij->i", points - center, points - center))))
    return center, radius


def hull_planes(points: np.ndarray) -> np.ndarray:
    """(F, 4) outward facet planes (unit normal a, offset d; inside a.x + d <= 0) of the
    convex hull of points (N, 3); empty when the points are degenerate (flat)."""
    from scipy.spatial import ConvexHull, QhullError

    try:
        return ConvexHull(np.asarray(points, dtype=float)).equations
    except (QhullError, ValueError):
        return np.zeros((0, 4))


def _radius(center: np.ndarray, points: np.ndarray) -> float:
    diff = points - center
    return float(np.sqrt(np.max(np.einsum("ij,ij->i", diff, diff))))


def push_inside(center: np.ndarray, points: np.ndarray, direction: np.ndarray, planes: np.ndarray,
                steps: int = 24) -> np.ndarray:
    """Move a ball centre along +-``direction`` to minimise how far the ball enclosing
    ``points`` (N, 3) sticks out of the convex body ``planes`` (F, 4).

    The ball's radius at centre c is the largest distance to ``points`` (so it keeps holding
    them); its protrusion is ``max_f(a_f . c + d_f) + r(c)``. Candidates lie on the chord of
    the body through ``center`` along ``direction``.
    """
    if len(planes) == 0 or not np.linalg.norm(direction) > 0:
        return center
    direction = direction / np.linalg.norm(direction)
    a, d = planes[:, :3], planes[:, 3]
    slack = -(a @ center + d)  # >= 0 inside
    rate = a @ direction
    with np.errstate(divide="ignore", invalid="ignore"):
        forward = np.min(np.where(rate > 1e-12, slack / rate, np.inf))
        backward = np.min(np.where(rate < -1e-12, -slack / rate, np.inf))
    forward, backward = max(0.0, min(forward, 1.0)), max(0.0, min(backward, 1.0))
    best, best_cost = center, np.inf
    for t in np.linspace(-backward, forward, steps):
        c = center + t * direction
        cost = float(np.max(a @ c + d)) + _radius(c, points)
        if cost < best_cost - 1e-12:
            best, best_cost = c, cost
    return best


def cluster_triangles(triangles: np.ndarray, n_clusters: int) -> tuple[np.ndarray, np.ndarray]:
    """Area-weighted k-means of the centroids of triangles (T, 3, 3), T >= 1, from a
    deterministic farthest-point start: (label (T,) int in [0, K), cluster centres (K, 3)),
    K = min(n_clusters, T) (clusters may end up empty)."""
    centroids = triangles.mean(axis=1)
    weight = 0.5 * np.linalg.norm(np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0]),
                                  axis=1) + 1e-12  # area
    k = max(1, min(int(n_clusters), len(triangles)))
    seeds = [int(np.argmax(np.linalg.norm(centroids - centroids.mean(axis=0), axis=1)))]
    dist = np.linalg.norm(centroids - centroids[seeds[0]], axis=1)
    for _ in range(1, k):
        seeds.append(int(np.argmax(dist)))
        dist = np.minimum(dist, np.linalg.norm(centroids - centroids[seeds[-1]], axis=1))
    centers = centroids[seeds].copy()
    for _ in range(30):
        label = np.argmin(((centroids[:, None, :] - centers[None]) ** 2).sum(-1), axis=1)
        for j in range(k):
            mask = label == j
            if mask.any():
                centers[j] = np.average(centroids[mask], axis=0, weights=weight[mask])
    return np.argmin(((centroids[:, None, :] - centers[None]) ** 2).sum(-1), axis=1), centers


_BOX_EDGES = 64  # longest edges of a cluster tried as box axes
_THIN = 1e-3  # m added to each half size when comparing candidate boxes (flat boxes have no volume)


def box_cover(triangles: np.ndarray, n_boxes: int) -> tuple[np.ndarray, np.ndarray]:
    """Cover triangles (T, 3, 3) with at most ``n_boxes`` oriented boxes, one per cluster of
    :func:`cluster_triangles` holding all its vertices (a box holding a triangle's vertices
    holds the triangle). Of the boxes along the cluster's principal axes, or along its normal
    and one of its longest edges, the smallest is kept: flat patches get flat boxes, so a plane
    or a box-shaped mesh is covered exactly.

    Returns:
        poses (K, 4, 4) (rotations with determinant +1) and half sizes (K, 3) (m, >= 0).
    """
    triangles = np.asarray(triangles, dtype=float)
    if len(triangles) == 0:
        return np.zeros((0, 4, 4)), np.zeros((0, 3))
    label = cluster_triangles(triangles, n_boxes)[0]
    poses, halves = [], []
    for j in np.unique(label):
        patch = triangles[label == j]
        points = patch.reshape(-1, 3)
        mean = points.mean(axis=0)
        principal = np.linalg.svd(points - mean, full_matrices=True)[2].T  # columns, the normal last
        normal = principal[:, 2]
        edges = np.concatenate([patch[:, 1] - patch[:, 0], patch[:, 2] - patch[:, 1], patch[:, 0] - patch[:, 2]])
        edges -= np.outer(edges @ normal, normal)  # into the patch's plane
        lengths = np.linalg.norm(edges, axis=1)
        longest = [i for i in np.argsort(-lengths)[:_BOX_EDGES] if lengths[i] > 1e-12]
        best = None
        for axes in [principal] + [_frame(edges[i] / lengths[i], normal) for i in longest]:
            axes = axes if np.linalg.det(axes) > 0 else axes * np.array([1.0, 1.0, -1.0])
            local = (points - mean) @ axes
            lo, hi = local.min(axis=0), local.max(axis=0)
            size = np.prod(0.5 * (hi - lo) + _THIN)
            if best is None or size < best[0]:
                best = size, axes, lo, hi
        _, axes, lo, hi = best
        pose = np.eye(4)
        pose[:3, :3], pose[:3, 3] = axes, mean + axes @ (0.5 * (lo + hi))
        poses.append(pose), halves.append(0.5 * (hi - lo))
    return np.array(poses), np.array(halves)


def _frame(x: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """(3, 3) axes (columns): unit x (orthogonal to the unit ``normal``), normal x x, normal."""
    return np.column_stack([x, np.cross(normal, x), normal])


def cover_triangles(triangles: np.ndarray, n_spheres: int, refine: int = 4,
                    planes: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
    """Cover triangles (T, 3, 3) with at most ``n_spheres`` balls.

    Triangle centroids are clustered with area-weighted k-means (deterministic farthest-point
    initialisation). Then ``refine`` rounds: each triangle goes to the ball that would need the
    smallest radius to hold its three vertices; each ball becomes the near-minimal enclosing
    ball of its triangles' vertices, and its centre is pushed along the patch normal into the
    body (:func:`push_inside` against ``planes``, default the convex hull of the triangles) so
    that the ball sticks out of the surface as little as possible. Each final radius is the
    largest vertex distance of its triangles, so every triangle lies inside its ball.

    Returns:
        centres (K, 3) and radii (K,) in m, K <= n_spheres.
    """
    triangles = np.asarray(triangles, dtype=float)
    if len(triangles) == 0:
        return np.zeros((0, 3)), np.zeros(0)
    if planes is None:
        planes = hull_planes(triangles.reshape(-1, 3))
    centers = cluster_triangles(triangles, n_spheres)[1]
    k = len(centers)
    normals = np.cross(triangles[:, 1] - triangles[:, 0], triangles[:, 2] - triangles[:, 0])
    for _ in range(refine + 1):
        need = np.sqrt(((triangles[:, :, None, :] - centers[None, None]) ** 2).sum(-1)).max(axis=1)
        label = np.argmin(need, axis=1)
        out = []
        for j in range(k):
            mask = label == j
            if mask.any():
                points = triangles[mask].reshape(-1, 3)
                c, _ = enclosing_ball(points)
                out.append(push_inside(c, points, normals[mask].sum(axis=0), planes))
        centers = np.array(out)
        k = len(centers)
    need = np.sqrt(((triangles[:, :, None, :] - centers[None, None]) ** 2).sum(-1)).max(axis=1)
    label = np.argmin(need, axis=1)
    radii = np.zeros(k)
    for j in range(k):
        mask = label == j
        if mask.any():
            radii[j] = need[mask, j].max()
    keep = radii > 0
    return centers[keep], radii[keep]


def _box_cover(size: np.ndarray, budget: int) -> tuple[np.ndarray, np.ndarray]:
    """Balls circumscribing a grid of sub-boxes of a box of full ``size`` (3,) centred at 0."""
    side = float(np.min(size)) / 8.0  # the finest grid of cubes within the budget
    while True:
        counts = np.maximum(1, np.ceil(size / side - 1e-9)).astype(int)
        if counts.prod() <= max(1, budget):
            break
        side *= 1.2
    cell = size / counts
    axes = [(np.arange(c) + 0.5) * cell[i] - 0.5 * size[i] for i, c in enumerate(counts)]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    return grid, np.full(len(grid), 0.5 * float(np.linalg.norm(cell)))


def _axis_cover(radius: float, length: float, budget: int, caps: bool) -> tuple[np.ndarray, np.ndarray]:
    """Balls covering a solid cylinder (z axis, centred) and, with ``caps``, its hemispherical caps.

    A slab of the cylinder of thickness d is inside the ball of radius sqrt(r^2 + (d/2)^2)
    at its centre; each cap is the ball of radius r at the segment end.
    """
    slots = max(1, budget - (2 if caps else 0))
    n = int(min(slots, max(1, np.ceil(length / (2.0 * radius) - 1e-9))))
    d = length / n
    z = (np.arange(n) + 0.5) * d - 0.5 * length
    centers = np.column_stack([np.zeros(n), np.zeros(n), z])
    radii = np.full(n, float(np.hypot(radius, 0.5 * d)))
    if caps:
        ends = np.array([[0.0, 0.0, -0.5 * length], [0.0, 0.0, 0.5 * length]])
        centers = np.vstack([centers, ends])
        radii = np.concatenate([radii, [radius, radius]])
    return centers, radii


def cover_primitive(geometry: Geometry, budget: int = 8) -> tuple[np.ndarray, np.ndarray]:
    """Exact cover of a primitive solid by at most about ``budget`` balls, in the link frame.

    Returns:
        centres (K, 3) and radii (K,) in m.

    Raises:
        TypeError: ``geometry.shape`` is a mesh (use :func:`cover_triangles`).
    """
    shape = geometry.shape
    if isinstance(shape, Sphere) or (isinstance(shape, Capsule) and shape.length == 0):  # a ball
        centers, radii = np.zeros((1, 3)), np.array([float(shape.radius)])
    elif isinstance(shape, Box):
        centers, radii = _box_cover(np.asarray(shape.size, dtype=float), budget)
    elif isinstance(shape, Cylinder):
        centers, radii = _axis_cover(float(shape.radius), float(shape.length), budget, caps=False)
    elif isinstance(shape, Capsule):
        centers, radii = _axis_cover(float(shape.radius), float(shape.length), budget, caps=True)
    else:
        raise TypeError(f"cover_primitive: {type(shape).__name__} is not a primitive")
    T = np.asarray(geometry.T_link_geom, dtype=float)
    return centers @ T[:3, :3].T + T[:3, 3], radii


def primitive_overshoot(geometry: Geometry, centers: np.ndarray, radii: np.ndarray) -> float:
    """How far (m) balls (centres (K, 3) inside the primitive, link frame; radii (K,)) reach out
    of the primitive solid at most: per ball its radius minus its centre's distance to the
    surface (the ball of that distance lies inside the convex solid)."""
    T, shape = np.asarray(geometry.T_link_geom, dtype=float), geometry.shape
    local = (centers - T[:3, 3]) @ T[:3, :3]
    if isinstance(shape, Box):
        depth = np.min(0.5 * np.asarray(shape.size) - np.abs(local), axis=1)
    elif isinstance(shape, Cylinder):
        depth = np.minimum(shape.radius - np.hypot(local[:, 0], local[:, 1]), 0.5 * shape.length - np.abs(local[:, 2]))
    else:  # a sphere, or a capsule: the distance to its axis segment
        half = 0.5 * shape.length if isinstance(shape, Capsule) else 0.0
        axis = np.zeros_like(local)
        axis[:, 2] = np.clip(local[:, 2], -half, half)
        depth = shape.radius - np.linalg.norm(local - axis, axis=1)
    return float(np.max(radii - depth))


def cover_geometries(
    geometries: tuple[Geometry, ...], n_spheres: int = 8, max_radius: float | None = None,
    max_edge: float = 0.02, max_spheres: int = 64, max_overshoot: float = PRIMITIVE_OVERSHOOT,
) -> tuple[np.ndarray, np.ndarray]:
    """Balls covering all ``geometries`` of one link (link frame).

    Meshes are merged and covered by :func:`cover_triangles` with ``n_spheres`` balls (more,
    up to ``max_spheres``, while the largest radius exceeds ``max_radius``); primitives get
    their exact covers with the same budget, grown the same way and also while a ball reaches
    more than ``max_overshoot`` out of the solid (:func:`primitive_overshoot`).

    Args:
        geometries: the link's collision geometries.
        n_spheres: balls for the link's meshes (and budget per primitive).
        max_radius: optional largest radius (m) of the balls.
        max_edge: triangles are subdivided to this edge length (m) before clustering.
        max_spheres: cap on the number of balls for the meshes and per primitive.
        max_overshoot: how far (m) a primitive's balls may reach out of it (a target: the
            budget stops growing at ``max_spheres``, logged at INFO; balls on a cylinder's
            axis reach about 0.4 of its radius out of its flat ends).

    Returns:
        centres (K, 3) and radii (K,) in m.
    """
    centers, radii, triangles = [np.zeros((0, 3))], [np.zeros(0)], []
    for geometry in geometries:
        if isinstance(geometry.shape, Mesh):
            triangles.append(geometry_triangles(geometry, max_edge))
        else:
            budget = n_spheres
            while True:
                c, r = cover_primitive(geometry, budget)
                overshoot = primitive_overshoot(geometry, c, r)
                if (max_radius is None or r.max() <= max_radius) and overshoot <= max_overshoot:
                    break
                if budget >= max_spheres:
                    if overshoot > max_overshoot:
                        log.info("%s: %d balls reach %.3f m out of it (target %.3f m)", geometry.shape, len(r),
                                 overshoot, max_overshoot)
                    break
                budget = min(max_spheres, budget + max(1, budget // 4))
            centers.append(c)
            radii.append(r)
    if triangles:
        tris = np.concatenate(triangles)
        k = n_spheres
        while True:
            c, r = cover_triangles(tris, k)
            if max_radius is None or r.max() <= max_radius or k >= max_spheres or len(c) < k:
                break
            k = min(max_spheres, k + max(1, k // 4))
        centers.append(c)
        radii.append(r)
    return np.concatenate(centers), np.concatenate(radii)


def pad_to_cover(centers: np.ndarray, radii: np.ndarray, triangles: np.ndarray,
                 max_growth: float = np.inf) -> tuple[np.ndarray, np.ndarray]:
    """Grow ``radii`` (K,) so that triangles (T, 3, 3) lie in one ball each.

    A triangle already inside some ball is left alone; otherwise the ball needing the
    smallest radius increase to contain the triangle's three vertices grows to do so, if its
    radius stays within ``max_growth`` (m) of its original radius. Radii never shrink, so triangles covered earlier
    stay covered.

    Returns:
        new radii (K,) and a (T,) bool mask of the triangles still not inside any ball
        (all False when ``max_growth`` is infinite).
    """
    radii = np.array(radii, dtype=float)
    limit = radii + max_growth
    uncovered = np.ones(len(triangles), dtype=bool)
    if len(triangles) == 0 or len(centers) == 0:
        return radii, uncovered
    need = np.sqrt(((triangles[:, :, None, :] - centers[None, None]) ** 2).sum(-1)).max(axis=1)
    uncovered = ~np.any(need <= radii[None], axis=1)
    order = np.flatnonzero(uncovered)
    order = order[np.argsort(np.min(need[order] - radii[None], axis=1))]
    for t in order:
        growth = np.where(need[t] <= limit, need[t] - radii, np.inf)
        j = int(np.argmin(growth))
        if growth[j] <= 0.0:
            uncovered[t] = False
        elif np.isfinite(growth[j]):
            radii[j] = need[t, j]
            uncovered[t] = False
    return radii, uncovered
