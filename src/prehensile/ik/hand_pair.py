"""Two arms of one model and, optionally, the object they hold solved as one IK (compiled).

:class:`HandPair` steps both tools toward their grasps of one object with a stacked
pseudoinverse or damped least-squares step over the joints of both arms, further joints
(e.g. the hip) and the object's world twist. It serves the hand-over IK (Vahrenkamp 2011
Alg. 8, :func:`~prehensile.ik.hybrid.solve_regrasp_ik`) and the steps of Regrasp-J+-RRT
(:mod:`prehensile.planning.jplus_rrt`).
"""

from __future__ import annotations

from typing import Sequence

import numpy as np
from numba import njit

from prehensile.errors import PrehensileError
from prehensile.ik.jacobian import METHODS, ChainSolver, JacobianIKSettings, free_joint_indices
from prehensile.ik.kernels import chain_pose_jacobian, joint_step, pose_error
from prehensile.ik.reach import ReachSamples, nearest_sample, to_frame
from prehensile.kinematics.kernels import FAST

UNBOUNDED = (np.full(6, -np.inf), np.full(6, np.inf))  # object bounds without a region


def check_arm_pair(arms: Sequence[ChainSolver], who: str) -> None:
    """PrehensileError (naming ``who``) unless ``arms`` are two solvers of different chains."""
    if len(arms) != 2 or arms[0].chain.name == arms[1].chain.name:
        raise PrehensileError(f"{who}: expected two arms of different chains, got "
                              f"{[arm.chain.name for arm in arms]}")


class HandPair:
    """Two arms of one model solved together, with further joints (e.g. the hip) and,
    optionally, the object pose as unknowns.

    Both tools are to sit at their grasps of one object: ``T_world_tcp[h] = T_world_object @
    grasps[h]``. A step stacks both tools' errors (12,) (each clamped to the Cartesian step)
    over the Jacobian of the joint columns ``var_q``; a free object adds six columns, its world
    twist (v, w), which moves both targets: ``δp_h = v + w × (p_h - p_object)``, ``δR_h = w``.
    The step is the pseudoinverse or damped least-squares solution (method, steps, damping,
    tolerances and caps of the first arm's :class:`~prehensile.ik.jacobian.JacobianIKSettings`);
    joints stay in their limits, the object in its bounds (position box, rpy ranges).

    Args:
        arms: two :class:`ChainSolver` of one model with one root pose.
        free: further joints solved with the arms: a chain name, joint names, or None.
        settings: Jacobian settings of the joint solve (full poses); the first arm's if None.
    """

    def __init__(self, arms: Sequence[ChainSolver], free: Sequence[str] | str | None = None,
                 settings: JacobianIKSettings | None = None) -> None:
        check_arm_pair(arms, "HandPair")
        a, b = arms
        if a.model is not b.model or not np.array_equal(a.T_world_root, b.T_world_root):
            raise PrehensileError("HandPair: both arms must belong to one model with one root pose")
        self.arms, self.model, self.settings = (a, b), a.model, a.settings if settings is None else settings
        if self.settings.position_only:
            raise PrehensileError("HandPair: grasps are full poses; the settings must not be position_only")
        extra = free_joint_indices(a.model, arms, free)
        self.var_q = np.array(list(dict.fromkeys([*a.var_q, *b.var_q, *extra])), dtype=np.int64)
        """(n,) q index of each joint column."""
        self.var_of_q = np.full(a.model.dof, -1, dtype=np.int64)
        self.var_of_q[self.var_q] = np.arange(len(self.var_q))
        self.lower, self.upper = a.model.sampling_limits(self.var_q)
        """(n,) range of random seeds; solutions keep the model's limits (none if continuous)."""
        s = self.settings
        limits = [np.ascontiguousarray(bound[self.var_q]) for bound in (a.model.lower, a.model.upper)]
        self._kernel_args = (a.table, b.table, self.var_of_q, self.var_q, a.T_world_root,
                             np.ascontiguousarray([a.T_tip_tcp, b.T_tip_tcp]), *limits)
        self._step_args = (s.max_step_position, s.max_step_rotation, METHODS[s.method], s.damping)

    def poses(self, q: np.ndarray) -> np.ndarray:
        """World poses (*batch, 2, 4, 4) of both tools for q (*batch, dof)."""
        return np.stack([arm.tool_pose(q) for arm in self.arms], axis=-3)

    def step(self, q: np.ndarray, T_world_object: np.ndarray, grasps: np.ndarray, free_object: bool
             ) -> tuple[np.ndarray, np.ndarray, float, float]:
        """One step from q (dof,) toward ``T_world_object @ grasps[h]`` (grasps (2, 4, 4)), the
        object pose moving too if ``free_object`` (without bounds).

        Returns:
            (q' (dof,), object pose' (4, 4), largest position error (m) and rotation error
            (rad) of the two tools at q, before the step).
        """
        q, T = np.array(q, dtype=float), np.array(T_world_object, dtype=float)
        pos_err, rot_err = _hands_step(q, T, np.ascontiguousarray(grasps, dtype=float), *self._kernel_args,
                                       free_object, *UNBOUNDED, *self._step_args)
        return q, T, pos_err, rot_err

    def solve(self, q: np.ndarray, T_world_object: np.ndarray, seeds: np.ndarray, objects: np.ndarray,
              relative: bool, chosen: np.ndarray, grasp_sets: Sequence[np.ndarray],
              bounds: tuple[np.ndarray, np.ndarray], reach: Sequence[ReachSamples]
              ) -> tuple[int, int, int, float, float]:
        """Solve the attempts in turn (compiled) until one converges, object pose free.

        Attempt r starts from the joint values ``seeds[r]`` (n,), except that each arm starts
        from its sample in ``reach[h]`` (:func:`~prehensile.ik.reach.reach_samples`) nearest
        to its target (the attempt is skipped if a target is out of reach), the object pose
        ``objects[r]`` (4, 4) (in the world, or if ``relative`` in the frame of arm b's base
        link) and the grasps ``chosen[r]`` (2,) (indices into the sets ``grasp_sets`` (k_h, 4, 4)).

        Args:
            q, T_world_object: (dof,) and (4, 4) outputs, the converged attempt's or else the
                closest one's (in tolerances, :func:`~prehensile.ik.kernels.miss`), unchanged if
                every attempt was skipped; ``q`` holds the other joints' values.

        Returns:
            (converged attempt or -1, attempt left in the outputs or -1, iterations, its
            largest position error m and rotation error rad of the two tools (inf if none)).
        """
        s = self.settings
        return _hands_restarts(q, T_world_object, seeds, objects, relative, chosen, grasp_sets[0], grasp_sets[1],
                               reach[0], reach[1], *self._kernel_args,
                               bounds[0], bounds[1], *self._step_args, s.position_tolerance, s.rotation_tolerance,
                               s.iteration_cap, s.stall_cap)


@njit(cache=True, fastmath=FAST)
def _hands_error(q, T_o, grasps, table_a, table_b, var_of_q, T_world_root, tcp, frames_a, frames_b, poses, jac, err,
                 target):
    """Both tools' poses ``poses`` (2, 4, 4), Jacobians ``jac`` (2, 6, n) and errors ``err``
    (12,) toward ``T_o @ grasps[h]`` (``target`` (4, 4) scratch); returns the largest position
    (m) and rotation (rad) error."""
    chain_pose_jacobian(q, T_world_root, table_a, var_of_q, tcp[0], frames_a, poses[0], jac[0])
    chain_pose_jacobian(q, T_world_root, table_b, var_of_q, tcp[1], frames_b, poses[1], jac[1])
    pos, rot = 0.0, 0.0
    for h in range(2):
        _compose(T_o, grasps[h], target)
        e = err[6 * h:6 * h + 6]
        pose_error(target, poses[h], e)
        pos = max(pos, np.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2))
        rot = max(rot, np.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2))
    return pos, rot


@njit(cache=True, fastmath=FAST)
def _compose(A, B, out):
    """out (4, 4) = A @ B for poses A, B (4, 4)."""
    for r in range(3):
        for c in range(4):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c] + (A[r, 3] if c == 3 else 0.0)
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@njit(cache=True, fastmath=FAST)
def _hands_update(q, T_o, grasps, jac, err, var_q, lower, upper, lo, hi, max_step_pos, max_step_rot, method, damping,
                  Jw, A, x, dx):
    """Move q (dof,) and, if ``Jw`` (12, n + 6) has object columns, T_o (4, 4) in place by one
    step toward err (12,); ``Jw``, ``A`` (12, 12), ``x`` (12,), ``dx`` (cols,) are scratch."""
    n = var_q.shape[0]
    for k in range(4):  # clamp each tool's position and rotation error
        limit = max_step_pos if k % 2 == 0 else max_step_rot
        norm = np.sqrt(err[3 * k] ** 2 + err[3 * k + 1] ** 2 + err[3 * k + 2] ** 2)
        if norm > limit:
            for r in range(3 * k, 3 * k + 3):
                err[r] *= limit / norm
    Jw[:, :] = 0.0
    Jw[:6, :n] = jac[0]
    Jw[6:, :n] = jac[1]
    if Jw.shape[1] > n:  # the targets move with the object: -[[I, -[r]x], [0, I]] per tool
        for h in range(2):
            r0, r1, r2 = (T_o[0, 0] * grasps[h, 0, 3] + T_o[0, 1] * grasps[h, 1, 3] + T_o[0, 2] * grasps[h, 2, 3],
                          T_o[1, 0] * grasps[h, 0, 3] + T_o[1, 1] * grasps[h, 1, 3] + T_o[1, 2] * grasps[h, 2, 3],
                          T_o[2, 0] * grasps[h, 0, 3] + T_o[2, 1] * grasps[h, 1, 3] + T_o[2, 2] * grasps[h, 2, 3])
            for i in range(3):
                Jw[6 * h + i, n + i] = -1.0
                Jw[6 * h + 3 + i, n + 3 + i] = -1.0
            Jw[6 * h, n + 4], Jw[6 * h, n + 5] = -r2, r1
            Jw[6 * h + 1, n + 3], Jw[6 * h + 1, n + 5] = r2, -r0
            Jw[6 * h + 2, n + 3], Jw[6 * h + 2, n + 4] = -r1, r0
    joint_step(method, Jw, err, damping, A, x, dx)
    blocked = False  # joints at a limit that the step pushes further out drop out of this step
    for c in range(n):
        if (q[var_q[c]] <= lower[c] and dx[c] < 0.0) or (q[var_q[c]] >= upper[c] and dx[c] > 0.0):
            blocked = True
            Jw[:, c] = 0.0
    if blocked:
        joint_step(method, Jw, err, damping, A, x, dx)
    for c in range(n):
        q[var_q[c]] = min(max(q[var_q[c]] + dx[c], lower[c]), upper[c])
    if Jw.shape[1] > n:
        _move_object(T_o, dx[n:], lo, hi)


@njit(cache=True, fastmath=FAST)
def _move_object(T, twist, lo, hi):
    """T (4, 4) moved by the world twist (v, w) (6,) (Rodrigues), then held in the bounds (6,)
    of (position, rpy): the position clipped to its box; rpy, where outside, clipped."""
    wx, wy, wz = twist[3], twist[4], twist[5]
    angle = np.sqrt(wx * wx + wy * wy + wz * wz)
    if angle > 0.0:
        x, y, z = wx / angle, wy / angle, wz / angle
        c, s = np.cos(angle), np.sin(angle)
        t = 1.0 - c
        R = ((t * x * x + c, t * x * y - s * z, t * x * z + s * y),
             (t * x * y + s * z, t * y * y + c, t * y * z - s * x),
             (t * x * z - s * y, t * y * z + s * x, t * z * z + c))
        for col in range(3):
            a, b, d = T[0, col], T[1, col], T[2, col]
            for r in range(3):
                T[r, col] = R[r][0] * a + R[r][1] * b + R[r][2] * d
    for r in range(3):
        T[r, 3] = min(max(T[r, 3] + twist[r], lo[r]), hi[r])
    rpy = (np.arctan2(T[2, 1], T[2, 2]), np.arctan2(-T[2, 0], np.hypot(T[0, 0], T[1, 0])), np.arctan2(T[1, 0], T[0, 0]))
    roll, pitch, yaw = min(max(rpy[0], lo[3]), hi[3]), min(max(rpy[1], lo[4]), hi[4]), min(max(rpy[2], lo[5]), hi[5])
    if (roll, pitch, yaw) != rpy:
        cr, cp, cy = np.cos(roll), np.cos(pitch), np.cos(yaw)
        sr, sp, sy = np.sin(roll), np.sin(pitch), np.sin(yaw)
        T[0, 0], T[0, 1], T[0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
        T[1, 0], T[1, 1], T[1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
        T[2, 0], T[2, 1], T[2, 2] = -sp, cp * sr, cp * cr


@njit(cache=True)
def _hands_step(q, T_o, grasps, table_a, table_b, var_of_q, var_q, T_world_root, tcp, lower, upper, free_object, lo,
                hi, max_step_pos, max_step_rot, method, damping):
    """One step of :meth:`HandPair.step` in place; returns the errors before it."""
    n = var_q.shape[0]
    cols = n + 6 if free_object else n
    poses, jac, err, target = np.empty((2, 4, 4)), np.empty((2, 6, n)), np.empty(12), np.empty((4, 4))
    frames_a, frames_b = np.empty((table_a.shape[0], 3, 4)), np.empty((table_b.shape[0], 3, 4))
    pos, rot = _hands_error(q, T_o, grasps, table_a, table_b, var_of_q, T_world_root, tcp, frames_a, frames_b,
                            poses, jac, err, target)
    _hands_update(q, T_o, grasps, jac, err, var_q, lower, upper, lo, hi, max_step_pos, max_step_rot, method, damping,
                  np.empty((12, cols)), np.empty((12, 12)), np.empty(12), np.empty(cols))
    return pos, rot


@njit(cache=True)
def _hands_restarts(q, T_o, seeds, objects, relative, chosen, grasps_a, grasps_b, reach_a, reach_b, table_a, table_b,
                    var_of_q, var_q, T_world_root, tcp, lower, upper, lo, hi, max_step_pos, max_step_rot, method,
                    damping, tol_pos, tol_rot, max_iterations, stall_iterations):
    """:meth:`HandPair.solve`: each attempt iterates steps until both tools are within the
    tolerances (converged), the iteration cap, or ``stall_iterations`` without a 0.1% gain.
    The converged attempt, else the closest, is copied to q and T_o."""
    n = var_q.shape[0]
    poses, jac, err, target = np.empty((2, 4, 4)), np.empty((2, 6, n)), np.empty(12), np.empty((4, 4))
    frames_a, frames_b = np.empty((table_a.shape[0], 3, 4)), np.empty((table_b.shape[0], 3, 4))
    Jw, A, x, dx = np.empty((12, n + 6)), np.empty((12, 12)), np.empty(12), np.empty(n + 6)
    grasps, local = np.empty((2, 4, 4)), np.empty((4, 4))
    q_try, T_try = q.copy(), T_o.copy()
    total, nearest, nearest_score, nearest_pos, nearest_rot = 0, -1, np.inf, np.inf, np.inf
    for a in range(seeds.shape[0]):
        for c in range(n):
            q_try[var_q[c]] = seeds[a, c]
        grasps[0], grasps[1] = grasps_a[chosen[a, 0]], grasps_b[chosen[a, 1]]
        chain_pose_jacobian(q_try, T_world_root, table_a, var_of_q, tcp[0], frames_a, poses[0], jac[0])
        chain_pose_jacobian(q_try, T_world_root, table_b, var_of_q, tcp[1], frames_b, poses[1], jac[1])
        if relative:  # objects[a] is in the frame of arm b's base link
            base = frames_b[reach_b.base]
            for r in range(3):
                for c in range(4):
                    T_try[r, c] = (base[r, 0] * objects[a, 0, c] + base[r, 1] * objects[a, 1, c]
                                   + base[r, 2] * objects[a, 2, c] + (base[r, 3] if c == 3 else 0.0))
            T_try[3, :] = objects[a, 3]
        else:
            T_try[:, :] = objects[a]
        reachable = True
        for reach, frames, h in ((reach_a, frames_a, 0), (reach_b, frames_b, 1)):
            _compose(T_try, grasps[h], target)
            to_frame(frames[reach.base], target, local)
            s = nearest_sample(reach, local)
            if s < 0:
                reachable = False
                break
            for c in range(reach.var_q.shape[0]):
                q_try[reach.var_q[c]] = reach.values[s, c]
        if not reachable:
            continue
        best, since_best = np.inf, 0
        for it in range(max_iterations + 1):
            pos, rot = _hands_error(q_try, T_try, grasps, table_a, table_b, var_of_q, T_world_root, tcp, frames_a,
                                    frames_b, poses, jac, err, target)
            if pos <= tol_pos and rot <= tol_rot:
                q[:] = q_try
                T_o[:, :] = T_try
                return a, a, total + it, pos, rot
            score = pos / tol_pos + rot / tol_rot
            if score < 0.999 * best:
                best, since_best = score, 0
            else:
                since_best += 1
            if since_best >= stall_iterations or it == max_iterations:
                break
            _hands_update(q_try, T_try, grasps, jac, err, var_q, lower, upper, lo, hi, max_step_pos, max_step_rot,
                          method, damping, Jw, A, x, dx)
        total += it
        if score < nearest_score:  # q_try is where the errors were last measured
            q[:] = q_try
            T_o[:, :] = T_try
            nearest, nearest_score, nearest_pos, nearest_rot = a, score, pos, rot
    return -1, nearest, total, nearest_pos, nearest_rot
