"""Compiled (numba) clearance and collision checks of a robot's balls, forward kinematics inside.

Obstacles are flat arrays: ``otype`` (O,) (SPHERE, BOX, CYLINDER, CAPSULE), ``opose`` (O, 3, 4)
the rotation and origin of each shape in the world, ``oparam`` (O, 3) (sphere: radius; box:
half sides; cylinder and capsule: radius, half length of the z-axis segment) and ``oaabb``
(6, O') world boxes (rows: min xyz, max xyz), padded with boxes at :data:`FAR` to a multiple
of :data:`LANES` columns, so that the loop over them runs whole in SIMD lanes. Every distance
is exact for a ball against the solid shape.

Forward kinematics runs only over the moving rigid bodies ("frames"); balls of links fixed to
a body are stored in that body's frame. Everything a kernel needs is one tuple ``data`` (see
:func:`clearance`) plus a ``scratch`` tuple of work arrays (:func:`make_scratch`), so planners
can call the kernels from their own compiled loops.

:func:`clearance` is the one loop nest: a lower bound on the distance between the robot's balls
and everything they may touch, capped at ``cap``. The hierarchy per configuration: a link's
bounding ball is tested against an obstacle's AABB, then the obstacle itself; only if it is
closer than the best distance so far are the link's own balls placed and measured. Self pairs
measure the two bounding balls first, then each ball of one link against the other's bounding
ball, and only the survivors against the other link's balls. A negative distance (a collision)
ends the configuration. With ``cap = 0`` this is a plain collision test.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from prehensile.kinematics.kernels import FAST, fmax, fmin, joint_transform_sincos, sincos_into

SPHERE, BOX, CYLINDER, CAPSULE = 0, 1, 2, 3
LANES = 8  # SIMD lanes of float64 the obstacles' boxes are padded to (AVX-512)
FAR = 1e30  # m: the corners of the padding boxes, beyond any reach


@njit(cache=True, inline="always")
def _link_pose(poses, pp, origin, f, jtype, axis, joint, out):
    """poses[out] (top 3 rows) = poses[pp] @ origin[f] @ motion (:func:`joint_transform_sincos`
    of the joint value, its sine and cosine ``joint[:, f]``).

    Arrays are indexed in place (no views), which keeps numba from reference counting.
    """
    l00, l01, l02, l03, l10, l11, l12, l13, l20, l21, l22, l23 = joint_transform_sincos(
        jtype, joint[0, f], joint[1, f], joint[2, f], axis[f, 0], axis[f, 1], axis[f, 2],
        origin[f, 0, 0], origin[f, 0, 1], origin[f, 0, 2], origin[f, 0, 3],
        origin[f, 1, 0], origin[f, 1, 1], origin[f, 1, 2], origin[f, 1, 3],
        origin[f, 2, 0], origin[f, 2, 1], origin[f, 2, 2], origin[f, 2, 3])
    for r in range(3):
        p0, p1, p2 = poses[pp, r, 0], poses[pp, r, 1], poses[pp, r, 2]
        poses[out, r, 0] = p0 * l00 + p1 * l10 + p2 * l20
        poses[out, r, 1] = p0 * l01 + p1 * l11 + p2 * l21
        poses[out, r, 2] = p0 * l02 + p1 * l12 + p2 * l22
        poses[out, r, 3] = p0 * l03 + p1 * l13 + p2 * l23 + poses[pp, r, 3]


@njit(cache=True, inline="always")
def _core_distance2(otype, opose, oparam, o, x, y, z):
    """(squared distance from the point (x, y, z) to obstacle o's core, core inflation radius).

    Every shape is a core grown by a radius: a sphere is its centre grown by its radius, a
    capsule its axis segment grown by its radius, a box or cylinder is its own solid (radius 0).
    The distance of a ball (x, y, z, r) to the solid is ``sqrt(d2) - inflation - r``.
    """
    dx, dy, dz = x - opose[o, 0, 3], y - opose[o, 1, 3], z - opose[o, 2, 3]
    if otype[o] == SPHERE:
        return dx * dx + dy * dy + dz * dz, oparam[o, 0]
    lx = opose[o, 0, 0] * dx + opose[o, 1, 0] * dy + opose[o, 2, 0] * dz
    ly = opose[o, 0, 1] * dx + opose[o, 1, 1] * dy + opose[o, 2, 1] * dz
    lz = opose[o, 0, 2] * dx + opose[o, 1, 2] * dy + opose[o, 2, 2] * dz
    if otype[o] == BOX:
        ex = max(abs(lx) - oparam[o, 0], 0.0)
        ey = max(abs(ly) - oparam[o, 1], 0.0)
        ez = max(abs(lz) - oparam[o, 2], 0.0)
        return ex * ex + ey * ey + ez * ez, 0.0
    ez = max(abs(lz) - oparam[o, 1], 0.0)
    if otype[o] == CYLINDER:
        er = max(np.sqrt(lx * lx + ly * ly) - oparam[o, 0], 0.0)
        return er * er + ez * ez, 0.0
    return lx * lx + ly * ly + ez * ez, oparam[o, 0]  # capsule: distance to the axis segment


@njit(cache=True, inline="always")
def _place(poses, f, c, i, out, k):
    """out[k] = poses[f] applied to the point c[i]."""
    x, y, z = c[i, 0], c[i, 1], c[i, 2]
    out[k, 0] = poses[f, 0, 0] * x + poses[f, 0, 1] * y + poses[f, 0, 2] * z + poses[f, 0, 3]
    out[k, 1] = poses[f, 1, 0] * x + poses[f, 1, 1] * y + poses[f, 1, 2] * z + poses[f, 1, 3]
    out[k, 2] = poses[f, 2, 0] * x + poses[f, 2, 1] * y + poses[f, 2, 2] * z + poses[f, 2, 3]


def make_scratch(data):
    """Work arrays for :func:`clearance` with the arrays ``data``: (poses, balls, groups'
    bounding balls, chunks' bounding balls, chunk flags), world coordinates, the squared
    distances of a bounding ball to the obstacles' boxes, and the frames' joint values, sines
    and cosines (3, F)."""
    T_world_base, fparent, centers, gframe, cranges, otype = data[0], data[1], data[11], data[8], data[16], data[19]
    poses = np.empty((fparent.shape[0] + 1, 4, 4))  # poses[0] = base, frame f at f + 1
    poses[0] = T_world_base
    return (poses, np.empty((max(centers.shape[0], 1), 3)), np.empty((max(gframe.shape[0], 1), 3)),
            np.empty((max(cranges.shape[0], 1), 3)), np.zeros(max(cranges.shape[0], 1), dtype=np.int64),
            np.empty(max(data[22].shape[1], 1)), np.zeros((3, fparent.shape[0])))


@njit(cache=True, inline="always")
def _chunk_center(poses, f, cbcenter, k, wk, placed):
    """Place chunk k's bounding ball (frame f) once per configuration."""
    if not placed[k] & 1:
        _place(poses, f + 1, cbcenter, k, wk, k)
        placed[k] |= 1


@njit(cache=True, inline="always")
def _chunk_balls(poses, f, centers, cranges, k, wc, placed):
    """Place chunk k's balls (frame f) once per configuration."""
    if not placed[k] & 2:
        for s in range(cranges[k, 0], cranges[k, 1]):
            _place(poses, f + 1, centers, s, wc, s)
        placed[k] |= 2


@njit(cache=True, inline="always")
def _margin(best, scale, slack):
    """How far apart (m) a ball and what it is tested against may be, beyond touching, and
    still lower ``best`` (:func:`clearance`); 0: only a collision counts."""
    return max(best * scale - slack, 0.0)


# no reference counting (``_nrt=False``): the kernel allocates nothing, and the increfs and
# decrefs numba emits for two dozen array arguments otherwise cost a third of a check
@njit(cache=True, fastmath=FAST, _nrt=False)
def clearance(q, data, scratch, cap, scales, slack):
    """Lower bound on the scaled clearance of the robot's balls at configuration q (dof,), capped.

    Returns ``min(cap, min over the tested ball pairs of (distance + slack) / scale)``: a ball
    s against an obstacle has scale ``bscale[s]``, two balls of self pair p have scale
    ``pscale[p]``. With a scale that bounds how far a
    ball moves (relative to what it is tested against) per unit of a motion parameter, the
    result is how far that parameter may change before any ball can come closer than
    ``-slack`` (m) to anything: with ``slack = 0`` a "free bubble" (Quinlan 1995) per ball
    pair. With scales 1 (:func:`unit_scales`) and no slack it is the clearance in metres. A
    collision returns a negative value, ``distance / scale`` of the pair found (the search
    stops there; touching balls count as free). ``cap = 0`` gives a plain collision test.

    ``data`` = (T_world_base, fparent, fjtype, forigin, faxis, fqidx, fmult, foffset, gframe,
    granges, centers, radii, gbcenter, gbradius, gtest, gchunks, cranges, cbcenter, cbradius,
    otype, opose, oparam, oaabb, prad, pairs). Frames (F) are the moving rigid bodies (a link and
    everything fixed to it): ``fparent`` (-1 for the world base), joint type, origin (F, 4, 4)
    in the parent frame, axis, q index, mimic multiplier and offset. Groups (G) are the links
    with balls: ``gframe`` (G,) their frame, ``granges`` (G, 2) their balls ``[start, stop)``
    (centres in the frame), a bounding ball ``gbcenter`` (G, 3), ``gbradius`` (G,), and their
    chunks ``gchunks`` (G, 2): runs of neighbouring balls ``cranges`` (C, 2) with bounding
    balls ``cbcenter`` (C, 3), ``cbradius`` (C,); groups are sorted by frame. ``gtest`` (G,)
    bool marks the groups tested against obstacles, ``pairs`` (P, 2) the group pairs tested
    against each other, ``prad`` (P,) the sums of their bounding radii. ``scales`` = (gscale
    (G,), pscale (P,), bscale (S,)): ``gscale[g]``
    must bound the world scales of the group's balls; scales must be positive (a tiny value for
    a ball that does not move: it then only counts if it collides). ``scratch`` comes from
    :func:`make_scratch`.

    Order: forward kinematics, the world (groups from the end of the chain, which moves
    fastest), then the self pairs. In a motion check a self pair's scale counts only the joints
    between its two links, so its scaled clearance is rarely the smallest; the world's, found
    first, prunes most pairs at their bounding balls (7 % faster on the MotionBenchMaker Panda
    problems than the reverse order, same evaluations). Each pair of bounding balls (group,
    then chunk) that cannot beat the best distance so far is skipped with everything inside it;
    a group's bounding ball is measured against every obstacle's box at once, and the group
    skipped if none is near enough.
    """
    (_, fparent, fjtype, forigin, faxis, fqidx, fmult, foffset, gframe, granges, centers, radii, gbcenter, gbradius,
     gtest, gchunks, cranges, cbcenter, cbradius, otype, opose, oparam, oaabb, prad, pairs) = data
    poses, wc, wb, wk, placed, gap2, joint = scratch
    gscale, pscale, bscale = scales
    best = cap
    g = 0
    for f in range(fparent.shape[0]):
        joint[0, f] = fmult[f] * q[fqidx[f]] + foffset[f] if fqidx[f] >= 0 else 0.0
    sincos_into(joint[0], joint[1], joint[2])  # all at once, in SIMD lanes
    for f in range(fparent.shape[0]):
        _link_pose(poses, fparent[f] + 1, forigin, f, fjtype[f], faxis, joint, f + 1)
        while g < gframe.shape[0] and gframe[g] == f:
            _place(poses, f + 1, gbcenter, g, wb, g)
            for k in range(gchunks[g, 0], gchunks[g, 1]):
                placed[k] = 0
            g += 1
    for g in range(gframe.shape[0] - 1, -1, -1):
        if not gtest[g]:
            continue
        bx, by, bz, br, f = wb[g, 0], wb[g, 1], wb[g, 2], gbradius[g], gframe[g]
        nearest = np.inf
        for o in range(oaabb.shape[1]):  # branch-free over the padded boxes: it runs in SIMD lanes
            ex = fmax(fmax(oaabb[0, o] - bx, bx - oaabb[3, o]), 0.0)
            ey = fmax(fmax(oaabb[1, o] - by, by - oaabb[4, o]), 0.0)
            ez = fmax(fmax(oaabb[2, o] - bz, bz - oaabb[5, o]), 0.0)
            gap2[o] = ex * ex + ey * ey + ez * ez
            nearest = fmin(nearest, gap2[o])
        reach = _margin(best, gscale[g], slack) + br
        if nearest >= reach * reach:  # every box is farther than reach from the bounding ball
            continue
        for o in range(otype.shape[0]):
            reach = _margin(best, gscale[g], slack) + br
            if gap2[o] >= reach * reach:  # the bounding ball is farther than reach from the box
                continue
            d2, grow = _core_distance2(otype, opose, oparam, o, bx, by, bz)
            reach = _margin(best, gscale[g], slack) + br + grow
            if d2 >= reach * reach:
                continue
            for k in range(gchunks[g, 0], gchunks[g, 1]):
                _chunk_center(poses, f, cbcenter, k, wk, placed)
                d2, grow = _core_distance2(otype, opose, oparam, o, wk[k, 0], wk[k, 1], wk[k, 2])
                reach = _margin(best, gscale[g], slack) + cbradius[k] + grow
                if d2 >= reach * reach:
                    continue
                _chunk_balls(poses, f, centers, cranges, k, wc, placed)
                for s in range(cranges[k, 0], cranges[k, 1]):
                    d2, grow = _core_distance2(otype, opose, oparam, o, wc[s, 0], wc[s, 1], wc[s, 2])
                    reach = _margin(best, bscale[s], slack) + radii[s] + grow
                    if d2 < reach * reach:
                        d = np.sqrt(d2) - grow - radii[s]
                        if d < 0.0:
                            return d / bscale[s]
                        best = (d + slack) / bscale[s]
    for p in range(pairs.shape[0]):
        i, j, both = pairs[p, 0], pairs[p, 1], pscale[p]
        dx, dy, dz = wb[i, 0] - wb[j, 0], wb[i, 1] - wb[j, 1], wb[i, 2] - wb[j, 2]
        reach = _margin(best, both, slack) + prad[p]
        if dx * dx + dy * dy + dz * dz >= reach * reach:
            continue
        fi, fj = gframe[i], gframe[j]
        for ki in range(gchunks[i, 0], gchunks[i, 1]):
            _chunk_center(poses, fi, cbcenter, ki, wk, placed)
            dx, dy, dz = wk[ki, 0] - wb[j, 0], wk[ki, 1] - wb[j, 1], wk[ki, 2] - wb[j, 2]
            reach = _margin(best, both, slack) + cbradius[ki] + gbradius[j]
            if dx * dx + dy * dy + dz * dz >= reach * reach:
                continue
            for kj in range(gchunks[j, 0], gchunks[j, 1]):
                _chunk_center(poses, fj, cbcenter, kj, wk, placed)
                dx, dy, dz = wk[ki, 0] - wk[kj, 0], wk[ki, 1] - wk[kj, 1], wk[ki, 2] - wk[kj, 2]
                reach = _margin(best, both, slack) + cbradius[ki] + cbradius[kj]
                if dx * dx + dy * dy + dz * dz >= reach * reach:
                    continue
                _chunk_balls(poses, fi, centers, cranges, ki, wc, placed)
                _chunk_balls(poses, fj, centers, cranges, kj, wc, placed)
                for s in range(cranges[ki, 0], cranges[ki, 1]):
                    dx, dy, dz = wc[s, 0] - wk[kj, 0], wc[s, 1] - wk[kj, 1], wc[s, 2] - wk[kj, 2]
                    reach = _margin(best, both, slack) + radii[s] + cbradius[kj]
                    if dx * dx + dy * dy + dz * dz >= reach * reach:  # ball s is farther from all of chunk kj
                        continue
                    for t in range(cranges[kj, 0], cranges[kj, 1]):
                        dx, dy, dz = wc[s, 0] - wc[t, 0], wc[s, 1] - wc[t, 1], wc[s, 2] - wc[t, 2]
                        reach = _margin(best, both, slack) + radii[s] + radii[t]
                        if dx * dx + dy * dy + dz * dz < reach * reach:
                            d = np.sqrt(dx * dx + dy * dy + dz * dz) - radii[s] - radii[t]
                            if d < 0.0:
                                return d / both
                            best = (d + slack) / both
    return best


def unit_scales(data) -> tuple:
    """Scales for :func:`clearance` that make it the clearance in metres."""
    return np.ones(data[13].shape[0]), np.ones(data[-1].shape[0]), np.ones(data[11].shape[0])


@njit(cache=True, fastmath=FAST)
def clearance_batch(qs, data, scratch, cap, scales, out):
    """out[b] = :func:`clearance` of qs[b] without slack, for configurations qs (B, dof); out (B,)."""
    for b in range(qs.shape[0]):
        out[b] = clearance(qs[b], data, scratch, cap, scales, 0.0)


@njit(cache=True, inline="always")
def screen_one(q, lower, upper, data, scratch, scales, world_scales, margin):
    """(inside, free, near) for configuration q (dof,): it lies within [lower, upper] (dof,), it
    is free (as :func:`check_batch`), some ball is closer than ``margin`` (m) to an obstacle
    (``world_scales``: :func:`unit_scales` of ``data`` without its self pairs)."""
    inside = True
    for k in range(q.shape[0]):
        inside &= lower[k] <= q[k] <= upper[k]
    world = data[:-1] + (data[-1][:0],)  # without self pairs
    free = clearance(q, data, scratch, 0.0, scales, 0.0) >= 0.0
    return inside, free, clearance(q, world, scratch, margin, world_scales, 0.0) < margin


@njit(cache=True, fastmath=FAST)
def screen_batch(qs, lower, upper, data, scratch, scales, world_scales, margin, inside, free, near):
    """:func:`screen_one` of each configuration of qs (B, dof) into inside, free and near (B,)
    bool: one compiled call for the three tests, given ``data`` once (each array passed costs
    the call time)."""
    for b in range(qs.shape[0]):
        inside[b], free[b], near[b] = screen_one(qs[b], lower, upper, data, scratch, scales, world_scales, margin)


@njit(cache=True, fastmath=FAST)
def free_one(q, data, scratch, scales):
    """True if configuration q (dof,) is free (:func:`check_batch` of one, without the batch)."""
    return clearance(q, data, scratch, 0.0, scales, 0.0) >= 0.0


@njit(cache=True, fastmath=FAST)
def check_batch(qs, data, scratch, scales, out, stop_at_first):
    """Check configurations qs (B, dof); out[b] = qs[b] is free (out (B,) bool).

    ``scales`` as for :func:`clearance` (any valid ones: the test does not depend on them).
    Returns the index of the first colliding configuration, or -1; with ``stop_at_first`` it
    returns there (later entries of ``out`` are not written). The whole batch is one compiled
    call (passing two dozen arrays per call costs more than the checks themselves).
    """
    first = -1
    for b in range(qs.shape[0]):
        out[b] = clearance(qs[b], data, scratch, 0.0, scales, 0.0) >= 0.0
        if not out[b] and first < 0:
            first = b
            if stop_at_first:
                return first
    return first
