"""Path shortcutting (Vahrenkamp 2011 B.3, Alg. 34), compiled.

Random shortcutting picks two positions a < b anywhere on the path (inside segments too, by
arc length in the workspace-weighted metric) and replaces the stretch between them by the
straight segment if that is free. Before and after, redundant waypoints go: first those on a
straight line with their neighbours (no check needed, the segment is the same set of
configurations), then, from each kept waypoint, all up to the farthest one (of the next
``_WINDOW``) it sees, tried farthest first: a blocked check mostly ends within a few clearance
evaluations, a free one covers the whole segment, so few free checks are the cheap way. No
step lengthens the path (the straight segment is never longer than any path between its ends,
in any norm), and every new segment passes :func:`~prehensile.planning.kernels.motion_free`.

Checks are spent only where they pay: a random shortcut is tried only if it shortens the path
by more than ``min_gain`` of its length (in the L1 metric many shortcuts save nothing), and
the pairs of input waypoints found blocked by one pruning are remembered, not checked again
by the next (the check is deterministic). Pruning tries every corner, even one that
saves no length: a trajectory stops at each corner (:mod:`~prehensile.planning.trajectory`).
"""

from __future__ import annotations


import numpy as np
from numba import njit

from prehensile.clock import COMPILING, clock, kernel_clock
from prehensile.planning.certify import check_valid_path, rework_certified
from prehensile.planning.context import PlanningContext, check_resolution
from prehensile.planning.kernels import FREE, NO_LIMIT, assign, distance, motion_free, rng_state, uniform
from prehensile.planning.seeding import planner_rng
from prehensile.settings import FRACTION, NON_NEGATIVE, at_least, check_value


@njit(cache=True, _nrt=False)
def _on_segment(a, b, c, idx, w):
    """True if b lies on the segment a -> c (dof,) (up to rounding)."""
    total = distance(a, c, idx, w)
    if total <= 0.0:
        return distance(a, b, idx, w) <= 0.0
    t = distance(a, b, idx, w) / total
    if t > 1.0 + 1e-9:
        return False
    for k in range(idx.shape[0]):
        j = idx[k]
        if abs(b[j] - (a[j] + t * (c[j] - a[j]))) > 1e-9 * (1.0 + abs(b[j])):
            return False
    return True


_WINDOW = 16  # waypoints ahead that pruning tries to reach (bounds its checks to linear)
# fraction of the path length a random shortcut must save to be worth a check. Median clearance
# evaluations of RRT-Connect on the 400 MotionBenchMaker Panda problems (without certification)
# and mean path length at 0 / 3e-3 / 0.01 / 0.02 / 0.03 / 0.05 / 0.1: 582 / 537 / 501 / 485 /
# 462 / 426 / 411, 7.84 / 7.86 / 7.90 / 7.94 / 7.99 / 8.09 / 8.31 m (16 attempts; none: 8.99 m).
MIN_GAIN = 0.03
# most waypoints random shortcuts add to a path (each adds at most one): the rows reserved for
# them, whatever the attempts (a time limit, not a row count, bounds those)
MAX_INSERTED = 1024


def waypoint_marks(rows: int) -> tuple:
    """Work arrays of :func:`prune` for up to ``rows`` waypoints: ids (rows,) int64 (the input
    waypoint behind a row, -1 for a shortcut point), checked (rows,) bool (the edge from the
    row to the next passed a motion check) and memo (rows, 2) int64 (pairs of ids found
    blocked, rows of -1 free)."""
    ids, checked, memo = np.empty(rows, np.int64), np.empty(rows, np.bool_), np.empty((rows, 2), np.int64)
    ids.fill(-1)  # cheaper than np.full in a query's cold caches
    checked.fill(True)
    memo.fill(-1)
    return ids, checked, memo


@njit(cache=True, _nrt=False)
def _move(path, marks, dst, src):
    """Row src -> dst, with its id and edge flag."""
    ids, checked, _ = marks
    assign(path[dst], path[src])
    ids[dst], checked[dst] = ids[src], checked[src]


@njit(cache=True, _nrt=False)
def _blocked(memo, a, b, record):
    """Whether the pair of input waypoint ids (a, b) is in ``memo``; with ``record``, add it (if
    there is room). Ids -1 (shortcut points) are never remembered."""
    if a < 0 or b < 0:
        return False
    for r in range(memo.shape[0]):
        if memo[r, 0] < 0:
            if record:
                memo[r, 0], memo[r, 1] = a, b
            return False
        if memo[r, 0] == a and memo[r, 1] == b:
            return True
    return False


@njit(cache=True, _nrt=False)
def prune(path, n, marks, idx, w, res, checker, scratch, motion, counters):
    """Drop redundant waypoints of path[:n] in place; returns the new count.

    ``marks`` (:func:`waypoint_marks`) move along with the rows. An edge that replaces
    collinear ones is checked if they all were; an edge found by a motion check is checked.
    Blocked pairs of ids are remembered in the memo and not checked again (across calls).
    """
    ids, checked, memo = marks
    m = 1  # collinear (and repeated) waypoints
    for i in range(1, n - 1):
        if _on_segment(path[m - 1], path[i], path[i + 1], idx, w):
            checked[m - 1] &= checked[i]
        else:
            _move(path, marks, m, i)
            m += 1
    _move(path, marks, m, n - 1)
    n = m + 1
    a, m = 0, 1  # from the anchor a (row m - 1), the farthest waypoint b it sees goes to row m (m <= a + 1 <= b)
    while a < n - 1:
        b = min(n - 1, a + _WINDOW)
        while b > a + 1:
            if not _blocked(memo, ids[a], ids[b], False):
                if motion_free(path[a], path[b], res, checker, scratch, motion, counters, NO_LIMIT, 0) == FREE:
                    checked[m - 1] = True
                    break
                _blocked(memo, ids[a], ids[b], True)
            b -= 1
        _move(path, marks, m, b)
        m += 1
        a = b
    return m


@njit(cache=True, _nrt=False)
def simplify(path, n, marks, iterations, deadline, compiling, min_gain, first, rng, idx, w, res, checker, scratch,
             motion, counters, cum, qa, qb):
    """Prune path[:n] in place if ``first``, make up to ``iterations`` random shortcut attempts
    (each checked only if it saves more than ``min_gain`` of the length) until ``deadline`` (s,
    :func:`~prehensile.clock.clock`, read before each with ``compiling``:
    :func:`~prehensile.clock.kernel_clock`), prune again; returns the new
    count. Each shortcut adds at most one waypoint; the attempts stop early when ``path`` has no
    row left for one more (:data:`MAX_INSERTED`); ``marks`` as for :func:`prune`; ``cum``
    (rows,), qa and qb (dof,) are work arrays, ``rng`` the (1,) uint64 state."""
    ids, checked, _ = marks
    if first:
        n = prune(path, n, marks, idx, w, res, checker, scratch, motion, counters)
    for _ in range(iterations):
        if n < 3 or n == path.shape[0] or kernel_clock(compiling) >= deadline:
            break
        cum[0] = 0.0
        for i in range(n - 1):
            cum[i + 1] = cum[i] + distance(path[i], path[i + 1], idx, w)
        total = cum[n - 1]
        s, e = uniform(rng) * total, uniform(rng) * total
        if s > e:
            s, e = e, s
        i = min(max(np.searchsorted(cum[:n], s, side="right") - 1, 0), n - 2)
        j = min(max(np.searchsorted(cum[:n], e, side="right") - 1, 0), n - 2)
        if i == j:
            continue
        ta = (s - cum[i]) / max(cum[i + 1] - cum[i], 1e-300)
        tb = (e - cum[j]) / max(cum[j + 1] - cum[j], 1e-300)
        for k in range(path.shape[1]):
            qa[k] = path[i, k] + ta * (path[i + 1, k] - path[i, k])
            qb[k] = path[j, k] + tb * (path[j + 1, k] - path[j, k])
        if (e - s) - distance(qa, qb, idx, w) <= min_gain * total:  # too little to gain
            continue
        if motion_free(qa, qb, res, checker, scratch, motion, counters, NO_LIMIT, 0) != FREE:
            continue
        # path[:i+1], qa, qb, path[j+1:n]: j - i waypoints out, two in; qb -> path[j + 1] is part of edge j
        tail, old, rest_checked = i + 3, j + 1, checked[j]
        if tail > old:
            for k in range(n - 1, old - 1, -1):
                _move(path, marks, k + tail - old, k)
        elif tail < old:
            for k in range(old, n):
                _move(path, marks, k + tail - old, k)
        assign(path[i + 1], qa)
        assign(path[i + 2], qb)
        ids[i + 1], ids[i + 2] = -1, -1
        checked[i + 1], checked[i + 2] = True, rest_checked
        n += tail - old
    return prune(path, n, marks, idx, w, res, checker, scratch, motion, counters)


def shortcut(ctx: PlanningContext, path: np.ndarray, rng: np.random.Generator | int | None, iterations: int = 100,
             time_budget_s: float = 0.05, resolution: float | None = None,
             stats: np.ndarray | None = None, min_gain: float = MIN_GAIN, certify: bool = True,
             retries: int = 3) -> np.ndarray:
    """A shorter path with the same ends: pruning, random shortcuts, pruning.

    Args:
        ctx: the planning context (sphere model, metric).
        path: (N, dof) full configurations, a valid path (:func:`~prehensile.planning.certify.check_valid_path`).
        rng: random source or seed (:func:`~prehensile.planning.seeding.planner_rng`; the same seed gives
            the same result, unless ``time_budget_s`` cuts the attempts short).
        iterations: random shortcut attempts.
        time_budget_s: stop the random attempts after this time (s), per try (see ``retries``).
        resolution: edge-check resolution (m); default ``ctx.resolution``.
        stats: optional (1,) int64 counter of clearance evaluations (incremented).
        min_gain: a random shortcut is checked only if it shortens the path by more than this
            fraction of its length (0: every one; larger values spend fewer checks on small gains).
        certify: return a path that passes :func:`~prehensile.planning.certify.certify_path`
            on the exact geometry, or the input path (a warning is logged if it fails too): new
            edges are checked on the balls, which
            may miss parts of the geometry (a spherized URDF). A shortened path that fails is
            made again with covering balls on the links that collided, or at half the
            resolution (:func:`~prehensile.planning.certify.rework_certified`).
        retries: tries after a failed certification before the input path is returned.

    Returns:
        (M, dof) waypoints, M <= N + min(iterations, :data:`MAX_INSERTED`), first and last equal
        to the input's.
    """
    for name, value, rule in (("iterations", iterations, at_least(0)), ("time_budget_s", time_budget_s, NON_NEGATIVE),
                              ("min_gain", min_gain, FRACTION), ("retries", retries, at_least(0))):
        check_value(f"shortcut: {name}", value, rule)
    path = check_valid_path(ctx, path, "shortcut").copy()  # returned as it is if nothing shorter passes
    res = ctx.resolution if resolution is None else check_resolution(resolution, "shortcut: resolution")
    rng = planner_rng(rng)

    def shorten(context: PlanningContext, edge_res: float) -> np.ndarray:
        return shortened(context, path, rng, int(iterations), time_budget_s, edge_res, stats, min_gain)

    if not certify:
        return shorten(ctx, res)
    return rework_certified(ctx, path, shorten, res, int(retries), "shortcut")[0]


def shortened(ctx: PlanningContext, path: np.ndarray, rng: np.random.Generator, iterations: int,
              time_budget_s: float, res: float, stats: np.ndarray | None, min_gain: float) -> np.ndarray:
    """:func:`shortcut` of the valid path (N, dof) on ``ctx``'s balls at resolution ``res`` (m),
    without certification; ``path`` itself if it has fewer than 3 waypoints."""
    if len(path) < 3:
        return path
    buffer = np.empty((len(path) + min(iterations, MAX_INSERTED), ctx.model.dof))
    buffer[:len(path)] = path
    marks = waypoint_marks(len(buffer))
    marks[0][:len(path)] = np.arange(len(path))
    n = shortcut_rows(ctx, buffer, len(path), marks, rng, iterations, min_gain, time_budget_s, res, stats,
                      prune_first=True)
    return buffer[:n].copy()


def shortcut_rows(ctx: PlanningContext, buffer: np.ndarray, n: int, marks: tuple, rng: np.random.Generator,
                  iterations: int, min_gain: float, time_budget_s: float, res: float, stats: np.ndarray | None,
                  prune_first: bool) -> int:
    """:func:`shortcut` of the valid path buffer[:n] (n >= 3), in place; returns the new count.
    ``buffer`` (rows > n, dof; :data:`MAX_INSERTED` more rows let every attempt run) and ``marks``
    (:func:`waypoint_marks` of as many rows, ids set for the first n) are overwritten. Without
    ``prune_first`` the path is not pruned first: it has been (:func:`prune`, with these marks),
    and the pairs its memo holds blocked are not checked again."""
    return simplify(buffer, n, marks, iterations, clock() + time_budget_s, COMPILING, min_gain, prune_first,
                    rng_state(rng), ctx.space.indices, ctx.space.weights, res, ctx.spheres.data, ctx.scratch,
                    ctx.motion_arrays(res), np.zeros(1, dtype=np.int64) if stats is None else stats,
                    np.empty(len(buffer)), np.empty(ctx.model.dof), np.empty(ctx.model.dof))
