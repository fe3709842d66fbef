"""FABRIK on general revolute chains, with joint limits and tip orientation.

FABRIK (Aristidou & Lasenby 2011, Graphical Models 73(5); Bischoff 2016 §3.5) moves joint
*positions*: forward reaching puts the tip on the target and walks to the base, each point
going onto the line to its old position at its segment's length; backward reaching pins the
base and walks back. Robot chains have single revolute axes, offsets and limits, so here the
joints carry out the backward pass and the solver only ever holds exact FK configurations:

1. Points: the distinct joint origins (coincident consecutive ones, e.g. the NAO shoulder,
   share one) and the tip, with constant segment lengths d_i.
2. Forward reaching (AL11 Algorithm 1; the backward update is p_{i+1}, not Bischoff's p_i):
   ``r_m = t``, ``r_i = r_{i+1} + d_i (p_i - r_{i+1}) / |p_i - r_{i+1}|``.
3. Backward reaching, base to tip: joint j turns about its own world axis a (through its origin
   o) to the angle that brings the points downstream closest, in least squares, to their
   forward-reaching places; with u_k = p_k - o, v_k = r_k - o,

   .. math:: \\Delta\\theta = \\operatorname{atan2}\\Big(\\sum_k a\\cdot(u_k\\times v_k),\\;
             \\sum_k u_k\\cdot v_k - (a\\cdot u_k)(a\\cdot v_k)\\Big).

   The angle goes into the limits at once (Bischoff §3.5 enforces them every iteration; plain
   FABRIK breaks the NAO limits in about a third of cases, §4.5): its 2π-equivalent within the
   limits, else the nearer limit -- the constrained optimum of this one-axis fit. The turn is
   carried rigidly downstream (FK is recomputed from q every iteration). Fitting only the next
   point (the literal update, equivalent on ball joints) stalled in our trials on hinge chains
   with offsets (Panda 0 % success, ARMAR-III TorsoRightArm 9-22 %).
4. Stop within ``tolerance`` (and ``rotation_tolerance``), at ``max_iterations``, or when the
   error has not fallen by 1 % in ``stall_iterations``; the best configuration seen is kept.

Orientation: a target rotation R places the tip link, so forward reaching pins the last joint
point (fixed in the tip frame at c) at ``t + R c``; if that point has a single joint, the point
before it goes onto the joint's circle (its axis is fixed in the tip frame). The tip frame axes,
scaled to ``orientation_weight * reach`` m, join the fitted points. Rotation error: the angle
of ``R^T R_tip``.

Reachability (AL11's first test): the tip stays in the shell ``max(0, 2 max(d) - sum(d)) <=
|t - p_0| <= sum(d)`` (with R, so does the pinned point for the segments before it); outside it
a target is UNREACHABLE and the iterations stretch the chain toward it. Prismatic joints and
mimic joints on the chain (they would move while the fit holds them rigid) are refused.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from prehensile.clock import clock
from prehensile.errors import PrehensileError
from prehensile.ik.result import IKResult, IKStatus, check_target_positions
from prehensile.kinematics import forward_kinematics
from prehensile.kinematics.kernels import FAST, PRISMATIC, fk_into
from prehensile.model.robot_model import RobotModel
from prehensile.settings import POSITIVE, at_least, check_fields
from prehensile.spatial.transforms import check_pose

CONVERGED, NOT_CONVERGED, UNREACHABLE = 0, 1, 2
_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True)
class FabrikSettings:
    """Settings of :func:`fabrik`.

    Attributes:
        tolerance: tip position tolerance, m.
        rotation_tolerance: tip orientation tolerance, rad (with ``target_orientation``).
        max_iterations: cap on forward/backward iterations per target position.
        stall_iterations: stop when the error has not fallen by 1 % over this many iterations.
        orientation_weight: length of the tip frame axes in the fit, as a fraction of the
            chain's reach (weighs orientation against position while converging).
    """

    tolerance: float = 1e-4
    rotation_tolerance: float = 1e-3
    max_iterations: int = 1000
    stall_iterations: int = 50
    orientation_weight: float = 0.25

    def __post_init__(self) -> None:
        check_fields(self, **dict.fromkeys(("tolerance", "rotation_tolerance", "orientation_weight"), POSITIVE),
                     max_iterations=at_least(1), stall_iterations=at_least(1))


@njit(cache=True, fastmath=FAST)
def _norm(x, y, z):
    return np.sqrt(x * x + y * y + z * z)


@njit(cache=True, fastmath=FAST)
def _errors(p, axes, target, target_axes, has_rot):
    """Position error (m) of tip position p (3,); rotation angle (rad) between the tip frame
    axes (3, 3) (row c: axis c in the world) and the target's."""
    pos = _norm(p[0] - target[0], p[1] - target[1], p[2] - target[2])
    if not has_rot:
        return pos, 0.0
    M = np.empty((3, 3))  # R_target^T R_tip
    for r in range(3):
        for c in range(3):
            M[r, c] = target_axes[r, 0] * axes[c, 0] + target_axes[r, 1] * axes[c, 1] + target_axes[r, 2] * axes[c, 2]
    sin2 = _norm(M[2, 1] - M[1, 2], M[0, 2] - M[2, 0], M[1, 0] - M[0, 1])
    return pos, np.arctan2(0.5 * sin2, 0.5 * (M[0, 0] + M[1, 1] + M[2, 2] - 1.0))


@njit(cache=True, fastmath=FAST)
def _within_limits(angle, lo, hi):
    """The best angle in [lo, hi] (rad) for a one-axis fit whose optimum is ``angle``."""
    if hi - lo >= _TWO_PI:  # every direction is available
        if angle > hi:
            angle -= _TWO_PI
        if angle < lo:
            angle += _TWO_PI
        if not (np.isfinite(lo) or np.isfinite(hi)):  # continuous: keep q in (-pi, pi]
            angle = (angle + np.pi) % _TWO_PI - np.pi
        return angle
    shifted = angle + _TWO_PI * np.ceil((lo - angle) / _TWO_PI)
    if shifted <= hi:
        return shifted
    to_lo = abs((angle - lo + np.pi) % _TWO_PI - np.pi)
    to_hi = abs((angle - hi + np.pi) % _TWO_PI - np.pi)
    return lo if to_lo <= to_hi else hi


@njit(cache=True, fastmath=FAST)
def _fit(S, C, a, x, y, o, w):
    """Add the terms (weight w) of turning x (3,) onto y (3,) about the axis a through o."""
    u0, u1, u2 = x[0] - o[0], x[1] - o[1], x[2] - o[2]
    v0, v1, v2 = y[0] - o[0], y[1] - o[1], y[2] - o[2]
    S += w * (a[0] * (u1 * v2 - u2 * v1) + a[1] * (u2 * v0 - u0 * v2) + a[2] * (u0 * v1 - u1 * v0))
    C += w * (u0 * v0 + u1 * v1 + u2 * v2 - (a[0] * u0 + a[1] * u1 + a[2] * u2) * (a[0] * v0 + a[1] * v1 + a[2] * v2))
    return S, C


@njit(cache=True, fastmath=FAST)
def _rotate(R, x, o):
    """x (3,) <- o + R (x - o), in place."""
    x0, x1, x2 = x[0] - o[0], x[1] - o[1], x[2] - o[2]
    for r in range(3):
        x[r] = o[r] + R[r, 0] * x0 + R[r, 1] * x1 + R[r, 2] * x2


@njit(cache=True, fastmath=FAST)
def _axis_rotation(a, angle, R):
    """R (3, 3) <- rotation by ``angle`` about the unit axis a (Rodrigues)."""
    c, s = np.cos(angle), np.sin(angle)
    t = 1.0 - c
    x, y, z = a[0], a[1], a[2]
    R[0, 0], R[0, 1], R[0, 2] = t * x * x + c, t * x * y - s * z, t * x * z + s * y
    R[1, 0], R[1, 1], R[1, 2] = t * x * y + s * z, t * y * y + c, t * y * z - s * x
    R[2, 0], R[2, 1], R[2, 2] = t * x * z - s * y, t * y * z + s * x, t * z * z + c


@njit(cache=True, fastmath=FAST)
def _to_target(target_axes, axes, x, out):
    """out (3,) += x (3,), a world vector fixed to the tip frame (axes), moved with it to the target axes."""
    for c in range(3):
        in_tip = axes[c, 0] * x[0] + axes[c, 1] * x[1] + axes[c, 2] * x[2]
        for r in range(3):
            out[r] += target_axes[c, r] * in_tip


@njit(cache=True, fastmath=FAST)
def _state(q, T_base, table, joint_link, point_link, frames, axis, origin, points, axes):
    """Exact chain FK, then world joint axes and origins (n, 3), points (m + 1, 3) and the tip
    frame axes (3, 3) (row c: axis c)."""
    fk_into(q, T_base, table, frames)
    for j in range(joint_link.shape[0]):
        k = joint_link[j]
        F = frames[k]
        for r in range(3):
            axis[j, r] = F[r, 0] * table[k, 5] + F[r, 1] * table[k, 6] + F[r, 2] * table[k, 7]
            origin[j, r] = F[r, 3]
    for r in range(3):
        for p in range(points.shape[0]):
            points[p, r] = frames[point_link[p], r, 3]
        for c in range(3):
            axes[c, r] = frames[-1, r, c]


@njit(cache=True, fastmath=FAST)
def _outside_shell(x, base, seg, count):
    """True if x (3,) is provably out of reach of the first ``count`` segments hinged at base."""
    distance = _norm(x[0] - base[0], x[1] - base[1], x[2] - base[2])
    reach = longest = 0.0
    for i in range(count):
        reach += seg[i]
        longest = max(longest, seg[i])
    return distance > reach * (1.0 + 1e-12) + 1e-12 or distance < 2.0 * longest - reach - 1e-12


@njit(cache=True, fastmath=FAST)
def solve_chain(q, T_base, table, joint_link, joint_q, lower, upper, target, target_axes, has_rot,
                orientation_weight, tol, rot_tol, max_iterations, stall_iterations):
    """FABRIK on one chain (see the module docstring), in place on the full configuration q (dof,).

    ``T_base`` (4, 4): world pose of the chain's base link; ``table`` (P, 20): the chain table of
    :func:`_pack`; ``joint_link``, ``joint_q`` (n,): chain row and q index of each solved joint,
    base to tip; ``lower``, ``upper`` (n,): limits (rad); ``target`` (3,) (m); ``target_axes``
    (3, 3): the target tip frame axes as rows (used if ``has_rot``). Returns (CONVERGED /
    NOT_CONVERGED / UNREACHABLE, iterations, position error m, rotation error rad) of the best
    configuration seen, which is left in q.
    """
    P, n = table.shape[0], joint_link.shape[0]
    frames = np.empty((P, 4, 4))
    fk_into(q, T_base, table, frames)  # q was checked finite by the caller
    point_link, point_of = np.empty(n + 1, np.int64), np.zeros(n, np.int64)
    point_link[0], m = joint_link[0], 1
    for j in range(1, n):  # consecutive joints with coincident origins share a point
        F, G = frames[joint_link[j]], frames[point_link[m - 1]]
        if _norm(F[0, 3] - G[0, 3], F[1, 3] - G[1, 3], F[2, 3] - G[2, 3]) > 1e-9:
            point_link[m] = joint_link[j]
            m += 1
        point_of[j] = m - 1
    point_link[m] = P - 1
    point_link = point_link[: m + 1]
    axis, origin = np.empty((n, 3)), np.empty((n, 3))
    points, reached = np.empty((m + 1, 3)), np.empty((m + 1, 3))
    axes, R, zero, v = np.empty((3, 3)), np.empty((3, 3)), np.zeros(3), np.empty(3)
    _state(q, T_base, table, joint_link, point_link, frames, axis, origin, points, axes)
    seg = np.empty(m)
    reach = 0.0
    for i in range(m):
        a, b = points[i], points[i + 1]
        seg[i] = _norm(b[0] - a[0], b[1] - a[1], b[2] - a[2])
        reach += seg[i]
    scale = orientation_weight * reach
    unreachable = _outside_shell(target, points[0], seg, m)

    # with an orientation: the last joint point's place, and the circle of the point before it
    pinned, hinge_axis, along, radius = np.zeros(3), np.zeros(3), 0.0, 0.0
    hinge = has_rot and m >= 2 and (n == 1 or point_of[n - 2] != point_of[n - 1])
    if has_rot:
        for r in range(3):
            pinned[r] = target[r]
            v[r] = points[m - 1, r] - points[m, r]
        _to_target(target_axes, axes, v, pinned)
        unreachable = unreachable or _outside_shell(pinned, points[0], seg, m - 1)
    if hinge:
        _to_target(target_axes, axes, axis[n - 1], hinge_axis)
        for r in range(3):
            along += (points[m - 2, r] - points[m - 1, r]) * axis[n - 1, r]
        radius = np.sqrt(max(seg[m - 2] ** 2 - along ** 2, 0.0))

    best_q = np.empty(n)
    for j in range(n):
        best_q[j] = q[joint_q[j]]
    pos_err, rot_err = _errors(points[m], axes, target, target_axes, has_rot)
    best = reference = pos_err + scale * rot_err
    iterations = stalled = 0
    while not (pos_err <= tol and rot_err <= rot_tol) and iterations < max_iterations and stalled < stall_iterations:
        iterations += 1
        if iterations > 1:
            _state(q, T_base, table, joint_link, point_link, frames, axis, origin, points, axes)
        # forward reaching: tip on the target (last joint point pinned), toward the base
        first = m - 2 if has_rot else m - 1
        for r in range(3):
            reached[m, r] = target[r]
            if has_rot:
                reached[m - 1, r] = pinned[r]
        if hinge:  # onto the last joint's circle: the offset from pinned without its axial part
            for r in range(3):
                v[r] = points[m - 2, r] - pinned[r]
            dot = v[0] * hinge_axis[0] + v[1] * hinge_axis[1] + v[2] * hinge_axis[2]
            for r in range(3):
                v[r] -= dot * hinge_axis[r]
            norm = _norm(v[0], v[1], v[2])
            if norm > 1e-12:
                for r in range(3):
                    reached[m - 2, r] = pinned[r] + along * hinge_axis[r] + radius / norm * v[r]
                first = m - 3
        for i in range(first, -1, -1):
            x = reached[i + 1]
            if _norm(points[i, 0] - x[0], points[i, 1] - x[1], points[i, 2] - x[2]) < 1e-12:
                x = points[i + 1]  # on top of the next point: keep the old segment direction
            dx, dy, dz = points[i, 0] - x[0], points[i, 1] - x[1], points[i, 2] - x[2]
            lam = seg[i] / max(_norm(dx, dy, dz), 1e-300)
            reached[i, 0] = reached[i + 1, 0] + lam * dx
            reached[i, 1] = reached[i + 1, 1] + lam * dy
            reached[i, 2] = reached[i + 1, 2] + lam * dz
        # backward reaching, carried out by the joints from the base to the tip
        for j in range(n):
            a, o = axis[j], origin[j]
            S = C = 0.0
            for p in range(point_of[j] + 1, m + 1):
                S, C = _fit(S, C, a, points[p], reached[p], o, 1.0)
            if has_rot:
                for c in range(3):
                    S, C = _fit(S, C, a, axes[c], target_axes[c], zero, scale * scale)
            if S * S + C * C <= 1e-24 * reach ** 4:  # nothing downstream lies off this axis
                continue
            qi = joint_q[j]
            angle = _within_limits(q[qi] + np.arctan2(S, C), lower[j], upper[j])
            if angle == q[qi]:
                continue
            _axis_rotation(a, angle - q[qi], R)
            q[qi] = angle
            for i in range(j + 1, n):
                _rotate(R, axis[i], zero)
                _rotate(R, origin[i], o)
            for p in range(point_of[j] + 1, m + 1):
                _rotate(R, points[p], o)
            for c in range(3):
                _rotate(R, axes[c], zero)
        pos_err, rot_err = _errors(points[m], axes, target, target_axes, has_rot)
        score = pos_err + scale * rot_err
        if score < best:
            best = score
            for j in range(n):
                best_q[j] = q[joint_q[j]]
        if score < 0.99 * reference:
            reference, stalled = score, 0
        else:
            stalled += 1
    for j in range(n):
        q[joint_q[j]] = best_q[j]
    _state(q, T_base, table, joint_link, point_link, frames, axis, origin, points, axes)
    pos_err, rot_err = _errors(points[m], axes, target, target_axes, has_rot)
    if pos_err <= tol and rot_err <= rot_tol:
        return CONVERGED, iterations, pos_err, rot_err
    return UNREACHABLE if unreachable else NOT_CONVERGED, iterations, pos_err, rot_err


@lru_cache(maxsize=64)
def _pack(model: RobotModel, chain: str) -> tuple[int, np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """(base link index, chain table (P, 20), joint rows (n,), q indices (n,), lower (n,), upper (n,)).

    The table holds the ``model.joint_table`` rows of the links after the base up to the tip,
    each link's parent re-indexed to the row before it (-1: the base).
    """
    spec = model.chain(chain)
    base = model.link_index(spec.base_link)
    path = model.path_to_root(spec.tip_link)
    path = path[: path.index(base)][::-1]
    solved = {model.joint_index(name) for name in spec.joint_names}
    rows, q_index = [], []
    for row, link in enumerate(path):
        qi = int(model.joint_q_index[link])
        if qi not in solved:
            continue  # held at the seed's value
        if model.mimic_of(link) is not None:  # the fit would place it as if it stayed rigid
            raise PrehensileError(f"fabrik: chain '{chain}' of robot '{model.name}' has mimic joint "
                                  f"'{model.link_joint_names[link]}' (follows {model.mimic_of(link)}), which FABRIK "
                                  "cannot follow; use a Jacobian method")
        if model.joint_type[link] == PRISMATIC:
            raise PrehensileError(f"fabrik: chain '{chain}' of robot '{model.name}' has prismatic joint "
                                  f"'{model.joint_names[qi]}'; FABRIK here solves revolute joints only")
        rows.append(row)
        q_index.append(qi)
    if solved - set(q_index):
        names = ", ".join(model.joint_names[i] for i in sorted(solved - set(q_index)))
        raise PrehensileError(f"fabrik: joints {names} of chain '{chain}' are not on the path "
                              f"{spec.base_link} -> {spec.tip_link} of robot '{model.name}'")
    if not rows:
        raise PrehensileError(f"fabrik: chain '{chain}' of robot '{model.name}' has no joints to solve")
    table = np.array(model.joint_table[path])
    table[:, 0] = np.arange(-1, len(path) - 1)
    q_index = np.array(q_index, dtype=np.int64)
    rows = np.array(rows, dtype=np.int64)
    return base, table, rows, q_index, model.lower[q_index].copy(), model.upper[q_index].copy()


def fabrik(model: RobotModel, chain: str, target: np.ndarray, q_seed: np.ndarray | None = None,
           settings: FabrikSettings = FabrikSettings(), target_orientation: np.ndarray | None = None) -> IKResult:
    """FABRIK IK of ``chain``'s tip toward a position, and optionally an orientation.

    Args:
        model: the robot; targets are in its root frame.
        chain: a chain of ``model`` (revolute joints; other joints on its path keep the seed's values).
        target: tip position (3,) or a set (k, 3) (m), any one of which will do (tried in order).
        q_seed: (dof,) start; the chain's joints are clipped into their limits. None: the
            neutral configuration with the chain's joints at the middle of their limits (a bent
            start, away from the straight-arm singularity of e.g. the NAO's zero pose).
        settings: :class:`FabrikSettings`.
        target_orientation: (3, 3) rotation of the tip frame in the root frame, or None.

    Returns:
        :class:`~prehensile.ik.result.IKResult`: SUCCESS; UNREACHABLE when every target is out
        of the chain's reach (``q`` stretched toward the best one); NOT_CONVERGED otherwise.
        ``q`` is always within the joint limits.

    Raises:
        PrehensileError: a NaN or malformed target, orientation or seed; an unsupported chain.
    """
    start = clock()
    targets = check_target_positions(target)
    has_rot, target_axes = target_orientation is not None, np.eye(3)
    if has_rot:
        if np.shape(target_orientation) != (3, 3):
            raise PrehensileError(f"target_orientation: expected (3, 3), got shape {np.shape(target_orientation)}")
        pose = np.eye(4)
        pose[:3, :3] = target_orientation
        target_axes = np.ascontiguousarray(check_pose(pose, "target_orientation")[:3, :3].T)  # row c: axis c
    base, table, joint_link, joint_q, lower, upper = _pack(model, chain)
    if q_seed is None:
        seed = model.neutral_configuration()
        limited = np.isfinite(lower) & np.isfinite(upper)
        seed[joint_q[limited]] = 0.5 * (lower[limited] + upper[limited])
    else:
        seed = np.array(model.check_configuration(q_seed, "q_seed"), dtype=float)
        seed[joint_q] = np.clip(seed[joint_q], lower, upper)
    T_base = forward_kinematics(model, seed)[base]

    best, iterations, all_unreachable = None, 0, True
    for index, point in enumerate(targets):
        q = seed.copy()
        status, its, pos_err, rot_err = solve_chain(
            q, T_base, table, joint_link, joint_q, lower, upper, point, target_axes, has_rot,
            settings.orientation_weight, settings.tolerance, settings.rotation_tolerance, settings.max_iterations,
            settings.stall_iterations)
        iterations += its
        all_unreachable &= status == UNREACHABLE
        if best is None or status == CONVERGED or pos_err + rot_err < best[3] + best[4]:
            best = (index, status, q, pos_err, rot_err)
        if status == CONVERGED:
            break
    index, status, q, pos_err, rot_err = best
    if status == CONVERGED:
        outcome, solutions = IKStatus.SUCCESS, q[None].copy()
    else:
        outcome = IKStatus.UNREACHABLE if all_unreachable else IKStatus.NOT_CONVERGED
        solutions = np.zeros((0, model.dof))
    return IKResult(outcome, q, solutions, float(pos_err), float(rot_err), int(iterations),
                    clock() - start, int(index))
