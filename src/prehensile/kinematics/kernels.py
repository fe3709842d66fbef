"""Compiled (numba) forward kinematics and Jacobian kernels.

They read the model's packed ``joint_table`` (L, 20) (see
:attr:`prehensile.model.RobotModel.joint_table`) and write poses in place into preallocated
float64 arrays (L, 4, 4). Columns of the table: 0 parent, 1 joint type, 2 q index,
3 multiplier, 4 offset, 5-7 axis, 8-19 the top three rows of the joint origin.

The joint math, :func:`joint_transform` and :func:`joint_column`, is also inlined into the IK
(:mod:`prehensile.ik.kernels`) and sphere-collision kernels. It takes and returns scalars:
arrays passed into an inlined function cost reference counting in every loop iteration.
numba's cache does not notice edits to it from those modules: delete their ``__pycache__``.
"""

from __future__ import annotations

import math

import numpy as np
from llvmlite import ir
from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic

FIXED, REVOLUTE, PRISMATIC = 0, 1, 2

# fast-math without the "no NaN / no inf" assumptions, so that the finiteness checks survive
FAST = {"nsz", "arcp", "contract", "afn", "reassoc"}


def _float_intrinsic(name: str):
    """A compiled-only function ``f(a, b)`` of two floats that calls the LLVM intrinsic ``name``
    with the "no NaNs" flag (the kernels' arguments are checked finite)."""

    @intrinsic
    def call(typingctx, a, b):
        def codegen(context, builder, signature, args):
            double = ir.DoubleType()
            fn = cgutils.get_or_insert_function(builder.module, ir.FunctionType(double, [double, double]), name)
            values = [context.cast(builder, v, t, types.float64) for v, t in zip(args, signature.args)]
            return builder.call(fn, values, fastmath=("nnan", "nsz"))

        return types.float64(a, b), codegen

    return call


# min and max of two floats as LLVM's minnum / maxnum, which its loop vectorizer turns into SIMD
# reductions (the builtins min and max compile to compares and selects that it keeps scalar)
fmin = _float_intrinsic("llvm.minnum.f64")
fmax = _float_intrinsic("llvm.maxnum.f64")


# Taylor coefficients of sin and cos, highest first: on |r| <= pi/4 the first term left out is
# below 5e-17 (a libm call for each costs about as much as the whole polynomial pair)
_SIN = tuple((-1.0) ** k / math.factorial(2 * k + 1) for k in range(8, 0, -1))
_COS = tuple((-1.0) ** k / math.factorial(2 * k) for k in range(8, 0, -1))
_HALF_PI_HI, _HALF_PI_LO = 1.5707963267948966, 6.123233995736766e-17  # pi / 2 = HI + LO


@njit(cache=True, inline="always")
def sincos(x):
    """(sin x, cos x) (x in rad) from x = k pi/2 + r, |r| <= pi/4: within 2e-16 for |x| <= 8,
    within about 1e-16 |x| beyond."""
    k = np.floor(x * (2.0 / np.pi) + 0.5)
    r = (x - k * _HALF_PI_HI) - k * _HALF_PI_LO
    r2 = r * r
    s = c = 0.0
    for a in _SIN:
        s = (s + a) * r2
    for a in _COS:
        c = (c + a) * r2
    s, c = r + r * s, 1.0 + c
    quadrant = int(k) & 3  # selects, no branches: a loop over angles runs in SIMD lanes
    if quadrant & 1:
        s, c = c, s
    return (-s if quadrant & 2 else s), (-c if (quadrant + 1) & 2 else c)


@njit(cache=True, inline="always")
def sincos_into(x, sin_out, cos_out):
    """sin_out[i], cos_out[i] = :func:`sincos` (x[i]) for x (n,) (rad), in SIMD lanes."""
    for i in range(x.shape[0]):
        sin_out[i], cos_out[i] = sincos(x[i])


@njit(cache=True, inline="always")
def joint_transform(jtype, value, x, y, z, o00, o01, o02, o03, o10, o11, o12, o13, o20, o21, o22, o23):
    """Top three rows of ``origin @ motion``, a link's pose in its parent link's frame.

    ``origin`` (3, 4) comes as its 12 entries o00 ... o23 (row-major, m) and goes out the
    same way, so that the callers keep everything in registers. The motion is a rotation by
    ``value`` (rad) about the unit axis (x, y, z) (Rodrigues; about z: a plane rotation) for a
    REVOLUTE joint, a translation by ``value`` (m) along it for a PRISMATIC one, none for a
    FIXED one.
    """
    s, c = sincos(value) if jtype == REVOLUTE else (0.0, 1.0)
    return joint_transform_sincos(jtype, value, s, c, x, y, z, o00, o01, o02, o03, o10, o11, o12, o13, o20, o21,
                                  o22, o23)


@njit(cache=True, inline="always")
def joint_transform_sincos(jtype, value, s, c, x, y, z, o00, o01, o02, o03, o10, o11, o12, o13, o20, o21, o22, o23):
    """:func:`joint_transform` given s, c = :func:`sincos` (value) of a REVOLUTE joint (callers
    computing many angles at once, :func:`sincos_into`)."""
    if jtype == REVOLUTE and x == 0.0 and y == 0.0:  # (0, 0, +-1), most URDF joints
        s *= z
        o00, o01 = o00 * c + o01 * s, o01 * c - o00 * s
        o10, o11 = o10 * c + o11 * s, o11 * c - o10 * s
        o20, o21 = o20 * c + o21 * s, o21 * c - o20 * s
    elif jtype == REVOLUTE:
        t = 1.0 - c
        m00, m01, m02 = t * x * x + c, t * x * y - s * z, t * x * z + s * y
        m10, m11, m12 = t * x * y + s * z, t * y * y + c, t * y * z - s * x
        m20, m21, m22 = t * x * z - s * y, t * y * z + s * x, t * z * z + c
        o00, o01, o02 = o00 * m00 + o01 * m10 + o02 * m20, o00 * m01 + o01 * m11 + o02 * m21, o00 * m02 + o01 * m12 + o02 * m22
        o10, o11, o12 = o10 * m00 + o11 * m10 + o12 * m20, o10 * m01 + o11 * m11 + o12 * m21, o10 * m02 + o11 * m12 + o12 * m22
        o20, o21, o22 = o20 * m00 + o21 * m10 + o22 * m20, o20 * m01 + o21 * m11 + o22 * m21, o20 * m02 + o21 * m12 + o22 * m22
    elif jtype == PRISMATIC:
        o03 += value * (o00 * x + o01 * y + o02 * z)
        o13 += value * (o10 * x + o11 * y + o12 * z)
        o23 += value * (o20 * x + o21 * y + o22 * z)
    return o00, o01, o02, o03, o10, o11, o12, o13, o20, o21, o22, o23


@njit(cache=True, fastmath=FAST, _nrt=False)
def fk_into(q, T_world_base, table, out):
    """Poses of all links for one configuration q (dof,) into out (L, 4, 4).

    Returns False (leaving ``out`` partly written) if q holds a NaN or infinity.
    """
    for k in range(q.shape[0]):
        if not np.isfinite(q[k]):
            return False
    for i in range(table.shape[0]):
        parent, jtype = int(table[i, 0]), int(table[i, 1])
        value = table[i, 3] * q[int(table[i, 2])] + table[i, 4] if jtype != FIXED else 0.0
        l00, l01, l02, l03, l10, l11, l12, l13, l20, l21, l22, l23 = joint_transform(
            jtype, value, table[i, 5], table[i, 6], table[i, 7], table[i, 8], table[i, 9], table[i, 10], table[i, 11],
            table[i, 12], table[i, 13], table[i, 14], table[i, 15], table[i, 16], table[i, 17], table[i, 18], table[i, 19])
        P = T_world_base if parent < 0 else out[parent]
        for r in range(3):
            b0, b1, b2 = P[r, 0], P[r, 1], P[r, 2]
            out[i, r, 0] = b0 * l00 + b1 * l10 + b2 * l20
            out[i, r, 1] = b0 * l01 + b1 * l11 + b2 * l21
            out[i, r, 2] = b0 * l02 + b1 * l12 + b2 * l22
            out[i, r, 3] = b0 * l03 + b1 * l13 + b2 * l23 + P[r, 3]
        out[i, 3, 0] = 0.0
        out[i, 3, 1] = 0.0
        out[i, 3, 2] = 0.0
        out[i, 3, 3] = 1.0
    return True


@njit(cache=True, _nrt=False)
def fk_batch_into(q, T_world_base, table, out):
    """Poses for q (B, dof) into out (B, L, 4, 4); returns the first row index holding a
    NaN or infinity, or -1."""
    for b in range(q.shape[0]):
        if not fk_into(q[b], T_world_base, table, out[b]):
            return b
    return -1


@njit(cache=True, inline="always")
def joint_column(jtype, m, x, y, z, r00, r01, r02, r10, r11, r12, r20, r21, r22, dx, dy, dz):
    """A joint's world-axes Jacobian column for a point: 6 scalars, the point's velocity (m/s)
    over the angular velocity (rad/s) per unit joint velocity.

    The joint's world axis is w = m R (x, y, z), R (3, 3) the world rotation of the joint's
    link (entries r00 ... r22) and m the mimic multiplier; a REVOLUTE joint gives (w x d, w)
    with d (m) from the link's origin to the point, a PRISMATIC one (w, 0).
    """
    wx = m * (r00 * x + r01 * y + r02 * z)
    wy = m * (r10 * x + r11 * y + r12 * z)
    wz = m * (r20 * x + r21 * y + r22 * z)
    if jtype == REVOLUTE:
        return wy * dz - wz * dy, wz * dx - wx * dz, wx * dy - wy * dx, wx, wy, wz
    return wx, wy, wz, 0.0, 0.0, 0.0


@njit(cache=True, fastmath=FAST, _nrt=False)
def jacobian_into(poses, link, point, table, out):
    """World-axes frame Jacobian (6, dof) of ``point`` (3,), given in ``link``'s frame.

    Rows 0-2: velocity of the point; rows 3-5: angular velocity. ``poses`` (L, 4, 4) from
    :func:`fk_into`. Mimic joints add their multiplier-scaled column to their leader's.
    """
    out[:, :] = 0.0
    T = poses[link]
    px = T[0, 0] * point[0] + T[0, 1] * point[1] + T[0, 2] * point[2] + T[0, 3]
    py = T[1, 0] * point[0] + T[1, 1] * point[1] + T[1, 2] * point[2] + T[1, 3]
    pz = T[2, 0] * point[0] + T[2, 1] * point[1] + T[2, 2] * point[2] + T[2, 3]
    j = link
    while j >= 0:
        jtype = int(table[j, 1])
        if jtype != FIXED:
            Tj = poses[j]
            col = joint_column(jtype, table[j, 3], table[j, 5], table[j, 6], table[j, 7],
                               Tj[0, 0], Tj[0, 1], Tj[0, 2], Tj[1, 0], Tj[1, 1], Tj[1, 2], Tj[2, 0], Tj[2, 1], Tj[2, 2],
                               px - Tj[0, 3], py - Tj[1, 3], pz - Tj[2, 3])
            c = int(table[j, 2])
            for k in range(6):
                out[k, c] += col[k]
        j = int(table[j, 0])


@njit(cache=True)
def fk_jacobian_batch_into(q, T_world_base, link, point, table, pose, jac):
    """Pose (B, 4, 4) of ``link`` and world-axes Jacobians (B, 6, dof) of ``point`` for
    q (B, dof); returns the first row index holding a NaN or infinity, or -1."""
    poses = np.empty((table.shape[0], 4, 4))
    for b in range(q.shape[0]):
        if not fk_into(q[b], T_world_base, table, poses):
            return b
        jacobian_into(poses, link, point, table, jac[b])
        pose[b] = poses[link]
    return -1
