"""Compiled (numba) forward kinematics and Jacobian kernels on the flat model arrays.

Poses are written in place into preallocated float64 arrays; the public functions in
:mod:`prehensile.kinematics.forward` wrap them with batching and validation.
"""

from __future__ import annotations

import numpy as np
from numba import njit

FIXED, REVOLUTE, PRISMATIC = 0, 1, 2


@njit(cache=True, fastmath=False, inline="always")
def _local_pose(origin, jtype, axis, value, out):
    """out (4, 4) = origin @ motion(jtype, axis, value)."""
    if jtype == FIXED:
        out[:, :] = origin
        return
    if jtype == PRISMATIC:
        for r in range(3):
            out[r, 0] = origin[r, 0]
            out[r, 1] = origin[r, 1]
            out[r, 2] = origin[r, 2]
            out[r, 3] = origin[r, 3] + value * (origin[r, 0] * axis[0] + origin[r, 1] * axis[1] + origin[r, 2] * axis[2])
        out[3, :] = origin[3, :]
        return
    x, y, z = axis[0], axis[1], axis[2]
    c, s = np.cos(value), np.sin(value)
    t = 1.0 - c
    m00 = t * x * x + c
    m01 = t * x * y - s * z
    m02 = t * x * z + s * y
    m10 = t * x * y + s * z
    m11 = t * y * y + c
    m12 = t * y * z - s * x
    m20 = t * x * z - s * y
    m21 = t * y * z + s * x
    m22 = t * z * z + c
    for r in range(3):
        a0, a1, a2 = origin[r, 0], origin[r, 1], origin[r, 2]
        out[r, 0] = a0 * m00 + a1 * m10 + a2 * m20
        out[r, 1] = a0 * m01 + a1 * m11 + a2 * m21
        out[r, 2] = a0 * m02 + a1 * m12 + a2 * m22
        out[r, 3] = origin[r, 3]
    out[3, :] = origin[3, :]


@njit(cache=True, inline="always")
def _compose(A, B, out):
    """out = A @ B for rigid transforms (last row assumed [0, 0, 0, 1])."""
    for r in range(3):
        a0, a1, a2 = A[r, 0], A[r, 1], A[r, 2]
        out[r, 0] = a0 * B[0, 0] + a1 * B[1, 0] + a2 * B[2, 0]
        out[r, 1] = a0 * B[0, 1] + a1 * B[1, 1] + a2 * B[2, 1]
        out[r, 2] = a0 * B[0, 2] + a1 * B[1, 2] + a2 * B[2, 2]
        out[r, 3] = a0 * B[0, 3] + a1 * B[1, 3] + a2 * B[2, 3] + A[r, 3]
    out[3, 0] = 0.0
    out[3, 1] = 0.0
    out[3, 2] = 0.0
    out[3, 3] = 1.0


@njit(cache=True)
def fk_single(q, T_world_base, parent, jtype, origin, axis, qidx, mult, offset, out):
    """All link poses for one configuration q (dof,) into out (L, 4, 4)."""
    local = np.empty((4, 4))
    for i in range(parent.shape[0]):
        value = 0.0
        if qidx[i] >= 0:
            value = mult[i] * q[qidx[i]] + offset[i]
        if parent[i] < 0:
            _local_pose(origin[i], jtype[i], axis[i], value, local)
            _compose(T_world_base, local, out[i])
        else:
            _local_pose(origin[i], jtype[i], axis[i], value, local)
            _compose(out[parent[i]], local, out[i])


@njit(cache=True)
def fk_batch(q, T_world_base, parent, jtype, origin, axis, qidx, mult, offset, out):
    """Link poses for q (B, dof) into out (B, L, 4, 4)."""
    for b in range(q.shape[0]):
        fk_single(q[b], T_world_base, parent, jtype, origin, axis, qidx, mult, offset, out[b])


@njit(cache=True)
def jacobian_single(poses, link, point, local, parent, jtype, axis, qidx, mult, out):
    """Frame Jacobian (6, dof) of ``point`` (3,) fixed in ``link`` into out (zeroed here).

    Rows are (linear, angular) velocity; in world axes (``local`` False) or the link's axes.
    """
    out[:, :] = 0.0
    T = poses[link]
    p = np.empty(3)
    for r in range(3):
        p[r] = T[r, 0] * point[0] + T[r, 1] * point[1] + T[r, 2] * point[2] + T[r, 3]
    w = np.empty(3)
    j = link
    while j >= 0:
        if jtype[j] != FIXED:
            Tj = poses[j]
            for r in range(3):
                w[r] = mult[j] * (Tj[r, 0] * axis[j, 0] + Tj[r, 1] * axis[j, 1] + Tj[r, 2] * axis[j, 2])
            c = qidx[j]
            if jtype[j] == REVOLUTE:
                dx, dy, dz = p[0] - Tj[0, 3], p[1] - Tj[1, 3], p[2] - Tj[2, 3]
                out[0, c] += w[1] * dz - w[2] * dy
                out[1, c] += w[2] * dx - w[0] * dz
                out[2, c] += w[0] * dy - w[1] * dx
                out[3, c] += w[0]
                out[4, c] += w[1]
                out[5, c] += w[2]
            else:
                out[0, c] += w[0]
                out[1, c] += w[1]
                out[2, c] += w[2]
        j = parent[j]
    if local:
        tmp = np.empty(3)
        for c in range(out.shape[1]):
            for block in range(2):
                for r in range(3):
                    tmp[r] = T[0, r] * out[3 * block, c] + T[1, r] * out[3 * block + 1, c] + T[2, r] * out[3 * block + 2, c]
                for r in range(3):
                    out[3 * block + r, c] = tmp[r]


@njit(cache=True)
def fk_jacobian_batch(q, T_world_base, link, point, local, parent, jtype, origin, axis, qidx, mult, offset, poses, out):
    """Poses (B, L, 4, 4) and Jacobians (B, 6, dof) of ``point`` in ``link`` for q (B, dof)."""
    for b in range(q.shape[0]):
        fk_single(q[b], T_world_base, parent, jtype, origin, axis, qidx, mult, offset, poses[b])
        jacobian_single(poses[b], link, point, local, parent, jtype, axis, qidx, mult, out[b])
