"""Bidirectional RRT-Connect (Kuffner & LaValle 2000; Vahrenkamp 2011 ch. 2, Alg. 1-3), compiled.

The whole search runs in one numba kernel: sampling, nearest neighbours (a linear scan of the
tree's nodes in the workspace-weighted metric, in SIMD lanes), extension and the motion
checks with the sphere model (:func:`~prehensile.planning.kernels.motion_free`). Per
iteration one tree extends one step toward a uniform sample, stepping from its nearest node
*toward* the sample (the thesis prints Alg. 1 line 6 reversed), and the other tree connects
toward the new node by repeated steps until it reaches it or is blocked; then the trees swap.
Every goal of a goal set is a root of the goal tree; goals can join between runs
(:class:`RRTConnectSearch`, for IK-RRT). The direct edges from the start to each goal are tried
first.

Edges are checked lazily (Bohlin & Kavraki 2000; the lazy checking of Vahrenkamp 2011 C.2):
a new edge gets ``eager_checks`` clearance evaluations (its end first, then bisection, which
finds most collisions); undecided edges stay provisional until they lie on a path between the
trees. That path is pruned first (:func:`~prehensile.planning.shortcut.prune`: its
replacement edges are checked in full), and only the provisional edges that survive pruning
are then checked in full; a blocked one cuts its subtree off the tree and the search goes on.

Endpoints in contact range of obstacles (grasps) may be rejected by the conservative balls
although the exact geometry is free; they get a short escape motion certified exactly
(:func:`~prehensile.planning.certify.certified_escape`) as their first tree edge.

The kernel reads the clock itself (:func:`~prehensile.clock.kernel_clock`) and stops
at the deadline; all state (trees, counters, the splitmix64 generator seeded from ``rng``) lives in
arrays, so a search resumes where it stopped. Trees start small and double when full, up to
``max_nodes``.

Afterwards the path is shortcut (:func:`~prehensile.planning.shortcut.simplify`, random
attempts and a last pruning, drawing from the search's generator) and
certified on the exact geometry (:func:`~prehensile.planning.certify.certify_path`). A path
that fails certification is discarded and the search repeats: if the context's balls do not
cover the geometry, with covering balls on the links that collided
(:meth:`~prehensile.planning.context.PlanningContext.refined`), else with half the resolution.

A query's usual course is one compiled call (:func:`_query`): planting the start and the goals
on new trees, the search and the shortcutting. Python validates the input before it, plants the
ends the sphere model alone cannot tell usable (escapes, static contacts, closed meshes:
:meth:`~prehensile.planning.context.PlanningContext.balls_decide_ends`) and certifies the path
after it. On the MotionBenchMaker problems the Python between three separate kernels cost
about a fifth of a median query, in the caches left cold by building its context.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np
from numba import njit

from prehensile.clock import COMPILING, clock, kernel_clock
from prehensile.collision import sphere_kernels as SK
from prehensile.errors import PrehensileError
from prehensile.planning.certify import (
    ESCAPE_ATTEMPTS, CertifyReport, certified_escape, certify_path, refine_after_failure,
)
from prehensile.planning.context import PlanningContext
from prehensile.planning.cspace import ConfigurationSpace
from prehensile.planning.kernels import (
    BLOCKED, FREE, NO_LIMIT, assign, distance, motion_free, nearest, path_length, rng_state, uniform,
)
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus
from prehensile.planning.seeding import planner_rng
from prehensile.planning.shortcut import MAX_INSERTED, MIN_GAIN, prune, simplify, waypoint_marks
from prehensile.settings import (
    FINITE_POSITIVE, FRACTION, NON_NEGATIVE, POSITIVE, at_least, check_fields, check_value, or_none,
)

_ITERATION_CAP = or_none(at_least(1))
RUNNING, FOUND, FULL, ENDS = 0, 1, 2, 3  # kernel results (ENDS: an end needs the exact geometry, _plant_ends)
_TRAPPED, _ADVANCED, _REACHED, _NO_ROOM = 0, 1, 2, 3  # extension results
_CHECKED, _DEAD = 1, 2  # node flags: edge from the parent fully checked; cut off the tree
# counters: clearance evaluations, iterations, tree sizes, start nodes, path length, goal root,
# the goal-tree nodes [DIRECT, DIRECT_END) whose direct edges from the start are still to try
CHECKS, ITERATIONS, SIZE, START_NODES, PATH_LENGTH, GOAL_ROOT, DIRECT, DIRECT_END = 0, 1, 2, 4, 5, 6, 7, 8
_COUNTERS = 9  # their number


@dataclass(frozen=True)
class RRTConnectSettings:
    """Settings of :func:`rrt_connect`.

    Attributes:
        time_budget_s: search time (s) over all attempts; simplification and certification
            are timed separately.
        step: extension step (m, workspace-weighted metric).
        eager_checks: clearance evaluations spent on a new tree edge before it is kept
            provisionally; the rest of the check happens once the edge lies on a path between
            the trees and survives its pruning (lazy collision checking: most blocked edges
            show within a few checks, most free ones are never needed). A large value checks
            every edge at once. On the 400 MotionBenchMaker Panda problems 3 spends the fewest
            in the mean and close to the fewest in the median (search evaluations at 2, 3, 4, 5,
            6: median 382, 404, 412, 434, 458; mean 1977, 1798, 1818, 1940, 1972; one seed per
            problem, other seeds move these by a few percent).
        max_nodes: nodes per tree.
        shortcut: simplify the path (:func:`~prehensile.planning.shortcut.shortcut`).
        shortcut_iterations: random shortcut attempts.
        shortcut_time_s: time limit (s) of the random shortcut attempts.
        shortcut_min_gain: a random shortcut is checked only if it shortens the path by more
            than this fraction of its length (:data:`~prehensile.planning.shortcut.MIN_GAIN`
            has the trade-off measured on MotionBenchMaker; 0 checks every one).
        certify: certify the path on the exact geometry before returning SUCCESS.
        certify_retries: searches repeated after a path failed certification (with covering
            balls on the links that collided, the last one on every link; else at half the
            resolution each), before giving up with CERTIFICATION_FAILED.
        escape: an endpoint within the limits that the sphere model rejects, or holds less
            than half the resolution from the world, gets a short straight escape motion
            certified on the exact geometry (:func:`~prehensile.planning.certify.certified_escape`)
            as its first tree edge: the conservative balls of a grasp in contact range of the
            object would otherwise make it unreachable. A start the balls reject tries
            directions until the budget runs out (TIMEOUT if none is found); a start they accept
            and each goal try 64 (a goal the balls reject is then INVALID_GOAL; an end they
            accept stays a node without an escape).
    """

    time_budget_s: float = 1.0
    step: float = 1.0
    eager_checks: int = 3
    max_nodes: int = 100_000
    shortcut: bool = True
    shortcut_iterations: int = 16
    shortcut_time_s: float = 0.05
    shortcut_min_gain: float = MIN_GAIN
    certify: bool = True
    certify_retries: int = 3
    escape: bool = True

    def __post_init__(self) -> None:
        check_fields(self, time_budget_s=FINITE_POSITIVE, step=POSITIVE, eager_checks=at_least(1),
                     max_nodes=at_least(2), shortcut_iterations=at_least(0), shortcut_time_s=NON_NEGATIVE,
                     shortcut_min_gain=FRACTION, certify_retries=at_least(0))


@njit(cache=True, inline="always")
def _set_point(points, t, i, q, idx, w):
    """Node i of tree t at q (dof,) in the weighted coordinates of :func:`nearest`."""
    for k in range(idx.shape[0]):
        points[t, k, i] = w[k] * q[idx[k]]


@njit(cache=True, inline="always")
def _cut(flags, points, t, i):
    """Take node i off tree t: never extended, never nearest."""
    flags[t, i] |= _DEAD
    points[t, 0, i] = np.inf


@njit(cache=True, _nrt=False)
def _extend(nodes, parents, flags, points, counters, t, target, near, dist, step, res, budget, idx, w, checker,
            scratch, motion):
    """Step tree t from node ``near`` (at distance ``dist``) toward target; (result, new node)."""
    size = counters[SIZE + t]
    if size == nodes.shape[1]:
        return _NO_ROOM, -1
    new, base = nodes[t, size], nodes[t, near]
    assign(new, base)
    if dist <= step:
        for k in idx:
            new[k] = target[k]
    else:
        f = step / dist
        for k in idx:
            new[k] = base[k] + f * (target[k] - base[k])
    verdict = motion_free(base, new, res, checker, scratch, motion, counters, budget, 1)
    if verdict == BLOCKED:
        return _TRAPPED, -1
    parents[t, size], flags[t, size] = near, _CHECKED if verdict == FREE else 0
    _set_point(points, t, size, new, idx, w)
    counters[SIZE + t] = size + 1
    return (_REACHED if dist <= step else _ADVANCED), size


@njit(cache=True, _nrt=False)
def _connect(nodes, parents, flags, points, work, counters, t, target, step, res, budget, idx, w, checker, scratch,
             motion):
    """Extend tree t toward target until reached or blocked; (result, last node)."""
    near, dist = nearest(points[t], counters[SIZE + t], target, idx, w, work)
    while True:
        result, new = _extend(nodes, parents, flags, points, counters, t, target, near, dist, step, res, budget, idx,
                              w, checker, scratch, motion)
        if result != _ADVANCED:
            return result, new
        near, dist = new, distance(nodes[t, new], target, idx, w)


@njit(cache=True, _nrt=False)
def _write_path(nodes, parents, flags, counters, start_node, goal_node, joined, path, marks, owner):
    """path[:m] = start root .. start_node, goal_node .. goal root (goal_node skipped if it is
    the same configuration as start_node); returns m and sets GOAL_ROOT. Edge i (path[i] ->
    path[i + 1]) is the tree edge ``owner[i] = t * capacity + node`` (node's edge from its
    parent in tree t; -1 for a direct edge between the trees). ``marks``
    (:func:`~prehensile.planning.shortcut.waypoint_marks`) get ids 0 .. m - 1, the edges'
    checked flags from the trees and an empty memo."""
    ids, checked, memo = marks
    capacity = nodes.shape[1]
    m, k = 0, start_node
    while k >= 0:
        m, k = m + 1, parents[0, k]
    i, k = m, start_node
    while k >= 0:
        i -= 1
        assign(path[i], nodes[0, k])
        if i > 0:
            owner[i - 1], checked[i - 1] = k, flags[0, k] & _CHECKED != 0
        k = parents[0, k]
    k, edge = (parents[1, goal_node], goal_node) if joined else (goal_node, -1)
    owner[m - 1], checked[m - 1] = -1, True  # not joined: a direct edge, checked
    root = goal_node
    while k >= 0:
        if edge >= 0:
            owner[m - 1], checked[m - 1] = capacity + edge, flags[1, edge] & _CHECKED != 0
        assign(path[m], nodes[1, k])
        m, root, edge, k = m + 1, k, k, parents[1, k]
    counters[GOAL_ROOT] = root
    for i in range(m):
        ids[i] = i
    for i in range(memo.shape[0]):  # the blocked pairs fill a prefix of the rows
        if memo[i, 0] < 0:
            break
        memo[i, 0] = memo[i, 1] = -1
    return m


@njit(cache=True, _nrt=False)
def _confirm(nodes, parents, flags, points, counters, n, marks, owner, res, checker, scratch, motion):
    """Finish the checks of the tree edges behind the unchecked edges of path[:n] (see
    :func:`_write_path`); on a blocked one cut the subtree below it off its tree and return False."""
    ids, checked, _ = marks
    capacity = nodes.shape[1]
    for i in range(n - 1):
        if checked[i]:
            continue
        for e in range(ids[i], ids[i + 1]):  # the collinear tree edges this edge stands for
            t, k = owner[e] // capacity, owner[e] % capacity
            if owner[e] < 0 or flags[t, k] & _CHECKED:
                continue
            if motion_free(nodes[t, parents[t, k]], nodes[t, k], res, checker, scratch, motion, counters,
                           NO_LIMIT, 0) != FREE:
                _cut(flags, points, t, k)
                for j in range(k + 1, counters[SIZE + t]):  # children come after their parents
                    if flags[t, parents[t, j]] & _DEAD:
                        _cut(flags, points, t, j)
                return False
            flags[t, k] |= _CHECKED
    return True


@njit(cache=True, _nrt=False)
def _finish(nodes, parents, flags, points, counters, start_node, goal_node, joined, path, marks, owner, prune_path,
            idx, w, res, checker, scratch, motion):
    """Write the path between the trees through start_node and goal_node, prune it (if
    ``prune_path``), then finish the checks of the tree edges left in it; True (and
    PATH_LENGTH set) if they are free. Pruning first spares the checks of the many tree edges
    that pruning drops."""
    n = _write_path(nodes, parents, flags, counters, start_node, goal_node, joined, path, marks, owner)
    if prune_path:
        n = prune(path, n, marks, idx, w, res, checker, scratch, motion, counters)
    if not _confirm(nodes, parents, flags, points, counters, n, marks, owner, res, checker, scratch, motion):
        return False
    counters[PATH_LENGTH] = n
    return True


@njit(cache=True, _nrt=False)
def search(nodes, parents, flags, points, work, counters, path, marks, owner, prune_path, rng, iterations, deadline,
           compiling, step, res, budget, idx, w, lower, upper, sample, checker, scratch, motion):
    """Run up to ``iterations`` steps, each a direct edge's goal or an RRT-Connect iteration,
    until ``deadline`` (s, :func:`~prehensile.clock.clock`, read before each step with
    ``compiling``: :func:`~prehensile.clock.kernel_clock`); returns RUNNING, FOUND
    or FULL.

    Tree 0 (start) and tree 1 (goals) hold nodes (2, capacity, dof) with parents (2,
    capacity) (-1 for roots), flags (2, capacity), the nodes' coordinates for :func:`nearest`
    ``points`` (2, n, capacity) (``work`` (capacity,) its scratch) and sizes
    ``counters[SIZE:SIZE + 2]``. The first ``counters[START_NODES]`` nodes of tree 0 are the
    start and its escape node; goals (roots with their escape nodes) may be appended to tree 1
    between calls. The direct edges from the start nodes to the goal nodes
    ``[counters[DIRECT], counters[DIRECT_END])`` are tried first, goal by goal, so that a large
    goal set spreads over calls (and the caller's time checks) like the iterations.
    Nodes flagged _DEAD are never extended (cut off, or a root that only its certified escape
    edge leaves).
    ``sample`` (dof,) holds the values of the joints not planned; ``lower``, ``upper`` (n,)
    bound the sampled joints ``idx``. ``budget``: see ``RRTConnectSettings.eager_checks``. On
    FOUND, path[:counters[PATH_LENGTH]] is the path, pruned if ``prune_path`` (rows of path,
    marks and owner >= 2 * capacity; see :func:`_finish`).
    """
    tried = 0
    while counters[DIRECT] < counters[DIRECT_END]:
        if tried == iterations or kernel_clock(compiling) >= deadline:
            return RUNNING
        g = counters[DIRECT]
        counters[DIRECT] += 1
        tried += 1
        for a in range(counters[START_NODES]):
            if not (flags[0, a] | flags[1, g]) & _DEAD and motion_free(
                    nodes[0, a], nodes[1, g], res, checker, scratch, motion, counters, NO_LIMIT, 0) == FREE:
                if _finish(nodes, parents, flags, points, counters, a, g, False, path, marks, owner, prune_path, idx,
                           w, res, checker, scratch, motion):
                    return FOUND
    for _ in range(iterations - tried):
        if kernel_clock(compiling) >= deadline:
            return RUNNING
        t = counters[ITERATIONS] % 2
        counters[ITERATIONS] += 1
        for k in range(idx.shape[0]):
            sample[idx[k]] = lower[k] + uniform(rng) * (upper[k] - lower[k])
        near, dist = nearest(points[t], counters[SIZE + t], sample, idx, w, work)
        result, new = _extend(nodes, parents, flags, points, counters, t, sample, near, dist, step, res, budget, idx,
                              w, checker, scratch, motion)
        if result == _NO_ROOM:
            counters[ITERATIONS] -= 1
            return FULL
        if result == _TRAPPED:
            continue
        result, other = _connect(nodes, parents, flags, points, work, counters, 1 - t, nodes[t, new], step, res,
                                 budget, idx, w, checker, scratch, motion)
        if result == _NO_ROOM:
            return FULL
        if result == _REACHED:
            start_node, goal_node = (new, other) if t == 0 else (other, new)
            if _finish(nodes, parents, flags, points, counters, start_node, goal_node, True, path, marks, owner,
                       prune_path, idx, w, res, checker, scratch, motion):
                return FOUND
    return RUNNING


@njit(cache=True, inline="always")
def _add_node(nodes, parents, flags, points, counters, t, q, parent, flag, idx, w):
    """Append q (dof,) to tree t with its parent node (-1 for a root) and flags (room for it is the caller's)."""
    i = counters[SIZE + t]
    assign(nodes[t, i], q)
    parents[t, i], flags[t, i] = parent, flag
    _set_point(points, t, i, q, idx, w)
    if flag & _DEAD:
        _cut(flags, points, t, i)
    counters[SIZE + t] = i + 1


@njit(cache=True, _nrt=False)
def _plant(nodes, parents, flags, points, counters, t, qs, parent, flag, idx, w):
    """Append the nodes qs (m, dof) with parents ``parent`` (m,) (counted from the first of
    them, -1 for a root) and flags ``flag`` (m,) to tree t (room for them is the caller's)."""
    first = counters[SIZE + t]
    for r in range(qs.shape[0]):
        _add_node(nodes, parents, flags, points, counters, t, qs[r], first + parent[r] if parent[r] >= 0 else -1,
                  flag[r], idx, w)


@functools.cache
def _load_planting() -> None:
    """Load :func:`_plant` (numba compiles it or reads it from its cache on first use, a few
    ms) once per process, before a search's clock starts: only certified escapes and goals
    added to a running search use it, inside the budget."""
    one, index = np.zeros((2, 1, 1)), np.zeros((2, 1), dtype=np.int64)
    _plant(one, index, index.copy(), one.copy(), np.zeros(_COUNTERS, dtype=np.int64), 0, np.zeros((0, 1)),
           np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64), np.zeros(1, dtype=np.int64), np.ones(1))


@njit(cache=True, _nrt=False)
def _plant_ends(ends, screen, nodes, parents, flags, points, counters, idx, w, checker, scratch):
    """Plant ends[0] as the root of the start tree and ends[1:] as roots of the goal tree if each
    lies within the limits, is free for the balls and holds ``margin`` (m) from the world
    (``screen`` = (lower, upper, scales, world scales, margin),
    :func:`~prehensile.collision.sphere_kernels.screen_one`); False, and nothing planted, if one
    does not (it needs the exact geometry: an escape, or the reason it is unusable)."""
    lower, upper, scales, world_scales, margin = screen
    for b in range(ends.shape[0]):
        inside, free, near = SK.screen_one(ends[b], lower, upper, checker, scratch, scales, world_scales, margin)
        if not inside or not free or near:
            return False
    for b in range(ends.shape[0]):
        _add_node(nodes, parents, flags, points, counters, min(b, 1), ends[b], -1, 0, idx, w)
    counters[START_NODES], counters[DIRECT], counters[DIRECT_END] = 1, 0, ends.shape[0] - 1
    return True


@njit(cache=True, _nrt=False)
def _query(ends, screen, trees, prune_path, rng, iterations, deadline, compiling, step, res, budget, idx, w, lower,
           upper, rows, checker, scratch, motion, shortcut, times):
    """A query's usual course in one compiled call: on empty trees plant the ends
    (:func:`_plant_ends`; ENDS if it cannot), :func:`search` (its arguments, ``sample`` the
    first of ``rows`` (3, dof); ``trees`` = (nodes, parents, flags, points, work, counters, path,
    marks, owner)), then on FOUND with ``prune_path`` shorten a path of 3 or more waypoints
    (:func:`~prehensile.planning.shortcut.simplify`, the same generator, qa and qb the other
    rows; ``shortcut`` = (attempts, time limit s, min_gain, evaluation counter (1,) int64, cum
    (path rows,))) and set ``counters[PATH_LENGTH]`` to its waypoints. Returns search's result
    or ENDS; ``times[0]`` is the clock (:func:`~prehensile.clock.clock`) when the search stopped,
    ``times[1]`` on FOUND the path's length (m, :func:`~prehensile.planning.kernels.path_length`)."""
    nodes, parents, flags, points, work, counters, path, marks, owner = trees
    if counters[SIZE] == 0 and not _plant_ends(ends, screen, nodes, parents, flags, points, counters, idx, w,
                                               checker, scratch):
        times[0] = kernel_clock(compiling)
        return ENDS
    code = search(nodes, parents, flags, points, work, counters, path, marks, owner, prune_path, rng, iterations,
                  deadline, compiling, step, res, budget, idx, w, lower, upper, rows[0], checker, scratch, motion)
    times[0] = kernel_clock(compiling)
    if code == FOUND:
        if prune_path and counters[PATH_LENGTH] >= 3:
            attempts, limit, min_gain, checks, cum = shortcut
            counters[PATH_LENGTH] = simplify(path, counters[PATH_LENGTH], marks, attempts, times[0] + limit,
                                             compiling, min_gain, False, rng, idx, w, res, checker, scratch, motion,
                                             checks, cum, rows[1], rows[2])
        times[1] = path_length(path[:counters[PATH_LENGTH]], idx, w)
    return code


class _Trees:
    """Tree arrays for :func:`search` in the space ``space``, empty at first, doubled when full.
    The path rows (``path``, ``marks``, ``cum``) have ``spare`` rows more than the trees' nodes,
    for the points that shortcutting inserts in place."""

    def __init__(self, capacity: int, space: ConfigurationSpace, spare: int) -> None:
        self.space, self.spare, dof = space, spare, space.model.dof
        self.nodes = np.empty((2, capacity, dof))
        self.parents, self.flags = np.empty((2, capacity), dtype=np.int64), np.empty((2, capacity), dtype=np.int64)
        self.points, self.work = np.empty((2, space.n, capacity)), np.empty(capacity)
        self._path_rows(2 * capacity)
        self.counters = np.zeros(_COUNTERS, dtype=np.int64)

    @property
    def arrays(self) -> tuple:
        """(nodes, parents, flags, points, work, counters, path, marks, owner) of :func:`search`."""
        return (self.nodes, self.parents, self.flags, self.points, self.work, self.counters, self.path, self.marks,
                self.owner)

    def reserve(self, t: int, count: int) -> None:
        """Make room for ``count`` more nodes in tree t."""
        while self.counters[SIZE + t] + count > self.nodes.shape[1]:
            self.grow(2 * self.nodes.shape[1])

    def append(self, t: int, tree_nodes: list) -> int:
        """Append (q, parent, flags) nodes to tree t, parents counted from the first of them;
        returns the index of the first."""
        first = int(self.counters[SIZE + t])
        self.reserve(t, len(tree_nodes))
        qs, parents, flags = zip(*tree_nodes)
        _plant(self.nodes, self.parents, self.flags, self.points, self.counters, t, np.array(qs),
               np.array(parents, dtype=np.int64), np.array(flags, dtype=np.int64), self.space.indices,
               self.space.weights)
        return first

    def grow(self, limit: int) -> bool:
        capacity = self.nodes.shape[1]
        if capacity >= limit:
            return False
        bigger = min(2 * capacity, limit)
        nodes = np.empty((2, bigger, self.nodes.shape[2]))
        parents, flags = np.empty((2, bigger), dtype=np.int64), np.empty((2, bigger), dtype=np.int64)
        points = np.empty((2, self.space.n, bigger))
        nodes[:, :capacity], parents[:, :capacity], flags[:, :capacity] = self.nodes, self.parents, self.flags
        points[:, :, :capacity] = self.points
        self.nodes, self.parents, self.flags, self.points = nodes, parents, flags, points
        self.work = np.empty(bigger)
        self._path_rows(2 * bigger)
        return True

    def _path_rows(self, nodes: int) -> None:
        """Path arrays for paths through up to ``nodes`` tree nodes."""
        rows = nodes + self.spare
        self.path, self.marks = np.empty((rows, self.nodes.shape[2])), waypoint_marks(rows)
        self.owner = np.empty(rows, dtype=np.int64)
        self.cum = np.empty(rows)


def _endpoints(ctx: PlanningContext, qs: np.ndarray, toward: np.ndarray, settings: RRTConnectSettings,
               rng: np.random.Generator, deadline: float, persistent: int = 0) -> list[list | None]:
    """Per configuration of qs (k, dof): its tree nodes [(q, -1, flags)] plus, if it needs one,
    its certified escape node [(escape, 0, _CHECKED)] (moving toward ``toward`` (k, dof); of
    the first ``persistent`` rows, those the balls reject try directions until ``deadline`` (s,
    :func:`~prehensile.clock.clock`), every other row ``ESCAPE_ATTEMPTS`` directions or until
    then: a row the balls accept is a node without one); None if it is unusable (outside the
    limits, or colliding for the balls without an escape)."""
    inside, free, near = ctx.spheres.screen(qs, ctx.end_margin)
    inside &= ctx.exact_screen(qs)  # no escape from a static contact or from inside a closed mesh
    valid, tight = inside & free, inside & near
    out: list[list | None] = []
    for i, q in enumerate(qs):
        escape = None
        if settings.escape and inside[i] and (tight[i] or not valid[i]):
            attempts = None if i < persistent and not valid[i] and np.isfinite(deadline) else ESCAPE_ATTEMPTS
            escape = certified_escape(ctx, q, toward[i], rng, ctx.end_margin, attempts=attempts,
                                      deadline=deadline)
        if not valid[i] and escape is None:
            out.append(None)
            continue
        out.append([(q, -1, 0 if valid[i] else _DEAD)] + ([] if escape is None else [(escape, 0, _CHECKED)]))
    return out


class RRTConnectSearch:
    """An RRT-Connect query whose trees persist: goals can be added and the search resumed.

    :func:`rrt_connect` is one :meth:`add_goals` and one :meth:`solve`. IK-RRT adds each goal
    its IK sampler finds and resumes the same trees (Vahrenkamp 2011 Alg. 16). A path that
    fails the exact certification makes the search start over (new trees in the refined
    context, or at half the resolution; see :class:`RRTConnectSettings`).

    Args:
        ctx: the planning context.
        q_start: (dof,) start configuration (rad or m).
        settings: :class:`RRTConnectSettings` (its time budget is not used: see :meth:`solve`).
        rng: random source or seed (:func:`~prehensile.planning.seeding.planner_rng`: seed 0 if
            None). The same seed and the same calls give the same path.
    """

    def __init__(self, ctx: PlanningContext, q_start: np.ndarray, settings: RRTConnectSettings = RRTConnectSettings(),
                 rng: np.random.Generator | int | None = None) -> None:
        ctx.warm_up(settings.certify or settings.escape)
        _load_planting()
        started = clock()
        self.ctx, self.settings = ctx, settings
        self.rng = planner_rng(rng)
        self.start = ctx.model.check_one(q_start, "rrt_connect: q_start").copy()
        """(dof,) the start configuration (a copy: the caller may change theirs)."""
        self.ends = self.start[None]  # row 0 the start, then the goals as planned (ConfigurationSpace.goal_turns)
        self.goal_of: list[int] = []  # row of the goals as given, per goal row of self.ends
        self.given = 0  # goals given
        self.context, self.res, self.refined = ctx, ctx.resolution, frozenset()
        self.state = rng_state(self.rng)
        self.trees: _Trees | None = None
        self.start_status: PlanStatus | None = None
        self.goal_row: dict[int, int] = {}  # goal tree root node -> row of the goals as given
        self.escapes = 0  # certified escape nodes in the trees
        # work arrays of _query: rows for the sample (the joints not planned at the start's values), qa and qb;
        # the clock and the path's length; the shortening's clearance evaluations
        self._rows, self._times, self._checks = np.empty((3, ctx.model.dof)), np.zeros(2), np.zeros(1, dtype=np.int64)
        self._rows[0] = self.start
        self._setup_s = clock() - started  # counted into the next solve's search time

    @property
    def goals(self) -> np.ndarray:
        """(k, dof) the goals as planned (a continuous joint's goal once each way round)."""
        return self.ends[1:]

    def add_goals(self, q_goals: np.ndarray, deadline: float = np.inf) -> None:
        """Add a goal (dof,) or goals (k, dof); the joints not planned must equal the start's. A
        continuous joint's goal value counts modulo 2 pi: the goal is reached either way round
        (:meth:`ConfigurationSpace.goal_turns`). A goal that needs a certified escape gets none
        found after ``deadline`` (s, :func:`~prehensile.clock.clock`)."""
        started = clock()
        model, space = self.ctx.model, self.ctx.space
        goals = model.check_configuration(q_goals, "rrt_connect: q_goal")  # (..., dof)
        if goals.ndim > 2:
            raise PrehensileError(f"rrt_connect: q_goal must be ({model.dof},) or (k, {model.dof}), got {goals.shape}")
        goals = goals.reshape(-1, model.dof)
        if not len(goals):
            raise PrehensileError(f"rrt_connect: q_goal: no goals given (shape {goals.shape})")
        fixed = space.fixed
        if len(fixed):
            differ = fixed[(np.abs(goals[:, fixed] - self.start[fixed]) > 1e-9).any(axis=0)]
            if len(differ):
                raise PrehensileError("rrt_connect: goal and start differ in joints that are not planned "
                                      f"({', '.join(model.joint_names[i] for i in differ)}; planned: "
                                      f"{', '.join(space.joint_names)})")
            goals = goals.copy()
            goals[:, fixed] = self.start[fixed]  # equal within 1e-9: the path keeps them constant
        planned, rows = space.goal_turns(goals, self.start)
        first = len(self.ends) - 1
        self.ends = np.concatenate((self.ends, planned))
        self.goal_of += (self.given + rows).tolist()
        self.given += len(goals)
        if self.trees is not None and self.trees.counters[SIZE]:  # planted: the new goals join the goal tree
            self._append_goals(first, deadline)
        self._setup_s += clock() - started

    def _append_goals(self, first: int, deadline: float) -> None:
        """Put goals[first:] (with their escape nodes, searched until ``deadline``) into the goal tree."""
        goals = self.goals[first:]
        toward = np.empty_like(goals)
        toward[:] = self.start
        self._add_goal_nodes(first, _endpoints(self.context, goals, toward, self.settings, self.rng, deadline))

    def _add_goal_nodes(self, first: int, goal_nodes: list) -> None:
        """Roots (with escape nodes) of goals[first:] in the goal tree, in one append; None: an
        unusable goal. Their direct edges from the start are tried next."""
        counters = self.trees.counters
        begin = int(counters[SIZE + 1])
        nodes, roots = [], []  # roots: (node offset, row of the goals as given)
        for row, goal in enumerate(goal_nodes, first):
            if goal is not None:
                offset = len(nodes)
                roots.append((offset, self.goal_of[row]))
                nodes += [(q, parent if parent < 0 else offset + parent, flags) for q, parent, flags in goal]
                self.escapes += len(goal) - 1
        if nodes:
            at = self.trees.append(1, nodes)
            self.goal_row.update((at + offset, row) for offset, row in roots)
        if counters[DIRECT] == counters[DIRECT_END]:  # skip the nodes the search added since
            counters[DIRECT] = begin
        counters[DIRECT_END] = counters[SIZE + 1]

    def _plant_exactly(self, deadline: float) -> bool:
        """Plant the start and every goal on the empty trees, each end the balls reject or hold
        near the world with its certified escape (searched until ``deadline``); False, and the
        trees dropped, if the start is unusable (``start_status`` INVALID_START, unless the
        deadline cut its escape search short: a later solve may find one)."""
        toward = np.empty_like(self.ends)  # the start escapes toward the first goal, goals toward the start
        toward[0], toward[1:] = self.ends[min(1, len(self.goals))], self.start
        start, *goal_nodes = _endpoints(self.context, self.ends, toward, self.settings, self.rng, deadline,
                                        persistent=1)
        if start is None:
            self.start_status = PlanStatus.INVALID_START if clock() < deadline else None
            self.trees = None
            return False
        self.trees.append(0, start)
        self.trees.counters[START_NODES] = len(start)
        self.escapes = len(start) - 1
        self._add_goal_nodes(0, goal_nodes)
        return True

    def _start_over(self, report: CertifyReport, last: bool) -> None:
        """After a path failed certification: new trees, with covering balls on the links that
        collided (for the ``last`` search on every link with balls), else at half the resolution
        (:func:`~prehensile.planning.certify.refine_after_failure`)."""
        self.context, self.refined, self.res = refine_after_failure(self.ctx, self.context, self.refined, self.res,
                                                                    report, last)
        self.trees = None

    def _run(self, deadline: float, iterations: int) -> tuple[int, int]:
        """Resume the search (on new trees plant the ends first) until ``deadline`` (s,
        :func:`~prehensile.clock.clock`) or for at most ``iterations``, and shorten the path it
        finds (its clearance evaluations counted in ``_checks``); (waypoints of the path in
        ``trees.path``, goal root), (0, -1) without a path, (-1, -1) if the ends leave nothing
        to search (``start_status`` says why, else no goal is usable)."""
        ctx, settings = self.context, self.settings
        if self.trees is None:
            self.trees = _Trees(min(1024, settings.max_nodes), ctx.space,
                                min(settings.shortcut_iterations, MAX_INSERTED))
            self.goal_row, self.escapes = {}, 0
        if not self.trees.counters[SIZE]:  # the kernel plants ends the balls decide; the others need escapes here
            if not self.given:
                return -1, -1
            self.trees.reserve(1, len(self.ends) - 1)
            if not ctx.balls_decide_ends(self.start) and not (self._plant_exactly(deadline) and self.goal_row):
                return -1, -1
        space, trees = ctx.space, self.trees
        lower, upper = space.sampling_bounds(self.start[space.indices])
        last = trees.counters[ITERATIONS] + iterations
        while True:  # again when the trees grew, or when direct edges took some of the iterations
            planting = not trees.counters[SIZE]
            if not (planting or self.goal_row):  # no usable goal (yet)
                return -1, -1
            code = _query(self.ends, ctx.end_screening, trees.arrays, settings.shortcut, self.state,
                          last - trees.counters[ITERATIONS], deadline, COMPILING, settings.step, self.res,
                          settings.eager_checks, space.indices, space.weights, lower, upper, self._rows,
                          ctx.spheres.data, ctx.scratch, ctx.motion_arrays(self.res),
                          (settings.shortcut_iterations, settings.shortcut_time_s, settings.shortcut_min_gain,
                           self._checks, trees.cum), self._times)
            if code == ENDS:
                if not self._plant_exactly(deadline):
                    return -1, -1
                continue
            if planting:  # the kernel planted the start as node 0 of tree 0, the goals as the goal tree's roots
                self.goal_row, self.escapes = dict(enumerate(self.goal_of)), 0
            if code == FOUND:
                return int(trees.counters[PATH_LENGTH]), int(trees.counters[GOAL_ROOT])
            if (code == FULL and not trees.grow(settings.max_nodes) or clock() >= deadline
                    or trees.counters[ITERATIONS] >= last):
                return 0, -1

    def solve(self, time_budget_s: float, max_iterations: int | None = None) -> PlanResult:
        """Search for up to ``time_budget_s`` (s, > 0) more, from where the last call stopped,
        and at most ``max_iterations`` iterations (None: no cap; a search that stops at the
        cap, not the clock, resumes the same way on any machine).

        Returns:
            :class:`PlanResult` with this call's statistics (see :func:`rrt_connect`).
        """
        check_value("RRTConnectSearch.solve: time_budget_s", time_budget_s, FINITE_POSITIVE)
        check_value("RRTConnectSearch.solve: max_iterations", max_iterations, _ITERATION_CAP)
        return self._solve(time_budget_s, NO_LIMIT if max_iterations is None else int(max_iterations))

    def _solve(self, time_budget_s: float, limit: int) -> PlanResult:
        """:meth:`solve` with arguments known to be valid (``limit``: the iteration cap, NO_LIMIT for none)."""
        t0 = clock() - self._setup_s
        self._setup_s = 0.0
        deadline = t0 + time_budget_s
        settings = self.settings
        totals = dict(iterations=0, nodes=0, collision_checks=0, plan_time_s=0.0, simplify_time_s=0.0,
                      certify_time_s=0.0)
        self._checks[0] = 0
        if not self.given:
            return self._no_path(PlanStatus.INVALID_GOAL, totals, {"reason": "no goal given: call add_goals first"})
        report: CertifyReport | None = None
        for attempt in range(settings.certify_retries + 1):
            begun = t0 if attempt == 0 else clock()
            before = [0] * _COUNTERS if self.trees is None else self.trees.counters.tolist()
            n, root = self._run(deadline, limit)
            if n < 0:
                status = self.start_status or (PlanStatus.TIMEOUT if clock() >= deadline else PlanStatus.INVALID_GOAL)
                totals["plan_time_s"] += clock() - begun
                # after a failed certification: the covering balls of the refined context reject an end
                # that the planning balls let through
                return self._no_path(status, totals, {} if report is None else self._failure_info(attempt, report))
            counts = self.trees.counters.tolist()
            totals["iterations"] += counts[ITERATIONS] - before[ITERATIONS]
            totals["nodes"] = counts[SIZE] + counts[SIZE + 1]
            totals["collision_checks"] += counts[CHECKS] - before[CHECKS]
            if n == 0:
                totals["plan_time_s"] += clock() - begun
                status = PlanStatus.TIMEOUT if report is None else PlanStatus.CERTIFICATION_FAILED
                return self._no_path(status, totals, self._failure_info(attempt, report))
            stopped, length = self._times.tolist()  # the search's end (the shortening ran after it); the path's
            totals["plan_time_s"] += stopped - begun
            totals["simplify_time_s"] += clock() - stopped
            path = self.trees.path[:n].copy()
            info = {"attempts": attempt + 1, "length": length, "escapes": self.escapes,
                    "refined": tuple(sorted(self.refined))}
            if settings.certify:
                report = certify_path(self.context, path)
                totals["certify_time_s"] += report.time_s
                info["certify"] = report
            if report is None or report.ok:
                totals["collision_checks"] += int(self._checks[0])
                return PlanResult(PlanStatus.SUCCESS, path, PlanStats(**totals), goal_index=self.goal_row[root],
                                  info=info)
            self._start_over(report, last=attempt + 1 == settings.certify_retries)
            if clock() >= deadline:
                break
        totals["collision_checks"] += int(self._checks[0])
        return self._no_path(PlanStatus.CERTIFICATION_FAILED, totals, self._failure_info(attempt, report))

    def _no_path(self, status: PlanStatus, totals: dict, info: dict) -> PlanResult:
        """A result without a path: ``status``, statistics ``totals``, ``info``."""
        return PlanResult(status, np.zeros((0, self.ctx.model.dof)), PlanStats(**totals), info=info)

    def _failure_info(self, attempt: int, report: CertifyReport | None) -> dict:
        """``info`` of a result without a path: attempts, the last certification report (or
        None), the links planned on covering balls."""
        return {"attempts": attempt + 1, "certify": report, "refined": tuple(sorted(self.refined))}


def rrt_connect(ctx: PlanningContext, q_start: np.ndarray, q_goal: np.ndarray,
                settings: RRTConnectSettings = RRTConnectSettings(),
                rng: np.random.Generator | int | None = None) -> PlanResult:
    """Plan a collision-free path from q_start to q_goal (or to any goal of a set).

    Args:
        ctx: the planning context.
        q_start: (dof,) start configuration (rad or m).
        q_goal: (dof,) goal, or (k, dof) goal set; the joints not planned must equal the start's.
            Setting up a goal set (screening each goal, escapes where needed) takes a few
            microseconds per goal of the budget before the clock is first checked.
        settings: :class:`RRTConnectSettings`.
        rng: random source or seed (seed 0 if None). The same seed gives the same path.

    Returns:
        :class:`PlanResult`: on SUCCESS ``path`` (N, dof) runs from exactly q_start to exactly
        the reached goal (``goal_index`` its row; a continuous joint ends at the goal's angle
        plus whole turns, the shorter way round unless that is blocked), ``info`` has
        ``length`` (m, weighted),
        ``attempts``, ``escapes`` (certified escape edges among the roots), ``refined``
        (links planned on covering balls, see ``settings.certify_retries``) and ``certify``
        (:class:`CertifyReport`, if certified). INVALID_START /
        INVALID_GOAL when the start / every goal is outside the limits, or in collision for
        the sphere model without a certified escape (see ``settings.escape``; ``info["reason"]``
        says which, :meth:`~prehensile.planning.context.PlanningContext.explain`), also for
        the covering balls of a search repeated after a failed certification (an end the
        planning balls let through although the geometry collides; ``info["certify"]`` holds
        the failed path's report); TIMEOUT when
        the budget ran out (or every tree filled up); CERTIFICATION_FAILED when every path
        found failed the exact check.
    """
    query = RRTConnectSearch(ctx, q_start, settings, rng)
    query.add_goals(q_goal)
    return ctx.explain(query._solve(settings.time_budget_s, NO_LIMIT), q_start, q_goal)  # the settings are checked
