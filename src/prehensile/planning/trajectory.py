"""Time parameterization of collision-checked paths with TOPP-RA.

A planner's path is a polyline in configuration space (Vahrenkamp 2011, §A.5): waypoints
joined by straight segments, and it is the straight segments that were collision-checked.
A corner of a polyline can only be followed exactly by stopping there (any non-zero
velocity would need an infinite acceleration to turn), so by default every segment is
parameterized on its own, rest to rest. Consecutive collinear segments are merged first, so
a densely sampled straight line does not stop at every sample.

Optionally the corners are *blended* by a cubic spline through the waypoints, but only where
a caller-supplied motion check accepts the spline (densely sampled): a run of waypoints whose
spline fails is split at its middle waypoint, where the motion stops, and each half is tried
again, down to single straight segments. Blending matters for dense paths such as an elastic
band's, where stopping at every waypoint multiplies the duration (about 5x on the Panda band
of the tests).

Each piece is parameterized time-optimally under joint velocity and acceleration limits as a
path velocity ``sd(s)`` on a grid of path positions with constant path acceleration between
gridpoints, integrated exactly here and sampled at a fixed period. A straight segment's
optimum is known in closed form: accelerate at the largest rate every joint allows, cruise at
the largest speed, brake (a trapezoid, or a triangle on a short segment; three intervals). The
spline gets TOPP-RA (Pham & Pham 2018, `toppra`).
"""

from __future__ import annotations

import functools
import logging
from dataclasses import dataclass, field
from typing import Callable

import numpy as np
import toppra
import toppra.algorithm
import toppra.constraint
from toppra.interpolator import AbstractGeometricPath

from prehensile.errors import PrehensileError
from prehensile.model.robot_model import RobotModel
from prehensile.settings import FINITE_POSITIVE, POSITIVE, check_value

log = logging.getLogger(__name__)

DEFAULT_VELOCITY = 1.0
"""Velocity limit (rad/s or m/s) for joints whose model gives none (infinite or <= 0)."""

DEFAULT_ACCELERATION = 2.0
"""Acceleration limit (rad/s^2 or m/s^2); robot descriptions carry none. Conservative: most
arms accelerate a joint at 5-20 rad/s^2 (Panda datasheet: 7.5-20)."""

MAX_SAMPLES = 1_000_000  # samples of a trajectory (at dt = 0.01 s: 2.8 hours of motion)
_SPLINE_GRID = 8  # TOPP-RA gridpoints per spline segment, knots included (the spline's second derivative kinks there)
_DUPLICATE_TOL = 1e-9  # rad or m: waypoints closer than this (max-norm) are one waypoint


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class Trajectory:
    """Joint positions, velocities and accelerations sampled at a fixed period.

    Attributes:
        t: (M,) sample times (s), from 0 to the duration; the last step may be shorter.
        q: (M, n) positions (rad or m).
        qd: (M, n) velocities (rad/s or m/s); zero at both ends.
        qdd: (M, n) accelerations (rad/s^2 or m/s^2); zero at the last sample (at rest).
        joint_names: names of the n joints, or () when unknown.
        motion: the continuous motion the samples were taken from, ``t (K,) -> (q, qd, qdd)``
            (K, n) each, or None (a trajectory given only by its samples).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray
    joint_names: tuple[str, ...] = ()
    motion: Callable[[np.ndarray], tuple[np.ndarray, np.ndarray, np.ndarray]] | None = field(
        default=None, repr=False)

    def __post_init__(self) -> None:
        for name in ("t", "q", "qd", "qdd"):
            array = np.array(getattr(self, name), dtype=float)
            array.setflags(write=False)
            object.__setattr__(self, name, array)
        if self.q.ndim != 2 or self.t.shape != self.q.shape[:1] or not self.q.shape == self.qd.shape == self.qdd.shape:
            raise PrehensileError(f"Trajectory: t (M,) and q, qd, qdd (M, n) must agree, got t {self.t.shape}, "
                                  f"q {self.q.shape}, qd {self.qd.shape}, qdd {self.qdd.shape}")
        if self.joint_names and len(self.joint_names) != self.q.shape[1]:
            raise PrehensileError(f"Trajectory: {len(self.joint_names)} joint names for {self.q.shape[1]} joints")

    @property
    def duration(self) -> float:
        """Duration (s)."""
        return float(self.t[-1])

    def sample(self, t: float | np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities and accelerations at times t (*batch,) (s), clamped to the duration.

        With :attr:`motion` (every trajectory of :func:`time_parameterize`) the motion itself is
        evaluated, which meets the limits between samples too (a straight segment exactly, a
        blended spline where the profile was checked: five times per interval of its grid and
        at every sample). Without it positions and
        velocities come from the cubic Hermite interpolant of (q, qd) between samples and
        accelerations are interpolated linearly; where the acceleration changes within one
        period (a stop at a corner shorter than ``dt``) that interpolant can exceed the
        velocity limit by any amount.

        Returns:
            (q, qd, qdd), each (*batch, n).
        """
        t = np.clip(np.asarray(t, dtype=float), 0.0, self.duration)
        if len(self.t) == 1:
            shape = t.shape + self.q.shape[1:]
            return (np.broadcast_to(self.q[0], shape).copy(), np.zeros(shape), np.zeros(shape))
        if self.motion is not None:
            q, qd, qdd = (x.reshape(t.shape + self.q.shape[1:]) for x in self.motion(t.ravel()))
            end = t >= self.duration  # at rest at the last waypoint, as the last sample
            q[end], qd[end], qdd[end] = self.q[-1], 0.0, 0.0
            return q, qd, qdd
        k = np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, len(self.t) - 2)
        h = (self.t[k + 1] - self.t[k])[..., None]
        r = (t - self.t[k])[..., None] / h
        q0, q1, v0, v1 = self.q[k], self.q[k + 1], self.qd[k] * h, self.qd[k + 1] * h
        q = ((2 * r**3 - 3 * r**2 + 1) * q0 + (r**3 - 2 * r**2 + r) * v0
             + (-2 * r**3 + 3 * r**2) * q1 + (r**3 - r**2) * v1)
        qd = ((6 * r**2 - 6 * r) * (q0 - q1) + (3 * r**2 - 4 * r + 1) * v0 + (3 * r**2 - 2 * r) * v1) / h
        qdd = (1 - r) * self.qdd[k] + r * self.qdd[k + 1]
        return q, qd, qdd

    def to_dict(self) -> dict:
        """JSON-ready dictionary: joint_names, duration (s), t, q, qd, qdd as nested lists."""
        return {"joint_names": list(self.joint_names), "duration": self.duration, "t": self.t.tolist(),
                "q": self.q.tolist(), "qd": self.qd.tolist(), "qdd": self.qdd.tolist()}


def model_limits(model: RobotModel, indices: np.ndarray | None = None,
                 acceleration: float | np.ndarray = DEFAULT_ACCELERATION) -> tuple[np.ndarray, np.ndarray]:
    """Velocity and acceleration limits of some of the model's variables.

    Args:
        indices: (n,) variable indices (e.g. ``ConfigurationSpace.indices``); all if None.
        acceleration: acceleration limit(s) (rad/s^2 or m/s^2, positive), scalar or (n,).

    Returns:
        (velocity (n,), acceleration (n,)); velocities the model leaves unlimited (infinite
        or <= 0) get :data:`DEFAULT_VELOCITY`.
    """
    if indices is None:
        indices = np.arange(model.dof)
    indices = np.asarray(indices)
    if indices.ndim != 1 or indices.dtype.kind not in "iu" or np.any((indices < 0) | (indices >= model.dof)):
        raise PrehensileError(f"model_limits: indices must be variable indices in [0, {model.dof}) of robot "
                              f"'{model.name}' (joints: {', '.join(model.joint_names)}), got {indices.tolist()}")
    velocity = np.asarray(model.velocity_limit, dtype=float)[indices]
    velocity = np.where(np.isfinite(velocity) & (velocity > 0), velocity, DEFAULT_VELOCITY)
    acceleration = np.asarray(acceleration, dtype=float)
    if acceleration.ndim > 1 or acceleration.size not in (1, len(indices)) or not np.all(acceleration > 0) \
            or not np.all(np.isfinite(acceleration)):
        raise PrehensileError(f"model_limits: acceleration must be one positive number or {len(indices)} "
                              f"(rad/s^2 or m/s^2), got {acceleration.tolist()}")
    return velocity, np.broadcast_to(acceleration, velocity.shape).copy()


class _Line(AbstractGeometricPath):
    """The straight segment a -> b as a toppra path over s in [0, 1]."""

    def __init__(self, a: np.ndarray, b: np.ndarray) -> None:
        self.a, self.delta = a, b - a

    def __call__(self, s, order: int = 0):
        s = np.asarray(s, dtype=float)
        if order == 0:
            return self.a + s[..., None] * self.delta
        return np.broadcast_to(self.delta if order == 1 else 0.0 * self.delta, s.shape + self.delta.shape).copy()

    @property
    def dof(self) -> int:
        return len(self.delta)

    @property
    def path_interval(self) -> np.ndarray:
        return np.array([0.0, 1.0])


def _corners(path: np.ndarray) -> np.ndarray:
    """The waypoints without repeats and without points inside a straight run, (K, n)."""
    keep = [path[0]]
    for q in path[1:]:
        if np.max(np.abs(q - keep[-1])) > _DUPLICATE_TOL:
            keep.append(q)
    if len(keep) == 1:
        return np.array(keep)
    out = [keep[0]]
    for i in range(1, len(keep) - 1):
        u, w = keep[i] - out[-1], keep[i + 1] - keep[i]
        if np.linalg.norm(u / np.linalg.norm(u) - w / np.linalg.norm(w)) > 1e-9:  # turns here
            out.append(keep[i])
    out.append(keep[-1])
    return np.array(out)


def _spline(corners: np.ndarray, check: Callable[[np.ndarray, np.ndarray], bool], step: float):
    """(The cubic spline through the corners, its TOPP-RA gridpoints) if ``check`` accepts every
    chord between samples of it spaced at most ``step`` (max-norm) apart; None otherwise. The
    spline's parameter is the chord length (rad or m): scaled to [0, 1], paths a few mm long
    gave TOPP-RA path derivatives so small that it found no profile."""
    knots = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(corners, axis=0), axis=1))])
    spline = toppra.SplineInterpolator(knots, corners, bc_type="natural")
    count = int(np.ceil(np.sum(np.max(np.abs(np.diff(corners, axis=0)), axis=1)) / step)) + 1
    while True:
        samples = spline(np.linspace(0.0, knots[-1], count + 1))
        if np.max(np.abs(np.diff(samples, axis=0))) <= step:
            break
        count *= 2
    if all(check(a, b) for a, b in zip(samples[:-1], samples[1:])):
        fractions = np.arange(_SPLINE_GRID) / _SPLINE_GRID
        grid = np.append((knots[:-1, None] + np.diff(knots)[:, None] * fractions).ravel(), knots[-1])
        return spline, grid
    return None


def _line_knots(line: _Line, velocity: np.ndarray, acceleration: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Time-optimal rest-to-rest profile of a straight segment: gridpoints s (G,) and path
    speeds sd (G,) with constant path acceleration between them (the trapezoid's corners)."""
    moving = line.delta != 0.0
    top = float(np.min(velocity[moving] / np.abs(line.delta[moving])))  # path speed, 1/s
    rate = float(np.min(acceleration[moving] / np.abs(line.delta[moving])))  # path acceleration, 1/s^2
    ramp = min(0.5 * top * top / rate, 0.5)  # path length to reach the top speed
    peak = np.sqrt(2.0 * rate * ramp)
    if ramp == 0.5:
        return np.array([0.0, 0.5, 1.0]), np.array([0.0, peak, 0.0])
    return np.array([0.0, ramp, 1.0 - ramp, 1.0]), np.array([0.0, peak, peak, 0.0])


def _toppra_knots(piece, velocity: np.ndarray, acceleration: np.ndarray, grid: np.ndarray):
    """Rest-to-rest TOPP-RA solution of a piece on ``grid``: gridpoints s (G,) and path speeds sd
    (G,), or None if TOPP-RA finds none."""
    constraints = [toppra.constraint.JointVelocityConstraint(velocity),
                   toppra.constraint.JointAccelerationConstraint(acceleration)]
    algorithm = toppra.algorithm.TOPPRA(constraints, piece, gridpoints=grid, solver_wrapper="seidel")
    _, sd, _ = algorithm.compute_parameterization(0.0, 0.0)
    if sd is None or not np.all(np.isfinite(sd)):
        log.info("time_parameterize: TOPP-RA failed on a blended piece (%s)", algorithm.problem_data.return_code)
        return None
    return algorithm.gridpoints, np.maximum(sd, 0.0)


def _evaluate(pieces, ss, sd, piece_of, starts, t):
    """q, qd, qdd (len(t), n) from per-interval knots with constant path acceleration."""
    j = np.clip(np.searchsorted(starts, t, side="right") - 1, 0, len(starts) - 1)
    u = (sd[j, 1] ** 2 - sd[j, 0] ** 2) / (2.0 * (ss[j, 1] - ss[j, 0]))
    tau = t - starts[j]
    s = np.clip(ss[j, 0] + sd[j, 0] * tau + 0.5 * u * tau**2, ss[j, 0], ss[j, 1])
    v = np.maximum(sd[j, 0] + u * tau, 0.0)[:, None]
    n = pieces[0].dof
    q, qd, qdd = np.empty((len(t), n)), np.empty((len(t), n)), np.empty((len(t), n))
    for p in np.unique(piece_of[j]):
        m = piece_of[j] == p
        d1, d2 = pieces[p](s[m], 1), pieces[p](s[m], 2)
        q[m] = pieces[p](s[m], 0)
        qd[m] = d1 * v[m]
        qdd[m] = d2 * v[m] ** 2 + d1 * u[m, None]
    return q, qd, qdd


def time_parameterize(path: np.ndarray, velocity_limits: float | np.ndarray, acceleration_limits: float | np.ndarray,
                      dt: float = 0.01, blend_check: Callable[[np.ndarray, np.ndarray], bool] | None = None,
                      blend_step: float = 0.01, joint_names: tuple[str, ...] = ()) -> Trajectory:
    """Time-optimal rest-to-rest trajectory along a piecewise-linear path.

    By default the motion follows the polyline exactly, stopping at each corner (collinear
    waypoints and repeats are dropped first). With ``blend_check`` the corners are rounded by
    the natural cubic spline through the waypoints, used where ``blend_check(qa, qb)``
    accepts every chord between spline samples ``blend_step`` apart and the spline is the
    faster motion: a run of waypoints whose spline fails is split at its middle waypoint (the
    motion stops there) and each half blended on its own, down to straight segments.
    The check must also check joint limits, since the spline may overshoot: for a planning
    context, ``lambda a, b: ctx.check_motion(ctx.space.full(a), ctx.space.full(b))`` (the sphere
    model), or the exact check
    ``lambda a, b: certify_path(ctx, ctx.space.full(np.stack([a, b]))).ok``, which a path that
    starts or ends where only the conservative balls collide (a planner's certified escape)
    needs; ``prehensile plan`` uses it.

    Limits are enforced at the TOPP-RA gridpoints (the spline's knots among them); a blended
    piece is then slowed uniformly until it meets them at five points of every interval
    between gridpoints too, before its duration is compared with stopping at the corners. Any
    residual excess at the returned samples is removed by slowing the whole motion uniformly,
    so every sample meets the limits (to a relative 1e-9, for rounding).

    Args:
        path: (N, n) waypoints (rad or m), N >= 1.
        velocity_limits: (n,) or scalar, > 0 (rad/s or m/s), e.g. from :func:`model_limits`.
        acceleration_limits: (n,) or scalar, > 0 (rad/s^2 or m/s^2).
        dt: sampling period (s) of the result.
        blend_check: motion check ``(qa (n,), qb (n,)) -> bool`` enabling corner blending.
        blend_step: largest joint change (rad or m, max-norm) between checked spline samples.
        joint_names: names of the n joints, stored in the trajectory.

    Returns:
        :class:`Trajectory` sampled every ``dt`` (the last step ends exactly at the duration);
        a path that is a single configuration gives a one-sample trajectory of duration 0.

    Raises:
        PrehensileError: malformed path or limits, a non-positive ``dt``, or more than
            :data:`MAX_SAMPLES` samples.
    """
    path = np.asarray(path, dtype=float)
    if path.ndim != 2 or len(path) == 0 or path.shape[1] == 0 or not np.all(np.isfinite(path)):
        raise PrehensileError(f"time_parameterize: path must be a finite (N >= 1, n >= 1) array, "
                              f"got shape {path.shape}")
    n = path.shape[1]
    limits = []
    for name, value in (("velocity_limits", velocity_limits), ("acceleration_limits", acceleration_limits)):
        value = np.asarray(value, dtype=float)
        if value.ndim > 1 or value.size not in (1, n) or not np.all(np.isfinite(value) & (value > 0)):
            raise PrehensileError(f"time_parameterize: {name} must be a scalar or ({n},) positive finite numbers, "
                                  f"got {value}")
        limits.append(np.broadcast_to(value, (n,)).copy())
    velocity, acceleration = limits
    check_value("time_parameterize: dt", dt, FINITE_POSITIVE)
    check_value("time_parameterize: blend_step", blend_step, POSITIVE)
    corners = _corners(path)
    if len(corners) == 1:
        zero = np.zeros((1, n))
        return Trajectory(np.zeros(1), corners, zero, zero, tuple(joint_names))
    profiles = _profiles(corners, velocity, acceleration, blend_check, blend_step)
    if blend_check is not None and len(profiles) < len(corners) - 1:
        log.info("time_parameterize: %d blended pieces, at rest between them", len(profiles))
    pieces, ss, sd, piece_of, durations, starts = _intervals(profiles)
    # residual limit excess (numerical: each piece meets the limits at the probes), then on the samples
    scale = _probed_excess(pieces, ss, sd, piece_of, durations, starts, velocity, acceleration)
    while True:
        scaled_starts, total = starts * scale, float(np.sum(durations)) * scale
        if total / dt > MAX_SAMPLES:
            raise PrehensileError(f"time_parameterize: the motion takes {total:.4g} s, {total / dt:.4g} samples at "
                                  f"dt = {dt:g} s, more than {MAX_SAMPLES}: raise dt or the limits")
        t = np.append(np.arange(max(int(np.ceil(total / dt - 1e-6)), 1)) * dt, total)
        q, qd, qdd = _evaluate(pieces, ss, sd / scale, piece_of, scaled_starts, t)
        more = _excess(qd, qdd, velocity, acceleration)
        if more <= 1.0 + 1e-9:
            break
        scale *= max(more, 1.001)  # the new samples lie elsewhere: at least 0.1 % per round, so this ends
    q[0], q[-1], qd[0], qd[-1], qdd[-1] = corners[0], corners[-1], 0.0, 0.0, 0.0
    motion = functools.partial(_evaluate, pieces, ss, sd / scale, piece_of, scaled_starts)
    return Trajectory(t, q, qd, qdd, tuple(joint_names), motion)


def _profiles(corners: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray,
              check: Callable[[np.ndarray, np.ndarray], bool] | None, step: float) -> list[tuple]:
    """Rest-to-rest pieces through the corners (M, n), each with its profile (gridpoints s (G,),
    path speeds sd (G,), constant path acceleration between them): the straight segments, or
    with ``check`` the spline through the corners (:func:`_spline`) if it passes and is faster
    than stopping at them; a spline that fails the check (or that TOPP-RA cannot time) is split
    at its middle corner."""
    lines = [(line, *_line_knots(line, velocity, acceleration))
             for line in (_Line(a, b) for a, b in zip(corners[:-1], corners[1:]))]
    if check is None or len(corners) < 3:
        return lines
    blended = _spline(corners, check, step)
    knots = None if blended is None else _toppra_knots(blended[0], velocity, acceleration, blended[1])
    if knots is None:
        middle = len(corners) // 2
        return (_profiles(corners[:middle + 1], velocity, acceleration, check, step)
                + _profiles(corners[middle:], velocity, acceleration, check, step))
    spline = _slowed((blended[0], *knots), velocity, acceleration)
    if _duration(*spline[1:]) < sum(_duration(s, sd) for _, s, sd in lines):
        return [spline]
    return lines  # a spline that turns back on itself can be slower than stopping


def _duration(s: np.ndarray, sd: np.ndarray) -> float:
    """Duration (s) of a profile: gridpoints s (G,), path speeds sd (G,)."""
    return float(np.sum(2.0 * np.diff(s) / (sd[:-1] + sd[1:])))


def _intervals(profiles: list[tuple]):
    """The profiles' intervals of constant path acceleration, in order: (pieces, gridpoints ss
    (K, 2), path speeds sd (K, 2) at both ends, piece of each (K,), durations (K,) (s), start
    times (K,) (s))."""
    pieces = [piece for piece, _, _ in profiles]
    ss = np.concatenate([np.stack([s[:-1], s[1:]], axis=1) for _, s, _ in profiles])
    sd = np.concatenate([np.stack([v[:-1], v[1:]], axis=1) for _, _, v in profiles])
    piece_of = np.concatenate([np.full(len(s) - 1, p) for p, (_, s, _) in enumerate(profiles)])
    durations = 2.0 * (ss[:, 1] - ss[:, 0]) / (sd[:, 0] + sd[:, 1])
    return pieces, ss, sd, piece_of, durations, np.concatenate([[0.0], np.cumsum(durations)[:-1]])


def _probed_excess(pieces, ss, sd, piece_of, durations, starts, velocity, acceleration) -> float:
    """:func:`_excess` of the motion of :func:`_intervals` at five points of every interval."""
    probe = (starts[:, None] + durations[:, None] * np.array([0.0, 0.25, 0.5, 0.75, 1 - 1e-9])).ravel()
    return _excess(*_evaluate(pieces, ss, sd, piece_of, starts, probe)[1:], velocity, acceleration)


def _slowed(profile: tuple, velocity: np.ndarray, acceleration: np.ndarray) -> tuple:
    """A piece's profile (piece, s, sd) slowed down uniformly to meet the limits at the probes
    of :func:`_probed_excess`: TOPP-RA meets them only at its gridpoints, and a spline's
    curvature between them can take its acceleration well past them."""
    piece, s, sd = profile
    return piece, s, sd / _probed_excess(*_intervals([profile]), velocity, acceleration)


def _excess(qd: np.ndarray, qdd: np.ndarray, velocity: np.ndarray, acceleration: np.ndarray) -> float:
    """Factor (>= 1) by which slowing a motion down uniformly brings velocities qd and
    accelerations qdd (M, n) within the limits (n,): velocities scale with its inverse,
    accelerations with its inverse square."""
    return max(1.0, float(np.max(np.abs(qd) / velocity)), float(np.sqrt(np.max(np.abs(qdd) / acceleration))))
