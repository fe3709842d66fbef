r"""Closed-form inverse kinematics of the NAO arms: 4 DoF, and 5 DoF with WristYaw.

Bischoff 2016 §3.4 recommends the analytic arm IK of Kofinas, Orfanoudakis and Lagoudakis
("Complete analytical inverse kinematics for NAO", 2013), derived for the thesis's simplified
chain and in need of the digest's corrections (§1.5, §3.4). This module solves the *exact*
chain (digest §1.5(5), §1.6: ElbowOffsetY inside the chain, HandOffsetZ) geometrically and
keeps Kofinas's last steps: drop candidates outside the limits, verify every one by FK. All
parameters are read from the model. In the ShoulderPitch joint frame S the tip pose
:math:`(R, p)` is

.. math::

    T_S^{-1} T = R_y(\theta_1) R_z(\theta_2)\,\mathrm{Tr}(u)\,R_x(\theta_3) R_z(\theta_4)
    \,[\mathrm{Tr}(l\hat x)\,R_x(\theta_5)]\,T_c

with u = (UpperArmLength, ±ElbowOffsetY, 0), l = LowerArmLength (bracket only for 5 DoF) and
the fixed tip :math:`T_c = (R_c, t_c)`: (LowerArmLength + HandOffsetX, 0, −HandOffsetZ) in the
forearm for ``*_arm_tip``, (HandOffsetX, 0, −HandOffsetZ) in the wrist for ``*_gripper``.

**1. Elbow.** ElbowYaw and ElbowRoll meet at :math:`E = R_y R_z u`, and the WristYaw axis
(forearm x) passes through E, so E follows from the target alone:
:math:`E^* = p - R f`, :math:`f = R_c^\top (l\hat x + t_c)`.

**2. Position-exact elbow.** Reachable positions put E on the circle
:math:`C = \{E : |E| = |u|,\ |p - E| = |f|\}`; E* is replaced by its nearest point on C
(swivel ψ = 0). A consistent target is unchanged; an inconsistent one keeps its position
exactly (the 4-DoF arm reaches a 4-D subset of SE(3), the 5-DoF arm a 5-D one), and:

* 5 DoF: R becomes :math:`R' = R_a R`, :math:`R_a` the smallest rotation taking Rf to p − E:
  the least orientation change of all position-exact poses (up to branches and limits).
* 4 DoF: the swivel is the only freedom left. A candidate with a rotation error over 1e-10
  rad gets three Gauss-Newton steps on ψ (finite-difference derivative) that minimise it: the
  module's only iteration, reached only by inconsistent 4-DoF targets (without it the error
  grew to 30-50 δ near the stretched arm, where C is small).

Measured with orientations perturbed by δ = 1e-8 … 0.5 rad: position error ≤ 2e-16 m,
rotation error ≤ δ, both chains; UNREACHABLE when it exceeds the tolerance.

**3. Shoulder.** With the branch sign of :math:`m = \pm\sqrt{E_x^2 + E_z^2 - u_z^2}`:
:math:`\theta_2 = \operatorname{atan2}(E_y, m) - \operatorname{atan2}(u_y, u_x)`,
:math:`\theta_1 = \operatorname{atan2}(u_z, m) - \operatorname{atan2}(E_z, E_x)`; singular
only for m = u_z = 0 (upper arm along the pitch axis, |θ2| = 1.43 rad, outside the limits).

**4a. Forearm, 4 DoF.** :math:`g = (R_y R_z)^\top (p - E) = R_x(\theta_3) R_z(\theta_4) t_c`,
so with the elbow sign of :math:`\sigma = \pm\sqrt{g_y^2 + g_z^2 - t_{c,z}^2}`:
:math:`\theta_4 = \operatorname{atan2}(\sigma, g_x) - \operatorname{atan2}(t_{c,y}, t_{c,x})`,
:math:`\theta_3 = \operatorname{atan2}(g_z, g_y) - \operatorname{atan2}(t_{c,z}, \sigma)`.
Both signs reach p; FK keeps the one matching R. HandOffsetZ keeps θ3 defined when straight.

**4b. Forearm and wrist, 5 DoF.** X-Z-X Euler angles of :math:`M = (R_y R_z)^\top R' R_c^\top
= R_x(\theta_3) R_z(\theta_4) R_x(\theta_5)` with the elbow sign of
:math:`s_4 = \pm\sqrt{M_{10}^2 + M_{20}^2}`: :math:`\theta_4 = \operatorname{atan2}(s_4, M_{00})`,
:math:`\theta_3 = \operatorname{atan2}(M_{20} / s_4, M_{10} / s_4)`,
:math:`\theta_5 = \operatorname{atan2}(M_{02} / s_4, -M_{01} / s_4)`; singular only for a
straight arm, which the ElbowRoll limit (|θ4| ≥ 2°) excludes. So the 5-DoF chain has a closed
form without search: the WristYaw axis passes through E, and f absorbs HandOffsetZ.

**5. Limits, verification.** Each angle is shifted by a multiple of 2π into its limits (within
1e-9 rad, then clipped) or the candidate dropped; survivors are verified by FK within the
tolerances, duplicates removed.

**Solutions.** 2 shoulder × 2 elbow branches: at most :data:`MAX_SOLUTIONS` = 4 (Bischoff's
"8" counts arccos/arcsin signs that FK rejects). Without limits a pose has 4 solutions for 5
DoF and generically 1 for 4 DoF (on the other shoulder branch the ElbowRoll axis cannot be
normal to both arm segments); measured on 2000 poses each. The NAO limits leave at most one:
the other shoulder branch has :math:`|\theta_2'| = |\pi - 2\arctan(15/105) - |\theta_2|| \ge
1.53` rad > 1.3265 rad, and ElbowRoll has one sign per side. For limits wider than 2π one
representative of each angle is returned.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache

import numpy as np
from numba import njit

from prehensile.clock import clock
from prehensile.errors import PrehensileError
from prehensile.ik.result import IKResult, IKStatus, check_target_poses
from prehensile.kinematics import link_pose
from prehensile.model.robot_model import FIXED, REVOLUTE, RobotModel
from prehensile.spatial.transforms import rotation_error

MAX_SOLUTIONS = 4
_AXES = ((0.0, 1.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0), (0.0, 0.0, 1.0), (1.0, 0.0, 0.0))
_ROLES = ("ShoulderPitch (axis y)", "ShoulderRoll (axis z)", "ElbowYaw (axis x)", "ElbowRoll (axis z)",
          "WristYaw (axis x)")
_LIMIT_SLACK = 1e-9  # rad: angles this far outside a limit count as on it
_SAME = 1e-9         # rad: candidates closer than this are duplicates
_CONSISTENT = 1e-10  # rad: a larger rotation error of a 4-DoF candidate starts the swivel search
_SWIVEL_STEPS = 3    # Gauss-Newton steps on the swivel of an inconsistent 4-DoF target
_SWIVEL_STEP = 1e-6  # rad: finite-difference step of the swivel derivative
_TWO_PI = 2.0 * np.pi


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class _Arm:
    """Parameters of one NAO-type arm chain, read from the model (m, rad)."""

    q_indices: np.ndarray   # (n,) indices of the chain joints in q
    tip: str                # tip link
    T_S_inv: np.ndarray     # (4, 4) inverse pose of the ShoulderPitch joint frame S in the model root
    u: np.ndarray           # (3,) ElbowYaw origin in the ShoulderRoll frame
    wrist_offset: float     # l: WristYaw origin along the forearm x axis (0 for 4 DoF)
    R_c: np.ndarray         # (3, 3) rotation of the tip in the frame of the last joint
    t_c: np.ndarray         # (3,) position of the tip in the frame of the last joint
    f: np.ndarray           # (3,) elbow point to tip, in tip coordinates: p - R f is the elbow
    lower: np.ndarray       # (n,)
    upper: np.ndarray       # (n,)


def _not_nao(model: RobotModel, chain: str, reason: str) -> PrehensileError:
    return PrehensileError(
        f"robot '{model.name}', chain '{chain}': not a NAO-type arm ({reason}); expected joints "
        f"{', '.join(_ROLES[:4])}[, {_ROLES[4]}] with intersecting shoulder and elbow axes and the "
        "WristYaw axis through the elbow"
    )


@lru_cache(maxsize=32)
def _arm(model: RobotModel, chain: str) -> _Arm:
    """Read and check the arm parameters of ``chain``; raises PrehensileError for other chains."""
    spec = model.chain(chain)
    n = len(spec.joint_names)
    if n not in (4, 5):
        raise _not_nao(model, chain, f"{n} joints instead of 4 or 5")
    origins, T = [], np.eye(4)
    for link in model.path_to_root(spec.tip_link)[-2::-1]:  # root (excluded) to tip
        T = T @ model.joint_origin[link]
        if model.joint_type[link] == FIXED:
            continue
        k, name = len(origins), model.link_joint_names[link]
        if model.joint_type[link] != REVOLUTE or k >= n or name != spec.joint_names[k]:
            raise _not_nao(model, chain, f"unexpected joint '{name}' on the path to the tip")
        if model.mimic_of(link):
            raise _not_nao(model, chain, f"joint '{name}' is a mimic joint")
        if not np.allclose(model.joint_axis[link], _AXES[k], atol=1e-9):
            raise _not_nao(model, chain, f"joint '{name}' has axis {model.joint_axis[link]}, expected {_ROLES[k]}")
        if k > 0 and not np.allclose(T[:3, :3], np.eye(3), atol=1e-9):
            raise _not_nao(model, chain, f"joint '{name}' has a rotated origin")
        origins.append(T)
        T = np.eye(4)
    if len(origins) != n:
        raise _not_nao(model, chain, f"{len(origins)} of its {n} joints lie on the path to the tip")
    offsets = [o[:3, 3] for o in origins]
    if np.any(np.abs(offsets[1]) > 1e-9) or np.any(np.abs(offsets[3]) > 1e-9):
        raise _not_nao(model, chain, "ShoulderRoll / ElbowRoll origins are not on the previous joint")
    if n == 5 and np.any(np.abs(offsets[4][1:]) > 1e-9):
        raise _not_nao(model, chain, "the WristYaw axis misses the elbow point")
    q_indices, l = model.chain_q_indices(chain), float(offsets[4][0]) if n == 5 else 0.0
    return _Arm(q_indices=q_indices, tip=spec.tip_link, T_S_inv=np.linalg.inv(origins[0]), u=offsets[2].copy(),
                wrist_offset=l, R_c=T[:3, :3].copy(), t_c=T[:3, 3].copy(), f=T[:3, :3].T @ (T[:3, 3] + [l, 0, 0]),
                lower=model.lower[q_indices].copy(), upper=model.upper[q_indices].copy())


# Kernels: small loops instead of BLAS calls, which are slow at 3x3.

@njit(cache=True)
def _mul(A, B):
    """A @ B for 3x3 matrices."""
    out = np.zeros((3, 3))
    for i in range(3):
        for k in range(3):
            for j in range(3):
                out[i, j] += A[i, k] * B[k, j]
    return out


@njit(cache=True)
def _transpose(A):
    """A.T as a new C-contiguous 3x3 array."""
    out = np.empty((3, 3))
    for i in range(3):
        for j in range(3):
            out[i, j] = A[j, i]
    return out


@njit(cache=True)
def _mv(A, x):
    """A @ x for a 3x3 matrix and a 3-vector."""
    return np.array([A[0, 0] * x[0] + A[0, 1] * x[1] + A[0, 2] * x[2],
                     A[1, 0] * x[0] + A[1, 1] * x[1] + A[1, 2] * x[2],
                     A[2, 0] * x[0] + A[2, 1] * x[1] + A[2, 2] * x[2]])


@njit(cache=True)
def _dot(a, b):
    return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]


@njit(cache=True)
def _cross(a, b):
    return np.array([a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]])


@njit(cache=True)
def _rotate(M, i, j, angle):
    """M <- M @ R for R the rotation by ``angle`` in the (i, j) coordinate plane (x: 1,2; y: 2,0; z: 0,1)."""
    c, s = np.cos(angle), np.sin(angle)
    for r in range(3):
        a, b = M[r, i], M[r, j]
        M[r, i] = c * a + s * b
        M[r, j] = c * b - s * a


@njit(cache=True)
def _into_limits(angle, lo, hi):
    """``angle`` shifted by a multiple of 2π into [lo, hi] (clipped within the slack), else NaN."""
    a = angle - _TWO_PI * np.floor((angle + np.pi) / _TWO_PI)
    if a < lo - _LIMIT_SLACK:
        a += _TWO_PI
    elif a > hi + _LIMIT_SLACK:
        a -= _TWO_PI
    if a < lo - _LIMIT_SLACK or a > hi + _LIMIT_SLACK:
        return np.nan
    return min(max(a, lo), hi)


@njit(cache=True)
def _fk(q, u, l, R_c, t_c):
    """Tip pose (R (3, 3), p (3,)) of the chain at q (n,) in the shoulder frame S."""
    R = np.eye(3)
    _rotate(R, 2, 0, q[0])
    _rotate(R, 0, 1, q[1])
    p = _mv(R, u)
    _rotate(R, 1, 2, q[2])
    _rotate(R, 0, 1, q[3])
    if q.shape[0] == 5:
        for i in range(3):
            p[i] += l * R[i, 0]
        _rotate(R, 1, 2, q[4])
    return _mul(R, R_c), p + _mv(R, t_c)


@njit(cache=True)
def _rotation_residual(R_t, R):
    """sin(angle) * axis (3,) of the rotation N = R_t R^T: vee(N - N^T) / 2."""
    N = _mul(R_t, _transpose(R))
    return 0.5 * np.array([N[2, 1] - N[1, 2], N[0, 2] - N[2, 0], N[1, 0] - N[0, 1]])


@njit(cache=True)
def _branch(psi, circle, shoulder, elbow, p_t, R_j, u, t_c, q):
    """Raw angles q (n,) of one branch (shoulder, elbow = +-1) with the elbow at swivel psi on C.

    ``circle`` (3, 3) holds the centre of C and two orthogonal radius vectors; ``R_j`` is the
    target orientation of the last joint frame (5 DoF only).
    """
    E = circle[0] + np.cos(psi) * circle[1] + np.sin(psi) * circle[2]
    m = shoulder * np.sqrt(max(E[0] ** 2 + E[2] ** 2 - u[2] ** 2, 0.0))  # 3: shoulder
    q[0] = np.arctan2(u[2], m) - np.arctan2(E[2], E[0])
    q[1] = np.arctan2(E[1], m) - np.arctan2(u[1], u[0])
    R_b = np.eye(3)
    _rotate(R_b, 2, 0, q[0])
    _rotate(R_b, 0, 1, q[1])
    if q.shape[0] == 4:  # 4a: forearm through the target point
        g = _mv(_transpose(R_b), p_t - E)
        sigma = elbow * np.sqrt(max(g[1] ** 2 + g[2] ** 2 - t_c[2] ** 2, 0.0))
        q[3] = np.arctan2(sigma, g[0]) - np.arctan2(t_c[1], t_c[0])
        q[2] = np.arctan2(g[2], g[1]) - np.arctan2(t_c[2], sigma)
    else:  # 4b: X-Z-X Euler angles of the forearm and wrist
        M = _mul(_transpose(R_b), R_j)
        q[3] = np.arctan2(elbow * np.sqrt(M[1, 0] ** 2 + M[2, 0] ** 2), M[0, 0])
        q[2] = np.arctan2(elbow * M[2, 0], elbow * M[1, 0])
        q[4] = np.arctan2(elbow * M[0, 2], -elbow * M[0, 1])


@njit(cache=True)
def _refine_swivel(circle, shoulder, elbow, p_t, R_t, u, R_c, t_c, q):
    """Gauss-Newton on the swivel angle of a position-exact 4-DoF branch: least rotation error."""
    psi = 0.0
    for _ in range(_SWIVEL_STEPS):
        _branch(psi, circle, shoulder, elbow, p_t, R_t, u, t_c, q)
        e = _rotation_residual(R_t, _fk(q, u, 0.0, R_c, t_c)[0])
        _branch(psi + _SWIVEL_STEP, circle, shoulder, elbow, p_t, R_t, u, t_c, q)
        de = _rotation_residual(R_t, _fk(q, u, 0.0, R_c, t_c)[0]) - e  # derivative * step
        psi -= _SWIVEL_STEP * _dot(de, e) / max(_dot(de, de), 1e-300)
    _branch(psi, circle, shoulder, elbow, p_t, R_t, u, t_c, q)


@njit(cache=True)
def _verify(q, lower, upper, u, l, R_c, t_c, R_t, p_t, sol):
    """Shift q into the limits (into sol); (position error m, rotation error rad), inf outside the limits."""
    for j in range(q.shape[0]):
        sol[j] = _into_limits(q[j], lower[j], upper[j])
        if np.isnan(sol[j]):
            return np.inf, np.inf
    R, p = _fk(sol, u, l, R_c, t_c)
    pos2, chord2 = 0.0, 0.0
    for i in range(3):
        pos2 += (p[i] - p_t[i]) ** 2
        for j in range(3):
            chord2 += (R[i, j] - R_t[i, j]) ** 2
    return np.sqrt(pos2), 2.0 * np.arcsin(min(np.sqrt(chord2 / 8.0), 1.0))  # |R - R_t|_F = √8 sin(angle/2)


@njit(cache=True)
def _solve_one(T, u, l, R_c, t_c, f, lower, upper, tol_pos, tol_rot, out_q, out_err):
    """Verified solutions of one target T (4, 4) in frame S into out_q (S, n), out_err (S, 2); returns their count."""
    n = lower.shape[0]
    R_t, p_t = T[:3, :3].copy(), T[:3, 3].copy()
    # 1-2: elbow point E* from the target; the circle C of position-exact elbows, swivel 0 nearest E*
    d = np.sqrt(_dot(p_t, p_t))
    if d < 1e-12:
        return 0
    axis = p_t / d
    centre = (_dot(u, u) - _dot(f, f) + d * d) / (2.0 * d)
    radius = np.sqrt(max(_dot(u, u) - centre * centre, 0.0))  # 0 beyond reach: the FK check rejects it
    E = p_t - _mv(R_t, f)
    v = E - _dot(E, axis) * axis
    if _dot(v, v) < 1e-24:  # E* on the axis of C: every swivel is as close (an inconsistent target)
        v = np.array([axis[1], -axis[0], 0.0]) if abs(axis[2]) < 0.9 else np.array([0.0, axis[2], -axis[1]])
    v /= np.sqrt(_dot(v, v))
    circle = np.empty((3, 3))
    circle[0], circle[1], circle[2] = centre * axis, radius * v, radius * _cross(axis, v)
    # 5 DoF: R_a the smallest rotation taking R_t f to p - E; R_j = R_a R_t R_c^T (last joint frame)
    a, b = _mv(R_t, f), p_t - circle[0] - circle[1]
    a, b = a / np.sqrt(_dot(a, a)), b / np.sqrt(_dot(b, b))
    k, cos_ab = _cross(a, b), _dot(a, b)
    if cos_ab < -1.0 + 1e-12:
        return 0
    K = np.array([[0.0, -k[2], k[1]], [k[2], 0.0, -k[0]], [-k[1], k[0], 0.0]])
    R_a = np.eye(3) + K + _mul(K, K) / (1.0 + cos_ab)
    R_j = _mul(_mul(R_a, R_t), _transpose(R_c))
    count = 0
    q, sol = np.empty(n), np.empty(n)
    for shoulder in (1.0, -1.0):
        for elbow in (1.0, -1.0):
            _branch(0.0, circle, shoulder, elbow, p_t, R_j, u, t_c, q)
            pos, rot = _verify(q, lower, upper, u, l, R_c, t_c, R_t, p_t, sol)  # 5: limits and FK
            if n == 4 and pos <= tol_pos and rot > _CONSISTENT:  # inconsistent orientation
                _refine_swivel(circle, shoulder, elbow, p_t, R_t, u, R_c, t_c, q)
                pos, rot = _verify(q, lower, upper, u, l, R_c, t_c, R_t, p_t, sol)
            if not (pos <= tol_pos and rot <= tol_rot):  # NaN-safe
                continue
            duplicate = False
            for i in range(count):
                duplicate |= np.max(np.abs(out_q[i] - sol)) < _SAME
            if not duplicate:
                out_q[count] = sol
                out_err[count, 0], out_err[count, 1] = pos, rot
                count += 1
    return count


@njit(cache=True)
def _solve_batch(targets, u, l, R_c, t_c, f, lower, upper, tol_pos, tol_rot, out_q, out_err, out_count):
    for b in range(targets.shape[0]):
        out_count[b] = _solve_one(targets[b], u, l, R_c, t_c, f, lower, upper, tol_pos, tol_rot, out_q[b], out_err[b])


def _solve(arm: _Arm, poses: np.ndarray, tolerance) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    tol = np.asarray(tolerance, dtype=float)
    if tol.shape != (2,) or not np.all(np.isfinite(tol)) or np.any(tol <= 0):
        raise PrehensileError(f"tolerance: expected (position m, rotation rad), both > 0, got {tolerance!r}")
    q = np.full((len(poses), MAX_SOLUTIONS, len(arm.q_indices)), np.nan)
    err = np.full((len(poses), MAX_SOLUTIONS, 2), np.nan)
    counts = np.zeros(len(poses), dtype=np.int64)
    _solve_batch(arm.T_S_inv @ poses, arm.u, arm.wrist_offset, arm.R_c, arm.t_c, arm.f, arm.lower, arm.upper,
                 tol[0], tol[1], q, err, counts)
    return q, err, counts


def nao_arm_ik_batch(model: RobotModel, chain: str, targets: np.ndarray,
                     tolerance: tuple[float, float] = (1e-6, 1e-6)) -> tuple[np.ndarray, np.ndarray]:
    """All solutions for many tip poses of a NAO arm chain, in one compiled call.

    Args:
        model, chain, tolerance: as in :func:`nao_arm_ik`.
        targets: (B, 4, 4) tip poses in the model root frame (the NAO's torso) (m).

    Returns:
        solutions (B, MAX_SOLUTIONS, n) chain joint values (rad) in kernel order, NaN past
        each count, and counts (B,) the number of solutions per target.

    Raises:
        PrehensileError: as :func:`nao_arm_ik`.
    """
    arm = _arm(model, chain)
    q, _, counts = _solve(arm, check_target_poses(targets, "targets"), tolerance)
    return q, counts


def nao_arm_ik(model: RobotModel, chain: str, target: np.ndarray, q_seed: np.ndarray | None = None,
               tolerance: tuple[float, float] = (1e-6, 1e-6)) -> IKResult:
    """Every joint solution placing a NAO arm chain's tip at ``target`` (closed form, see module).

    Args:
        model: a NAO model (e.g. ``robots.load("nao")``).
        chain: ``left_arm`` / ``right_arm`` (4 DoF, tip ``*_arm_tip``) or ``left_arm_wrist`` /
            ``right_arm_wrist`` (5 DoF, tip ``*_gripper``), or another chain of this structure.
        target: tip pose (4, 4) in the model root frame (the NAO's torso) (m), or
            a pose set (k, 4, 4): the solutions of the first pose that has any are returned.
        q_seed: (dof,) full configuration; joints outside the chain keep its values and the
            solutions are sorted by distance to it. Default: the neutral configuration.
        tolerance: (position m, rotation rad) every solution reproduces the target within.

    Returns:
        SUCCESS with ``solutions`` (k, dof) sorted by distance to the seed and ``q`` the
        closest; or UNREACHABLE (the pose is outside the workspace, its orientation outside
        the 4-D / 5-D subset the chain reaches, or no solution is within the limits) with
        ``q`` = the seed, its errors against the first pose, and no solutions.

    Raises:
        PrehensileError: NaN / non-rotation target, a bad seed or tolerance, or a chain that is
            not a NAO-type arm.
    """
    start = clock()
    arm = _arm(model, chain)
    poses = check_target_poses(target)
    seed = model.neutral_configuration() if q_seed is None else model.check_one(q_seed, "q_seed").copy()
    q, err, counts = _solve(arm, poses, tolerance)
    for index in np.flatnonzero(counts):
        chain_q, chain_err = q[index, :counts[index]], err[index, :counts[index]]
        order = np.argsort(np.linalg.norm(chain_q - seed[arm.q_indices], axis=1), kind="stable")
        solutions = np.repeat(seed[None], len(order), axis=0)
        solutions[:, arm.q_indices] = chain_q[order]
        best = chain_err[order[0]]
        return IKResult(IKStatus.SUCCESS, solutions[0].copy(), solutions, float(best[0]), float(best[1]), 0,
                        clock() - start, target_index=int(index))
    reached = link_pose(model, seed, arm.tip)
    return IKResult(IKStatus.UNREACHABLE, seed, np.empty((0, model.dof)),
                    float(np.linalg.norm(reached[:3, 3] - poses[0, :3, 3])),
                    float(np.linalg.norm(rotation_error(poses[0, :3, :3], reached[:3, :3]))), 0,
                    clock() - start)
