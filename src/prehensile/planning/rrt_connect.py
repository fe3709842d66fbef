"""Bidirectional RRT-Connect (Kuffner & LaValle 2000; Vahrenkamp 2011 ch. 2, Alg. 1-3), compiled.

The whole search runs in one numba kernel: sampling, nearest neighbours (a linear scan of the
tree's contiguous node array in the workspace-weighted metric), extension and the motion
checks with the sphere model (:func:`~prehensile.planning.kernels.motion_free`). Per
iteration one tree extends one step toward a uniform sample, stepping from its nearest node
*toward* the sample (the thesis prints Alg. 1 line 6 reversed), and the other tree connects
toward the new node by repeated steps until it reaches it or is blocked; then the trees swap.
Every goal of a goal set is a root of the goal tree. The direct edges between the roots are
tried first.

Edges are checked lazily (Bohlin & Kavraki 2000; the lazy checking of Vahrenkamp 2011 C.2):
a new edge gets ``eager_checks`` clearance evaluations (its end first, then bisection, which
finds most collisions); undecided edges stay provisional until they lie on a path between the
trees, are then checked in full, and a blocked one cuts its subtree off the tree.

Endpoints in contact range of obstacles (grasps) may be rejected by the conservative balls
although the exact geometry is free; they get a short escape motion certified exactly
(:func:`~prehensile.planning.certify.certified_escape`) as their first tree edge.

numba cannot read the clock, so Python runs the kernel in chunks of iterations and checks the
time budget between them (chunks sized from the measured time per iteration); all state
(trees, counters, the splitmix64 generator seeded from ``rng``) lives in arrays, so the result
does not depend on where the chunks end. Trees start small and double when full, up to
``max_nodes``.

Afterwards the path is shortcut (:func:`~prehensile.planning.shortcut.shortcut`) and
certified on the exact geometry (:func:`~prehensile.planning.certify.certify_path`). A path
that fails certification is discarded and the search repeats: if the context's balls do not
cover the geometry, with covering balls on the links that collided
(:meth:`~prehensile.planning.context.PlanningContext.refined`), else with half the resolution.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
from numba import njit

from prehensile.errors import PrehensileError
from prehensile.planning.certify import CertifyReport, certified_escape, certify_path
from prehensile.planning.context import PlanningContext
from prehensile.planning.kernels import (
    BLOCKED, FREE, NO_LIMIT, distance, motion_free, nearest, rng_state, uniform,
)
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus
from prehensile.planning.shortcut import shortcut

RUNNING, FOUND, FULL = 0, 1, 2  # kernel results
_TRAPPED, _ADVANCED, _REACHED, _NO_ROOM = 0, 1, 2, 3  # extension results
_CHECKED, _DEAD = 1, 2  # node flags: edge from the parent fully checked; cut off the tree
# counters: clearance evaluations, iterations, tree sizes, started, path length, goal root
CHECKS, ITERATIONS, SIZE, STARTED, PATH_LENGTH, GOAL_ROOT = 0, 1, 2, 4, 5, 6


@dataclass(frozen=True)
class RRTConnectSettings:
    """Settings of :func:`rrt_connect`.

    Attributes:
        time_budget_s: search time (s) over all attempts; simplification and certification
            are timed separately.
        step: extension step (m, workspace-weighted metric).
        eager_checks: clearance evaluations spent on a new tree edge before it is kept
            provisionally; the rest of the check happens once the edge lies on a path between
            the trees (lazy collision checking: most blocked edges show within a few checks,
            most free ones are never needed). A large value checks every edge at once.
        max_nodes: nodes per tree.
        shortcut: simplify the path (:func:`~prehensile.planning.shortcut.shortcut`).
        shortcut_iterations: random shortcut attempts.
        shortcut_time_s: time limit (s) of the random shortcut attempts.
        certify: certify the path on the exact geometry before returning SUCCESS.
        certify_retries: searches repeated after a path failed certification (with covering
            balls on the links that collided, else at half the resolution each), before giving
            up with CERTIFICATION_FAILED.
        escape: an endpoint within the limits that the sphere model rejects, or holds less
            than half the resolution from the world, gets a short straight escape motion
            certified on the exact geometry (:func:`~prehensile.planning.certify.certified_escape`)
            as its first tree edge: the conservative balls of a grasp in contact range of the
            object would otherwise make it unreachable.
    """

    time_budget_s: float = 1.0
    step: float = 1.0
    eager_checks: int = 8
    max_nodes: int = 100_000
    shortcut: bool = True
    shortcut_iterations: int = 16
    shortcut_time_s: float = 0.05
    certify: bool = True
    certify_retries: int = 3
    escape: bool = True

    def __post_init__(self) -> None:
        if not (self.time_budget_s > 0 and self.step > 0 and self.eager_checks >= 1 and self.max_nodes >= 2
                and self.shortcut_iterations >= 0
                and self.shortcut_time_s >= 0 and self.certify_retries >= 0):
            raise PrehensileError(f"RRTConnectSettings: invalid values {self}")


@njit(cache=True)
def _extend(nodes, parents, flags, counters, t, target, near, dist, step, res, budget, idx, checker, scratch,
            motion):
    """Step tree t from node ``near`` (at distance ``dist``) toward target; (result, new node)."""
    size = counters[SIZE + t]
    if size == nodes.shape[1]:
        return _NO_ROOM, -1
    new, base = nodes[t, size], nodes[t, near]
    new[:] = base
    if dist <= step:
        for k in idx:
            new[k] = target[k]
    else:
        f = step / dist
        for k in idx:
            new[k] = base[k] + f * (target[k] - base[k])
    verdict = motion_free(base, new, res, checker, scratch, motion, counters, budget)
    if verdict == BLOCKED:
        return _TRAPPED, -1
    parents[t, size], flags[t, size] = near, _CHECKED if verdict == FREE else 0
    counters[SIZE + t] = size + 1
    return (_REACHED if dist <= step else _ADVANCED), size


@njit(cache=True)
def _connect(nodes, parents, flags, counters, t, target, step, res, budget, idx, w, checker, scratch, motion):
    """Extend tree t toward target until reached or blocked; (result, last node)."""
    near, dist = nearest(nodes[t], counters[SIZE + t], target, idx, w, flags[t], _DEAD)
    while True:
        result, new = _extend(nodes, parents, flags, counters, t, target, near, dist, step, res, budget, idx, checker,
                              scratch, motion)
        if result != _ADVANCED:
            return result, new
        near, dist = new, distance(nodes[t, new], target, idx, w)


@njit(cache=True)
def _confirm(nodes, parents, flags, counters, t, node, res, checker, scratch, motion):
    """Finish the checks of the edges from tree t's root to node; on a blocked edge cut the
    subtree below it off the tree and return False."""
    k = node
    while parents[t, k] >= 0:
        if not flags[t, k] & _CHECKED:
            if motion_free(nodes[t, parents[t, k]], nodes[t, k], res, checker, scratch, motion, counters,
                           NO_LIMIT) != FREE:
                flags[t, k] |= _DEAD
                for i in range(k + 1, counters[SIZE + t]):  # children come after their parents
                    if flags[t, parents[t, i]] & _DEAD:
                        flags[t, i] |= _DEAD
                return False
            flags[t, k] |= _CHECKED
        k = parents[t, k]
    return True


@njit(cache=True)
def _write_path(nodes, parents, counters, start_node, goal_node, joined, path):
    """path[:m] = start root .. start_node, goal_node .. goal root (goal_node skipped if it is
    the same configuration as start_node); sets PATH_LENGTH and GOAL_ROOT."""
    m, k = 0, start_node
    while k >= 0:
        m, k = m + 1, parents[0, k]
    i, k = m, start_node
    while k >= 0:
        i -= 1
        path[i] = nodes[0, k]
        k = parents[0, k]
    k = parents[1, goal_node] if joined else goal_node
    root = goal_node
    while k >= 0:
        path[m] = nodes[1, k]
        m, root, k = m + 1, k, parents[1, k]
    counters[PATH_LENGTH], counters[GOAL_ROOT] = m, root


@njit(cache=True)
def search(nodes, parents, flags, counters, path, rng, iterations, step, res, budget, idx, w, lower, upper, sample,
           checker, scratch, motion):
    """Run up to ``iterations`` RRT-Connect iterations; returns RUNNING, FOUND or FULL.

    Tree 0 (start) and tree 1 (goals) hold nodes (2, capacity, dof) with parents (2,
    capacity) (-1 for roots), flags (2, capacity) and sizes ``counters[SIZE:SIZE + 2]``; the
    roots (and their escape nodes) are in place before the first call, which tries the direct
    edges between them. Nodes flagged _DEAD are never extended (cut off, or a root that only
    its certified escape edge leaves).
    ``sample`` (dof,) holds the values of the joints not planned; ``lower``, ``upper`` (n,)
    bound the sampled joints ``idx``. ``budget``: see ``RRTConnectSettings.eager_checks``. On
    FOUND, path[:counters[PATH_LENGTH]] is the path (path rows >= 2 * capacity).
    """
    if counters[STARTED] == 0:
        counters[STARTED] = 1
        for a in range(counters[SIZE]):
            for g in range(counters[SIZE + 1]):
                if not (flags[0, a] | flags[1, g]) & _DEAD and motion_free(
                        nodes[0, a], nodes[1, g], res, checker, scratch, motion, counters, NO_LIMIT) == FREE:
                    _write_path(nodes, parents, counters, a, g, False, path)
                    return FOUND
    for _ in range(iterations):
        t = counters[ITERATIONS] % 2
        counters[ITERATIONS] += 1
        for k in range(idx.shape[0]):
            sample[idx[k]] = lower[k] + uniform(rng) * (upper[k] - lower[k])
        near, dist = nearest(nodes[t], counters[SIZE + t], sample, idx, w, flags[t], _DEAD)
        result, new = _extend(nodes, parents, flags, counters, t, sample, near, dist, step, res, budget, idx, checker,
                              scratch, motion)
        if result == _NO_ROOM:
            counters[ITERATIONS] -= 1
            return FULL
        if result == _TRAPPED:
            continue
        result, other = _connect(nodes, parents, flags, counters, 1 - t, nodes[t, new], step, res, budget, idx, w,
                                 checker, scratch, motion)
        if result == _NO_ROOM:
            return FULL
        if result == _REACHED:
            start_node, goal_node = (new, other) if t == 0 else (other, new)
            if (_confirm(nodes, parents, flags, counters, 0, start_node, res, checker, scratch, motion)
                    and _confirm(nodes, parents, flags, counters, 1, goal_node, res, checker, scratch, motion)):
                _write_path(nodes, parents, counters, start_node, goal_node, True, path)
                return FOUND
    return RUNNING


class _Trees:
    """Tree arrays for :func:`search`, doubled when full; built from (q, parent, flags) lists."""

    def __init__(self, start_nodes: list, goal_nodes: list, capacity: int) -> None:
        dof = len(start_nodes[0][0])
        capacity = max(capacity, len(start_nodes), len(goal_nodes))
        self.nodes = np.empty((2, capacity, dof))
        self.parents = np.full((2, capacity), -1, dtype=np.int64)
        self.flags = np.zeros((2, capacity), dtype=np.int64)
        self.path = np.empty((2 * capacity, dof))
        self.counters = np.zeros(8, dtype=np.int64)
        for t, tree in enumerate((start_nodes, goal_nodes)):
            for i, (q, parent, flags) in enumerate(tree):
                self.nodes[t, i], self.parents[t, i], self.flags[t, i] = q, parent, flags
            self.counters[SIZE + t] = len(tree)

    def grow(self, limit: int) -> bool:
        capacity = self.nodes.shape[1]
        if capacity >= limit:
            return False
        bigger = min(2 * capacity, limit)
        nodes = np.empty((2, bigger, self.nodes.shape[2]))
        parents, flags = np.full((2, bigger), -1, dtype=np.int64), np.zeros((2, bigger), dtype=np.int64)
        nodes[:, :capacity], parents[:, :capacity], flags[:, :capacity] = self.nodes, self.parents, self.flags
        self.nodes, self.parents, self.flags = nodes, parents, flags
        self.path = np.empty((2 * bigger, nodes.shape[2]))
        return True


def _search(ctx: PlanningContext, roots: tuple[list, list], settings: RRTConnectSettings, state: np.ndarray,
            res: float, deadline: float) -> tuple[np.ndarray | None, int, np.ndarray]:
    """One search until ``deadline`` (perf_counter s); (path or None, goal root, counters)."""
    space = ctx.space
    trees = _Trees(*roots, min(1024, settings.max_nodes))
    work = (space.lower, space.upper, roots[0][0][0].copy(), ctx.spheres.data, ctx.scratch, ctx.motion_arrays(res))
    chunk = 128
    while True:
        begun, before = time.perf_counter(), trees.counters[ITERATIONS]
        code = search(trees.nodes, trees.parents, trees.flags, trees.counters, trees.path, state, chunk, settings.step,
                      res, settings.eager_checks, space.indices, space.weights, *work)
        now = time.perf_counter()
        if code == FOUND:
            n = trees.counters[PATH_LENGTH]
            return trees.path[:n].copy(), int(trees.counters[GOAL_ROOT]), trees.counters
        if code == FULL and not trees.grow(settings.max_nodes) or now >= deadline:
            return None, -1, trees.counters
        per_iteration = (now - begun) / max(trees.counters[ITERATIONS] - before, 1)
        # a quarter of the time left, growing at most twofold (iterations slow down as trees grow)
        chunk = int(np.clip(0.25 * (deadline - now) / max(per_iteration, 1e-7), 1, 2 * chunk))


def _roots(ctx: PlanningContext, start: np.ndarray, goals: np.ndarray, settings: RRTConnectSettings,
           rng: np.random.Generator) -> tuple[list, list, np.ndarray] | PlanStatus:
    """Tree roots [(q, parent, flags)] of the start and the usable goals, with their escape
    nodes, and the goal rows of the goal tree's roots; or INVALID_START / INVALID_GOAL."""
    both = np.vstack([start, goals])
    inside = ctx.model.within_limits(both)
    valid = inside & ctx.spheres.is_free(both)
    tight = inside & (ctx.spheres.clearance(both, ctx.resolution, self_pairs=False) < 0.5 * ctx.resolution)
    trees, rows = ([], []), []
    for i, q in enumerate(both):
        tree, toward = (trees[0], goals[0]) if i == 0 else (trees[1], start)
        escape = None
        if settings.escape and inside[i] and (tight[i] or not valid[i]):
            escape = certified_escape(ctx, q, toward, rng, 0.5 * ctx.resolution)
        if not valid[i] and escape is None:
            if i == 0:
                return PlanStatus.INVALID_START
            continue
        tree.append((q, -1, 0 if valid[i] else _DEAD))
        if escape is not None:
            tree.append((escape, len(tree) - 1, _CHECKED))
        if i > 0:
            rows.append(i - 1)
    if not rows:
        return PlanStatus.INVALID_GOAL
    # roots first: move the goal tree's escape nodes behind every root
    order = sorted(range(len(trees[1])), key=lambda k: trees[1][k][1] >= 0)
    renumber = {old: new for new, old in enumerate(order)}
    goal_nodes = [(q, renumber[p] if p >= 0 else -1, f) for q, p, f in (trees[1][k] for k in order)]
    return trees[0], goal_nodes, np.array(rows)


def rrt_connect(ctx: PlanningContext, q_start: np.ndarray, q_goal: np.ndarray,
                settings: RRTConnectSettings = RRTConnectSettings(),
                rng: np.random.Generator | None = None) -> PlanResult:
    """Plan a collision-free path from q_start to q_goal (or to any goal of a set).

    Args:
        ctx: the planning context.
        q_start: (dof,) start configuration (rad or m).
        q_goal: (dof,) goal, or (k, dof) goal set; the joints not planned must equal the start's.
        settings: :class:`RRTConnectSettings`.
        rng: random source; ``np.random.default_rng(0)`` if None. The same seed gives the same path.

    Returns:
        :class:`PlanResult`: on SUCCESS ``path`` (N, dof) runs from exactly q_start to exactly
        the reached goal (``goal_index`` its row), ``info`` has ``length`` (m, weighted),
        ``attempts``, ``escapes`` (certified escape edges among the roots), ``refined``
        (links planned on covering balls, see ``settings.certify_retries``) and ``certify``
        (:class:`CertifyReport`, if certified). INVALID_START /
        INVALID_GOAL when the start / every goal is outside the limits, or in collision for
        the sphere model without a certified escape (see ``settings.escape``); TIMEOUT when
        the budget ran out (or every tree filled up); CERTIFICATION_FAILED when every path
        found failed the exact check.
    """
    t0 = time.perf_counter()
    rng = np.random.default_rng(0) if rng is None else rng
    model, space = ctx.model, ctx.space
    start = model.check_configuration(q_start, "q_start")
    goals = model.check_configuration(q_goal, "q_goal")
    if start.shape != (model.dof,) or goals.ndim > 2:
        raise PrehensileError(f"rrt_connect: q_start must be ({model.dof},), q_goal ({model.dof},) or (k, {model.dof})")
    goals = goals.reshape(-1, model.dof)
    fixed = np.setdiff1d(np.arange(model.dof), space.indices)
    if np.any(np.abs(goals[:, fixed] - start[fixed]) > 1e-9):
        raise PrehensileError("rrt_connect: goal and start differ in joints that are not planned "
                              f"({', '.join(model.joint_names[i] for i in fixed)})")
    empty = np.zeros((0, model.dof))
    deadline = t0 + settings.time_budget_s
    totals = dict(iterations=0, nodes=0, collision_checks=0, plan_time_s=0.0, simplify_time_s=0.0, certify_time_s=0.0)
    checks = np.zeros(1, dtype=np.int64)
    report: CertifyReport | None = None
    state, searched, context, res, refined = None, None, ctx, ctx.resolution, set()
    for attempt in range(settings.certify_retries + 1):
        begun = time.perf_counter()
        if report is not None:  # the last path failed certification
            refined |= set(report.colliding_links)
            finer = ctx.refined(refined)
            context, res = (context, 0.5 * res) if finer is None or finer is context else (finer, res)
        if context is not searched:
            roots = _roots(context, start, goals, settings, rng)
            if isinstance(roots, PlanStatus):
                if report is None:
                    return PlanResult(roots, empty, PlanStats(plan_time_s=time.perf_counter() - t0))
                break
            *roots, goal_rows = roots
            searched = context
        state = rng_state(rng) if state is None else state
        path, root, counters = _search(context, roots, settings, state, res, deadline)
        totals["plan_time_s"] += time.perf_counter() - (t0 if attempt == 0 else begun)
        totals["iterations"] += int(counters[ITERATIONS])
        totals["nodes"] += int(counters[SIZE] + counters[SIZE + 1])
        totals["collision_checks"] += int(counters[CHECKS])
        if path is None:
            status = PlanStatus.TIMEOUT if report is None else PlanStatus.CERTIFICATION_FAILED
            return PlanResult(status, empty, PlanStats(**totals), info={"attempts": attempt + 1, "certify": report})
        if settings.shortcut:
            begun = time.perf_counter()
            path = shortcut(context, path, rng, settings.shortcut_iterations, settings.shortcut_time_s, res, checks)
            totals["simplify_time_s"] += time.perf_counter() - begun
        escapes = sum(flags == _CHECKED for tree in roots for _, _, flags in tree)
        info = {"attempts": attempt + 1, "length": space.path_length(path[:, space.indices]), "escapes": escapes,
                "refined": tuple(sorted(refined))}
        if settings.certify:
            report = certify_path(context, path)
            totals["certify_time_s"] += report.time_s
            info["certify"] = report
        if report is None or report.ok:
            totals["collision_checks"] += int(checks[0])
            return PlanResult(PlanStatus.SUCCESS, path, PlanStats(**totals), goal_index=int(goal_rows[root]), info=info)
        if time.perf_counter() >= deadline:
            break
    totals["collision_checks"] += int(checks[0])
    return PlanResult(PlanStatus.CERTIFICATION_FAILED, empty, PlanStats(**totals),
                      info={"attempts": attempt + 1, "certify": report})

