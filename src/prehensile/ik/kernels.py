"""Compiled (numba) kernels of the Jacobian IK solvers.

A chain is packed as the links on the path from the model root to the tip (parents first):
``table`` (P, 20) holds those rows of the model's ``joint_table`` (columns: 0 parent, unused
here, 1 joint type, 2 q index, 3 multiplier, 4 offset, 5-7 axis, 8-19 the top three rows of
the joint origin). ``var_of_q`` (dof,) maps a q index to its column in the chain Jacobian, or
-1 for joints held at the seed's value. Every kernel works on full configurations (dof,).

The task error stacks position (m) over rotation (rad, rotation vector of
``R_target R_current^T``, world axes); ``rows`` selects and ``row_weight`` scales the
rows that take part (three for position-only targets).
"""

from __future__ import annotations

import numpy as np
from numba import njit

from prehensile.kinematics.kernels import FAST, FIXED, PRISMATIC, REVOLUTE, joint_column, joint_transform

TRANSPOSE, PSEUDOINVERSE, DAMPED = 0, 1, 2
# solver outcomes
CONVERGED, ITERATION_CAP, STALLED = 0, 1, 2


@njit(cache=True, fastmath=FAST)
def chain_pose_jacobian(q, T_world_root, table, var_of_q, T_tip_tcp, frames, pose, jac):
    """Tool pose ``pose`` (4, 4) and world-axes Jacobian ``jac`` (6, n) of the chain at q (dof,).

    ``frames`` (P, 3, 4) is scratch space: the world pose of every link on the path.
    """
    P = table.shape[0]
    for i in range(P):
        jtype = int(table[i, 1])
        value = table[i, 3] * q[int(table[i, 2])] + table[i, 4] if jtype != FIXED else 0.0
        l00, l01, l02, l03, l10, l11, l12, l13, l20, l21, l22, l23 = joint_transform(
            jtype, value, table[i, 5], table[i, 6], table[i, 7], table[i, 8], table[i, 9], table[i, 10], table[i, 11],
            table[i, 12], table[i, 13], table[i, 14], table[i, 15], table[i, 16], table[i, 17], table[i, 18], table[i, 19])
        for r in range(3):
            if i == 0:
                b0, b1, b2, b3 = T_world_root[r, 0], T_world_root[r, 1], T_world_root[r, 2], T_world_root[r, 3]
            else:
                b0, b1, b2, b3 = frames[i - 1, r, 0], frames[i - 1, r, 1], frames[i - 1, r, 2], frames[i - 1, r, 3]
            frames[i, r, 0] = b0 * l00 + b1 * l10 + b2 * l20
            frames[i, r, 1] = b0 * l01 + b1 * l11 + b2 * l21
            frames[i, r, 2] = b0 * l02 + b1 * l12 + b2 * l22
            frames[i, r, 3] = b0 * l03 + b1 * l13 + b2 * l23 + b3
    for r in range(3):
        for c in range(4):
            pose[r, c] = (frames[P - 1, r, 0] * T_tip_tcp[0, c] + frames[P - 1, r, 1] * T_tip_tcp[1, c]
                          + frames[P - 1, r, 2] * T_tip_tcp[2, c])
        pose[r, 3] += frames[P - 1, r, 3]
    pose[3, 0], pose[3, 1], pose[3, 2], pose[3, 3] = 0.0, 0.0, 0.0, 1.0
    jac[:, :] = 0.0
    px, py, pz = pose[0, 3], pose[1, 3], pose[2, 3]
    for i in range(P):
        jtype = int(table[i, 1])
        if jtype != REVOLUTE and jtype != PRISMATIC:
            continue
        c = var_of_q[int(table[i, 2])]
        if c < 0:
            continue
        col = joint_column(jtype, table[i, 3], table[i, 5], table[i, 6], table[i, 7],
                           frames[i, 0, 0], frames[i, 0, 1], frames[i, 0, 2], frames[i, 1, 0], frames[i, 1, 1],
                           frames[i, 1, 2], frames[i, 2, 0], frames[i, 2, 1], frames[i, 2, 2],
                           px - frames[i, 0, 3], py - frames[i, 1, 3], pz - frames[i, 2, 3])
        for k in range(6):
            jac[k, c] += col[k]


@njit(cache=True, inline="always")
def _rows_dot(A, B, i, j):
    """Entry (i, j) of A[:3, :3] @ B[:3, :3].T."""
    return A[i, 0] * B[j, 0] + A[i, 1] * B[j, 1] + A[i, 2] * B[j, 2]


@njit(cache=True, fastmath=FAST)
def pose_error(target, pose, err):
    """err (6,) = [target position - position (m), rotation vector of R_t R^T (rad)]."""
    for r in range(3):
        err[r] = target[r, 3] - pose[r, 3]
    # R = R_t R^T (rotation parts), entry by entry: no temporary array
    r00, r01, r02 = _rows_dot(target, pose, 0, 0), _rows_dot(target, pose, 0, 1), _rows_dot(target, pose, 0, 2)
    r10, r11, r12 = _rows_dot(target, pose, 1, 0), _rows_dot(target, pose, 1, 1), _rows_dot(target, pose, 1, 2)
    r20, r21, r22 = _rows_dot(target, pose, 2, 0), _rows_dot(target, pose, 2, 1), _rows_dot(target, pose, 2, 2)
    cos_angle = min(max(0.5 * (r00 + r11 + r22 - 1.0), -1.0), 1.0)
    angle = np.arccos(cos_angle)
    vx, vy, vz = r21 - r12, r02 - r20, r10 - r01
    sin_angle = np.sin(angle)
    if sin_angle > 1e-7:
        k = angle / (2.0 * sin_angle)
        err[3], err[4], err[5] = k * vx, k * vy, k * vz
    elif angle < 1.0:  # near zero: first order
        err[3], err[4], err[5] = 0.5 * vx, 0.5 * vy, 0.5 * vz
    else:  # near pi: axis from the diagonal of R = 2 a a^T - I
        ax = np.sqrt(max(0.5 * (r00 + 1.0), 0.0))
        ay = np.sqrt(max(0.5 * (r11 + 1.0), 0.0))
        az = np.sqrt(max(0.5 * (r22 + 1.0), 0.0))
        if ax >= ay and ax >= az:
            ay, az = np.copysign(ay, r01), np.copysign(az, r02)
        elif ay >= az:
            ax, az = np.copysign(ax, r01), np.copysign(az, r12)
        else:
            ax, ay = np.copysign(ax, r02), np.copysign(ay, r12)
        norm = np.sqrt(ax * ax + ay * ay + az * az)
        err[3], err[4], err[5] = angle * ax / norm, angle * ay / norm, angle * az / norm


@njit(cache=True, fastmath=FAST)
def _solve_spd(A, b, x):
    """x (m,) with A x = b for a symmetric positive definite A (m, m), by an in-place Cholesky
    factorization (A is overwritten)."""
    m = A.shape[0]
    for i in range(m):
        for j in range(i + 1):
            s = A[i, j]
            for k in range(j):
                s -= A[i, k] * A[j, k]
            A[i, j] = np.sqrt(max(s, 1e-300)) if i == j else s / A[j, j]
    for i in range(m):
        s = b[i]
        for k in range(i):
            s -= A[i, k] * x[k]
        x[i] = s / A[i, i]
    for i in range(m - 1, -1, -1):
        s = x[i]
        for k in range(i + 1, m):
            s -= A[k, i] * x[k]
        x[i] = s / A[i, i]


@njit(cache=True, fastmath=FAST)
def joint_step(method, Jw, ew, damping, A, x, dq):
    """Joint step dq (n,) for the weighted task Jacobian Jw (m, n) and error ew (m,).

    ``A`` (m, m) and ``x`` (m,) are scratch space.
    """
    m, n = Jw.shape
    if method == PSEUDOINVERSE:
        dq[:] = np.linalg.pinv(Jw, rcond=1e-10) @ ew
        return
    for i in range(m):  # A = J J^T
        for j in range(i + 1):
            s = 0.0
            for c in range(n):
                s += Jw[i, c] * Jw[j, c]
            A[i, j] = s
            A[j, i] = s
    if method == TRANSPOSE:  # Buss 2004: alpha = <e, J J^T e> / <J J^T e, J J^T e>
        num, den = 0.0, 0.0
        for i in range(m):
            s = 0.0
            for j in range(m):
                s += A[i, j] * ew[j]
            num += ew[i] * s
            den += s * s
        alpha = num / den if den > 0.0 else 0.0
        for i in range(m):
            x[i] = alpha * ew[i]
    else:
        # damped least squares, damping grown with the error (Sugihara 2011):
        # dq = J^T (J J^T + lambda^2 I)^-1 e with lambda^2 = |e|^2 + damping^2
        lam2 = damping * damping
        for i in range(m):
            lam2 += ew[i] * ew[i]
        for i in range(m):
            A[i, i] += lam2
        _solve_spd(A, ew, x)
    for c in range(n):
        s = 0.0
        for i in range(m):
            s += Jw[i, c] * x[i]
        dq[c] = s


@njit(cache=True, fastmath=FAST)
def solve(q, targets, target_index, T_world_root, table, var_of_q, var_q, T_tip_tcp, lower, upper,
          rows, row_weight, tol_pos, tol_rot, max_iterations, method, max_step_pos, max_step_rot,
          damping, gain, stall_iterations):
    """Move q (dof,) in place toward ``targets[target_index]`` (4, 4).

    ``var_q`` (n,) the q index of each Jacobian column; ``lower``/``upper`` (n,) their limits
    (the step is clamped into them). The Cartesian error is clamped to ``max_step_pos`` (m) and
    ``max_step_rot`` (rad) before each step (Vahrenkamp's LimitCartesianStepSize).

    Returns:
        (outcome, iterations, position error (m), rotation error (rad)) of the final q, both
        over the task ``rows`` only.
    """
    n = var_q.shape[0]
    target = targets[target_index]
    pose = np.empty((4, 4))
    jac = np.empty((6, n))
    frames = np.empty((table.shape[0], 3, 4))
    err = np.empty(6)
    m = rows.shape[0]
    Jw = np.empty((m, n))
    ew = np.empty(m)
    A = np.empty((m, m))
    x = np.empty(m)
    dq = np.empty(n)
    best = np.inf
    since_best = 0
    it = 0
    while True:
        chain_pose_jacobian(q, T_world_root, table, var_of_q, T_tip_tcp, frames, pose, jac)
        pose_error(target, pose, err)
        pos2, rot2 = 0.0, 0.0  # over the task rows only: a dropped row is neither solved for nor checked
        for r in rows:
            if r < 3:
                pos2 += err[r] * err[r]
            else:
                rot2 += err[r] * err[r]
        pos_err, rot_err = np.sqrt(pos2), np.sqrt(rot2)
        if pos_err <= tol_pos and rot_err <= tol_rot:
            return CONVERGED, it, pos_err, rot_err
        if it >= max_iterations:
            return ITERATION_CAP, it, pos_err, rot_err
        score = pos_err / tol_pos + rot_err / tol_rot
        if score < 0.999 * best:
            best, since_best = score, 0
        else:
            since_best += 1
            if since_best >= stall_iterations:
                return STALLED, it, pos_err, rot_err
        if pos_err > max_step_pos:
            for r in range(3):
                err[r] *= max_step_pos / pos_err
        if rot_err > max_step_rot:
            for r in range(3, 6):
                err[r] *= max_step_rot / rot_err
        for k in range(m):
            ew[k] = row_weight[k] * err[rows[k]]
            for c in range(n):
                Jw[k, c] = row_weight[k] * jac[rows[k], c]
        joint_step(method, Jw, ew, damping, A, x, dq)
        # joints at a limit that the step pushes further out drop out of this step
        blocked = False
        for c in range(n):
            qi = var_q[c]
            if (q[qi] <= lower[c] and dq[c] < 0.0) or (q[qi] >= upper[c] and dq[c] > 0.0):
                blocked = True
                for k in range(m):
                    Jw[k, c] = 0.0
        if blocked:
            joint_step(method, Jw, ew, damping, A, x, dq)
        for c in range(n):
            qi = var_q[c]
            q[qi] = min(max(q[qi] + gain * dq[c], lower[c]), upper[c])
        it += 1


@njit(cache=True, inline="always")
def miss(pos_err, rot_err, tol_pos, tol_rot):
    """How far a configuration is from its target, in tolerances: position error (m) over
    ``tol_pos`` plus rotation error (rad) over ``tol_rot`` (infinite for position-only)."""
    return pos_err / tol_pos + rot_err / tol_rot


@njit(cache=True)
def solve_restarts(q_out, q_seed, seeds, targets, T_world_root, table, var_of_q, var_q, T_tip_tcp, lower,
                   upper, rows, row_weight, tol_pos, tol_rot, max_iterations, method, max_step_pos,
                   max_step_rot, damping, gain, stall_iterations, first_target):
    """Try the seed rows ``seeds`` (R, n) in order until one converges.

    Each attempt starts from ``q_seed`` (dof,) with the chain joints set to a seed row and
    aims at target ``(first_target + attempt) % k`` of ``targets`` (k, 4, 4). The converged
    configuration, else the attempt closest to its target (:func:`miss`), is left in
    ``q_out`` (dof,).

    Returns:
        (attempt that converged or -1, target index, iterations summed, position error,
        rotation error), the index and errors of the configuration in ``q_out``.
    """
    total = 0
    k = targets.shape[0]
    q = np.empty_like(q_out)
    best = (np.inf, np.inf, np.inf, first_target % k)  # miss, position error, rotation error, target
    for a in range(seeds.shape[0]):
        q[:] = q_seed
        for c in range(var_q.shape[0]):
            q[var_q[c]] = seeds[a, c]
        target_index = (first_target + a) % k
        outcome, it, pos_err, rot_err = solve(
            q, targets, target_index, T_world_root, table, var_of_q, var_q, T_tip_tcp, lower, upper,
            rows, row_weight, tol_pos, tol_rot, max_iterations, method, max_step_pos, max_step_rot,
            damping, gain, stall_iterations)
        total += it
        far = miss(pos_err, rot_err, tol_pos, tol_rot)
        if outcome == CONVERGED or far < best[0]:
            q_out[:] = q
            best = (far, pos_err, rot_err, target_index)
        if outcome == CONVERGED:
            return a, target_index, total, pos_err, rot_err
    return -1, best[3], total, best[1], best[2]
