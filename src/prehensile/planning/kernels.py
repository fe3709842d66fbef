"""Compiled planning primitives: random numbers, the weighted metric, nearest neighbours and
motion checks with free bubbles.

Motion check (:func:`motion_free`). The segment qa -> qb is parameterised by s in [0, 1]. From
the context's per-ball joint weights (:mod:`prehensile.planning.context`) it first bounds how
far every ball can move over the whole segment against the world (all joints on its path),
and every link of a self pair against the other (only the joints below their common ancestor).
The sphere kernel divides each ball-pair clearance by the sum of those bounds, so a
configuration at s with scaled clearance c proves the whole stretch [s - c, s + c] free: no
ball can travel farther than its distance to anything it may hit ("free bubbles", Quinlan
1995; Vahrenkamp 2011 C.2). The check tests the ends not known free first (qb, a planner's new
node, then qa), then the midpoints of the stretches not yet covered, breadth first (a
bisection order, so a collision in the middle shows early). A stretch no wider than two
bubbles like the one beside it is tested one such bubble radius in from that side instead:
where the clearance changes little, two evaluations then cover it, where its midpoint would
leave two slivers (2.4 % fewer evaluations in the median of the 400 MotionBenchMaker Panda
problems). Ends known free (tree nodes, path points) are not evaluated: their
neighbourhoods are covered like any other stretch.

Resolution (Vahrenkamp 2011 B.2). Sampling so that no ball moves more than ``resolution``
between checks lets a ball overlap what it passes by up to half a resolution step between
two free samples. The check allows the same and no more, pair by pair: each sample's bubble
is the stretch over which no ball can move farther than its clearance plus half a resolution
step (``slack`` of :func:`~prehensile.collision.sphere_kernels.clearance`), and at least the
stretch over which no ball moves more than half a step. Where only slow balls are near
anything, samples lie farther apart than the fastest ball's step. A free answer is therefore at
least as strong as sampling at ``resolution``; where the balls keep a distance it is
continuous.

The planners' kernels (here, :mod:`~prehensile.planning.rrt_connect`,
:mod:`~prehensile.planning.shortcut`) are compiled without reference counting
(``_nrt=False``): they allocate nothing, and numba's atomic reference counts on array views
and tuples of arrays took about a quarter of the planning time.
"""

from __future__ import annotations

import numpy as np
from numba import njit

from prehensile.collision import sphere_kernels as SK
from prehensile.kinematics.kernels import FAST, fmax

_CAP = 0.25
_TINY = 1e-12  # scale of a group that does not move on a segment: it only counts if it collides
_GOLDEN, _MIX1, _MIX2 = np.uint64(0x9E3779B97F4A7C15), np.uint64(0xBF58476D1CE4E5B9), np.uint64(0x94D049BB133111EB)
_S30, _S27, _S31, _S11 = np.uint64(30), np.uint64(27), np.uint64(31), np.uint64(11)


def rng_state(rng: np.random.Generator) -> np.ndarray:
    """(1,) uint64 state of the compiled generator, drawn from ``rng`` (same rng seed, same stream)."""
    return rng.bit_generator.random_raw(1)


@njit(cache=True, _nrt=False)
def uniform(state):
    """A float in [0, 1) from the splitmix64 generator with state (1,) uint64 (advanced in place)."""
    state[0] += _GOLDEN
    z = state[0]
    z = (z ^ (z >> _S30)) * _MIX1
    z = (z ^ (z >> _S27)) * _MIX2
    z = z ^ (z >> _S31)
    return (z >> _S11) * (1.0 / 9007199254740992.0)


@njit(cache=True, inline="always")
def assign(dst, src):
    """dst[:] = src (1-d arrays) element by element: kernels compiled without reference
    counting cannot copy whole rows."""
    for k in range(src.shape[0]):
        dst[k] = src[k]


@njit(cache=True, _nrt=False)
def distance(a, b, idx, w):
    """Workspace-weighted distance (m) of configurations a, b (dof,) over the variables idx (n,)
    with weights w (n,)."""
    d = 0.0
    for k in range(idx.shape[0]):
        d += w[k] * abs(a[idx[k]] - b[idx[k]])
    return d


@njit(cache=True, _nrt=False)
def path_length(path, idx, w):
    """Workspace-weighted length (m) of path (N, dof) over the variables idx (n,) with weights w (n,)."""
    total = 0.0
    for i in range(path.shape[0] - 1):
        total += distance(path[i], path[i + 1], idx, w)
    return total


@njit(cache=True, fastmath=FAST, _nrt=False)
def nearest(points, count, x, idx, w, work):
    """(index, distance) of the node nearest to x (dof,) among the first ``count`` nodes, given
    as weighted coordinates ``points`` (n, N): ``points[k, i] = w[k] * q_i[idx[k]]`` (inf for a
    node to leave out); (-1, inf) if there is none. ``work`` (N,) is scratch.

    Node after node in the inner loop, so that the scan runs in SIMD lanes.
    """
    for i in range(count):
        work[i] = 0.0
    for k in range(idx.shape[0]):
        xk, row = w[k] * x[idx[k]], points[k]
        for i in range(count):
            work[i] += abs(row[i] - xk)
    best, arg = np.inf, -1
    for i in range(count):
        if work[i] < best:
            best, arg = work[i], i
    return arg, best


@njit(cache=True, fastmath=FAST, _nrt=False)
def _scales(qa, qb, pairs, motion):
    """Fill the clearance scales for the segment qa -> qb; returns the farthest any ball moves (m)."""
    Wball, Wgroup, qgroup, pcut, (gscale, pscale, bscale), _, _, dq, below = motion
    for s in range(bscale.shape[0]):
        bscale[s] = _TINY
    for k in range(qa.shape[0]):  # dq[dof] stays 0: the variable of the padding in qgroup
        dq[k] = abs(qb[k] - qa[k])
        if dq[k] != 0.0:  # skips the joints not planned
            for s in range(bscale.shape[0]):
                bscale[s] += Wball[k, s] * dq[k]
    longest = 0.0
    for s in range(bscale.shape[0]):  # in SIMD lanes
        longest = fmax(longest, bscale[s])
    for g in range(Wgroup.shape[0]):  # below[g, c]: bound from the c joints nearest to g's link
        acc = _TINY
        for i in range(Wgroup.shape[1]):
            acc += Wgroup[g, i] * dq[qgroup[g, i]]
            below[g, i + 1] = acc
        gscale[g] = acc  # at least each of the group's balls' (a sum of the joints' largest weights)
    for p in range(pscale.shape[0]):
        pscale[p] = below[pairs[p, 0], pcut[p, 0]] + below[pairs[p, 1], pcut[p, 1]]
    return longest


FREE, BLOCKED, UNDECIDED = 1, 0, -1  # motion check results
NO_LIMIT = 1 << 62  # a budget that decides every segment


@njit(cache=True, _nrt=False)
def motion_free(qa, qb, res, checker, scratch, motion, counters, budget, new_ends):
    """Check the segment qa -> qb (dof,) for the sphere model (see the module doc).

    Args:
        qa, qb: configurations (dof,).
        res: resolution (m) where the clearance does not cover the segment.
        checker, scratch: the sphere checker's ``data`` and work arrays.
        motion: ``PlanningContext.motion_arrays(res)``.
        counters: counters[0] is incremented per clearance evaluation.
        budget: most clearance evaluations to spend.
        new_ends: 0 if both ends are known free (the first evaluation is then the midpoint,
            where a blocked shortcut or pruning is most often blocked); 1 if qb is new (tested
            first: most extensions toward a sample end in a collision), qa known free; 2 if
            both are new (qb, then qa).

    Returns:
        FREE, BLOCKED, or UNDECIDED when the budget ran out first.
    """
    scales, queue, q = motion[4], motion[5], motion[6]
    longest = _scales(qa, qb, checker[-1], motion)
    slack = 0.5 * res
    half = slack / max(longest, _TINY)  # the stretch over which no ball moves more than half a step
    lo, hi, spent = 0.0, 1.0, 0  # the stretch (lo, hi) is left to cover
    if new_ends >= 1:
        counters[0] += 1
        spent = 1
        cover_b = SK.clearance(qb, checker, scratch, _CAP, scales, slack)
        if cover_b < 0.0:
            return BLOCKED
        if longest <= _TINY or cover_b >= 1.0:  # nothing moves, or qb's bubble holds the segment
            return FREE
        hi = 1.0 - max(cover_b, half)  # negative on a segment shorter than half a step
    if new_ends == 2:
        if spent >= budget:
            return UNDECIDED
        counters[0] += 1
        spent += 1
        cover_a = SK.clearance(qa, checker, scratch, min(max(hi, 0.0), _CAP), scales, slack)  # hi < 0: a plain test
        if cover_a < 0.0:
            return BLOCKED
        lo = max(cover_a, half)
    if longest <= _TINY or lo >= hi:
        return FREE
    size = queue.shape[0]
    head, tail = 0, 1
    queue[0, 0], queue[0, 1], queue[0, 2] = lo, hi, 0.0
    while head < tail:
        if spent >= budget:
            return UNDECIDED
        a, b, near = queue[head % size, 0], queue[head % size, 1], queue[head % size, 2]
        head += 1
        mid, h = 0.5 * (a + b), 0.5 * (b - a)
        if abs(near) < h <= 2.0 * abs(near):  # near: the radius of the bubble beside a (> 0) or b (< 0)
            mid = a + near if near > 0.0 else b + near
        for k in range(q.shape[0]):
            q[k] = qa[k] + mid * (qb[k] - qa[k])
        counters[0] += 1
        spent += 1
        need = max(mid - a, b - mid)  # the bubble that covers (a, b)
        cover = SK.clearance(q, checker, scratch, min(need, _CAP) if need > half else 0.0, scales, slack)
        if cover < 0.0:
            return BLOCKED
        r = max(cover, half)
        if mid - r <= a and b <= mid + r:
            continue
        if tail - head + 2 > size:  # cannot happen with the queue of motion_arrays(res); stay sound
            return BLOCKED
        if mid - r > a:
            queue[tail % size, 0], queue[tail % size, 1], queue[tail % size, 2] = a, mid - r, -r
            tail += 1
        if b > mid + r:
            queue[tail % size, 0], queue[tail % size, 1], queue[tail % size, 2] = mid + r, b, r
            tail += 1
    return FREE


@njit(cache=True, _nrt=False)
def motions_free(qa, qb, out, res, checker, scratch, motion, counters):
    """out[k] = True if the segment qa[k] -> qb[k] (rows of (n, dof), both ends new) is FREE
    (:func:`motion_free`, decided to the end)."""
    for k in range(qa.shape[0]):
        out[k] = motion_free(qa[k], qb[k], res, checker, scratch, motion, counters, NO_LIMIT, 2) == FREE
