r"""Elastic-band path smoothing (Quinlan 1995; Vahrenkamp 2011, §B.3, Alg. 35).

The waypoints of a path form a band. Every interior waypoint c_i feels an internal force
that tightens the band and an external force that pushes the robot away from obstacles
closer than ``d_min``:

.. math::

    f_{int}(i) = \frac{c_{i+1} - c_i}{\lVert c_{i+1} - c_i \rVert}
               + \frac{c_{i-1} - c_i}{\lVert c_{i-1} - c_i \rVert},
    \qquad
    f_{ext}(i) = \sum_{(p_r, p_o):\, d < d_{min}} J_{p_r}^{+}(c_i)\,(d_{min} - d)
                 \frac{p_r - p_o}{\lVert p_r - p_o \rVert},

    c_i \leftarrow c_i + k_{int} f_{int}(i) + k_{ext} f_{ext}(i),

in the planned joints, where (p_r, p_o) are the closest points of a robot link and an
obstacle at distance d (exact geometry, :meth:`ExactChecker.closest_points`) and J_{p_r} is
the (3, n) position Jacobian of the robot point. The thesis prints the external force with
``d = p_obst - p_rob`` (it would pull the robot *towards* the obstacle) and the update as
``c_i <- k f(i)``; both are corrected here. Its global gain k is folded into k_int and k_ext.

Choices the thesis leaves open:

* Every (link, obstacle) pair closer than ``d_min`` pushes, not only the closest one, so the
  band does not oscillate between two near links (the thesis ignores ties).
* J⁺ is the damped least-squares inverse ``Jᵀ (J Jᵀ + λ² I)⁻¹``, bounded near singularities.
* Waypoints are updated odd ones first, then even ones (red-black Gauss-Seidel): each update
  sees its neighbours' current positions, and each half is checked in one compiled call. An
  update is kept only if both adjacent edges pass ``ctx.check_motions`` (which tests the new
  waypoint's validity too); otherwise the waypoint stays. So a valid path stays valid, and the
  start and goal never move.
* The stopping rule bounds the largest step of an iteration, not the sum over waypoints
  (Σ‖f(i)‖ < δ in the thesis), which would depend on how finely the path is subdivided.
* Before the first iteration edges are subdivided to ``max_spacing`` (workspace-weighted
  distance), since a band of few waypoints cannot bend.
* Self-collision pairs exert no force; pairs already penetrating in the exact model (d <= 0)
  are skipped, as their witness points give no reliable direction.
* The band is certified on the exact geometry (``certify``): balls that do not cover it (a
  spherized URDF) let waypoints move where the geometry collides. A band that fails is made
  again with covering balls on the links that collided (or at half the resolution), and after
  ``certify_retries`` such tries the subdivided input path is returned
  (:func:`~prehensile.planning.certify.rework_certified`), with a warning if it fails too
  (an input free on balls that do not cover the geometry can).
"""

from __future__ import annotations

import logging
from dataclasses import dataclass

import numpy as np

from prehensile.clock import clock
from prehensile.kinematics import forward_kinematics, frame_jacobian
from prehensile.planning.certify import check_valid_path, rework_certified
from prehensile.settings import (
    FINITE_NON_NEGATIVE, FINITE_POSITIVE, NON_NEGATIVE, POSITIVE, at_least, check_fields, or_none,
)
from prehensile.spatial import make_pose

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class ElasticBandSettings:
    """Gains and stopping rule of :func:`elastic_band`.

    Attributes:
        k_int: tightening step (rad or m per iteration) along the sum of unit vectors to the
            neighbours (at most 2 k_int).
        k_ext: gain (dimensionless) on the repulsion; 1 would move a single close point to
            ``d_min`` to first order in one iteration.
        d_min: clearance (m) below which obstacles push.
        tolerance: δ (rad or m): stop when no waypoint's step in an iteration is longer (or
            when no waypoint could move).
        max_iterations: iteration cap.
        max_spacing: subdivide edges longer than this workspace-weighted distance (m,
            :meth:`ConfigurationSpace.distance`) first; None keeps the waypoints.
        damping: λ (m/rad) of the damped pseudoinverse.
        certify: return a band that passes the exact certification, or the subdivided input.
        certify_retries: bands made again after a failed certification.
        time_budget_s: stop iterating after this time (s) over all tries, or None (only
            ``max_iterations`` and ``tolerance`` stop it, and the same input gives the same
            band on any machine). A band cut short is as valid as a finished one: every
            iteration keeps the path valid.
    """

    k_int: float = 0.01
    k_ext: float = 0.5
    d_min: float = 0.05
    tolerance: float = 1e-3
    max_iterations: int = 100
    max_spacing: float | None = 0.05
    damping: float = 1e-2
    certify: bool = True
    certify_retries: int = 3
    time_budget_s: float | None = None

    def __post_init__(self) -> None:
        check_fields(self, **dict.fromkeys(("k_int", "k_ext", "damping"), FINITE_NON_NEGATIVE), tolerance=NON_NEGATIVE,
                     d_min=FINITE_POSITIVE, max_iterations=at_least(0), max_spacing=or_none(POSITIVE),
                     certify_retries=at_least(0), time_budget_s=or_none(FINITE_POSITIVE))


def _subdivide(ctx, path: np.ndarray, spacing: float) -> np.ndarray:
    """Path (M, dof) with points inserted on each straight edge so that no edge is longer than
    spacing (m); the given waypoints stay exactly as they are."""
    out = [path[:1]]
    for a, b in zip(path[:-1], path[1:]):
        steps = max(int(np.ceil(float(ctx.space.distance(ctx.space.active(a), ctx.space.active(b))) / spacing)), 1)
        out.extend((a + np.linspace(0.0, 1.0, steps + 1)[1:-1, None] * (b - a), b[None]))
    return np.concatenate(out)


def internal_force(prev: np.ndarray, current: np.ndarray, following: np.ndarray) -> np.ndarray:
    """Tightening force (..., n): the sum of unit vectors from ``current`` to its neighbours
    (..., n each)."""
    force = np.zeros_like(current)
    for other in (prev, following):
        offset = other - current
        length = np.linalg.norm(offset, axis=-1, keepdims=True)
        force += np.divide(offset, length, out=np.zeros_like(offset), where=length > 0)
    return force


def external_force(ctx, q: np.ndarray, d_min: float, damping: float = 1e-2) -> np.ndarray:
    """Repulsion (n,) in the planned joints at configuration q (dof,), pushing every robot link
    closer than d_min (m) to an obstacle away from it (see the module docstring)."""
    exact, indices = ctx.exact, ctx.space.indices
    model = exact.model  # the robot with any attached objects as links
    force = np.zeros(len(indices))
    pairs = [p for p in exact.closest_points(q, max_distance=d_min) if 0 < p.distance < d_min]
    if not pairs:
        return force
    poses = forward_kinematics(model, q, exact.T_world_base)
    for pair in pairs:
        away = pair.point_on_robot - pair.point_on_other
        norm = np.linalg.norm(away)
        if norm <= 1e-12:
            continue
        T = poses[model.link_index(pair.link)]
        point = T[:3, :3].T @ (pair.point_on_robot - T[:3, 3])
        _, jac = frame_jacobian(model, q, pair.link, make_pose(position=point), T_world_base=exact.T_world_base)
        J = jac[:3, indices]
        push = (d_min - pair.distance) * away / norm
        force += J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(3), push)
    return force


def _near_obstacles(ctx, path: np.ndarray, d_min: float) -> np.ndarray:
    """(N,) bool: the waypoints (N, dof) where some link may be closer than d_min (m) to an
    obstacle. Balls that cover the geometry answer for all of them in one call (a waypoint whose
    balls keep d_min feels no push); otherwise every waypoint is a candidate."""
    if not ctx.sphere_model.covering:
        return np.ones(len(path), dtype=bool)
    return ctx.spheres.clearance(path, d_min, self_pairs=False) < d_min


def elastic_band(ctx, path: np.ndarray, settings: ElasticBandSettings = ElasticBandSettings()) -> np.ndarray:
    """Smooth a valid path and push it away from obstacles with an elastic band.

    Args:
        ctx: a :class:`~prehensile.planning.context.PlanningContext` (model, configuration
            space, exact and sphere checkers, validity and motion checks).
        path: (N, dof) full configurations (rad or m) joined by straight, valid edges.
        settings: :class:`ElasticBandSettings`.

    Returns:
        (M, dof) the band, M >= N (edges subdivided to ``settings.max_spacing``); same first
        and last waypoints; a waypoint moves only where both its edges pass ``ctx.check_motion``;
        certified on the exact geometry if ``settings.certify`` (see the module doc).
        Joints outside ``ctx.space`` keep their values.

    Raises:
        PrehensileError: path is not a valid path (:func:`~prehensile.planning.certify.check_valid_path`).
    """
    path = check_valid_path(ctx, path, "elastic_band").copy()
    deadline = np.inf if settings.time_budget_s is None else clock() + settings.time_budget_s
    if settings.max_spacing is not None:
        path = _subdivide(ctx, path, settings.max_spacing)

    def band(context, edge_res: float) -> np.ndarray:
        return _tightened(context, path, settings, edge_res, deadline)

    if not settings.certify:
        return band(ctx, ctx.resolution)
    return rework_certified(ctx, path, band, ctx.resolution, settings.certify_retries, "elastic_band")[0]


def _tightened(ctx, path: np.ndarray, settings: ElasticBandSettings, resolution: float, deadline: float) -> np.ndarray:
    """The band's iterations on a copy of path (M, dof), each move checked on ``ctx``'s balls at
    ``resolution`` (m), until ``deadline`` (s, :func:`~prehensile.clock.clock`)."""
    path = path.copy()
    space = ctx.space
    band = space.active(path)
    for iteration in range(settings.max_iterations):
        largest, accepted = 0.0, 0
        pushed = _near_obstacles(ctx, path, settings.d_min) if settings.k_ext > 0 else np.zeros(len(path), bool)
        for first in (1, 2):  # odd waypoints, then even ones: neither half moves the other's neighbours
            rows = np.arange(first, len(band) - 1, 2)
            step = settings.k_int * internal_force(band[rows - 1], band[rows], band[rows + 1])
            for k in np.flatnonzero(pushed[rows]):
                step[k] += settings.k_ext * external_force(ctx, path[rows[k]], settings.d_min, settings.damping)
            size = np.linalg.norm(step, axis=1)
            largest = max(largest, float(size.max(initial=0.0)))
            rows, step = rows[size > 0], step[size > 0]
            q = path[rows].copy()
            q[:, space.indices] = np.clip(band[rows] + step, space.lower, space.upper)
            ends = ctx.check_motions(np.concatenate((path[rows - 1], q)), np.concatenate((q, path[rows + 1])),
                                     resolution)
            moved = ends[:len(rows)] & ends[len(rows):]
            path[rows[moved]] = q[moved]
            band[rows[moved]] = q[moved][:, space.indices]
            accepted += int(moved.sum())
        log.debug("elastic band iteration %d: largest step %.4g, %d waypoints moved", iteration, largest, accepted)
        if largest < settings.tolerance or accepted == 0 or clock() >= deadline:
            break
    return path
