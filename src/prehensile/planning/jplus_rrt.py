"""J+-RRT: a unidirectional RRT toward a workspace goal, grown by Jacobian steps.

Vahrenkamp 2011 §4.1 (Alg. 13-15) and §4.4.2 (Regrasp-J+-RRT, Alg. 18-20). The tree grows
from the start by ordinary RRT steps; with probability ``goal_probability`` a random goal g
(a grasp) is picked and the tree node nearest to it among the nodes not yet marked for g is
pulled toward it by pseudoinverse steps, ``c' = c + J^+(c) clamp(Δp)``, each new
configuration joining the tree (clamped into the joint limits). A blocked step (collision, or
no progress) marks the node for g, so that the same node is not pulled toward the same goal
again. No IK solver is needed.

- :func:`jplus_rrt`: one tool, a set of tool poses (the grasps of an object); nearest node in
  the SE(3) metric ``|Δt| + rotation_weight * angle`` (§2.2).
- :func:`regrasp_jplus_rrt`: two tools, a grasp pair (g_a, g_b) of one object. With the object
  pose free (hand-over, Alg. 18-20) the goal is the relation of the two tools, ``T_b^-1 T_a =
  g_b^-1 g_a``: the object is where tool b holds it, and the nearest node is the one whose
  relation is closest. The steps move both arms at once: a stacked pseudoinverse over both
  arms and the object's twist (:class:`~prehensile.ik.hand_pair.HandPair`), where the thesis
  alternates single-arm steps toward the pose the other hand currently implies; both split
  the motion between the arms.
  With a set of object poses (bimanual J+-RRT) each goal is a pose and a grasp pair, and the
  two tools step toward fixed targets.

The search loop runs in Python over compiled pieces (tool poses and Jacobians, motion checks);
the returned path is shortcut and certified with the exact geometry like every planner's.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from typing import Callable, Sequence

import numpy as np

from prehensile.clock import clock
from prehensile.errors import PrehensileError
from prehensile.ik import kernels as ik_kernels
from prehensile.ik.hand_pair import HandPair
from prehensile.ik.jacobian import ChainSolver, JacobianIKSettings
from prehensile.planning.certify import certified_escape, certify_path, refine_after_failure
from prehensile.planning.context import PlanningContext
from prehensile.planning.finish import finish_path
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus
from prehensile.planning.seeding import planner_rng
from prehensile.settings import (
    FINITE_NON_NEGATIVE, FINITE_POSITIVE, NON_NEGATIVE, POSITIVE, UNIT_INTERVAL, at_least, check_fields,
)
from prehensile.spatial.transforms import check_one_pose, invert


_HALVINGS = 4  # times a Jacobian step that made the error grow is taken again, half as long


@dataclass(frozen=True)
class JPlusRRTSettings:
    """Settings of :func:`jplus_rrt` and :func:`regrasp_jplus_rrt`.

    Attributes:
        time_budget_s: search budget (s).
        step: RRT extension step in the workspace-weighted metric (m).
        goal_probability: chance per iteration of an extension toward a goal (r_ExtendToGoal, r_Re).
        max_step_position, max_step_rotation: Cartesian step clamp of a Jacobian step (m, rad).
        damping: λ (m) of the damped least-squares Jacobian steps of :func:`jplus_rrt` (0: the
            thesis's pseudoinverse), which keeps steps near a singularity bounded. On 60 random
            reachable Panda poses above a floor (2 s budget), with the halved steps and the
            joints held at their limits of :func:`_extend_to_goal`: 0: 48 solved, 0.01: 50,
            0.05: 50 (the thesis's steps: 44); 0.05 never converged to a pose that needs a
            joint at its limit, where 0.01 takes 10 ms.
        position_tolerance, rotation_tolerance: goal reached (m, rad), per tool.
        rotation_weight: m per rad in the SE(3) metric of the nearest-node search.
        max_goal_steps: Jacobian steps per extension toward a goal.
        max_nodes: tree capacity.
        shortcut_iterations: random shortcuts of the found path.
        certify: certify the path with the exact geometry before returning it.
        certify_retries: searches started over (a new tree) after a path failed certification,
            as in :class:`~prehensile.planning.rrt_connect.RRTConnectSettings`: with covering
            balls on the links that collided (the last one on every link with balls), else at
            half the resolution each, before giving up with CERTIFICATION_FAILED.
        escape: a start within the limits that only the conservative balls reject leaves
            along a short straight motion certified on the exact geometry (as in
            :class:`~prehensile.planning.rrt_connect.RRTConnectSettings`), searched until the
            budget runs out (TIMEOUT if none is found); the start itself is then not extended.
        exact_approach: within this distance (m) of a goal position a Jacobian step that the
            balls block is certified on the exact geometry instead (0: never): the
            conservative balls would keep a grasp in contact range of the object out of reach.
            :func:`jplus_rrt` only: a hand-over's two hands are close at every goal, and
            certifying each blocked step made Regrasp-J+-RRT 1.5x slower on ARMAR-III.
    """

    time_budget_s: float = 5.0
    step: float = 0.05
    goal_probability: float = 0.2
    max_step_position: float = 0.03
    max_step_rotation: float = 0.15
    damping: float = 0.01
    position_tolerance: float = 1e-3
    rotation_tolerance: float = 1e-2
    rotation_weight: float = 0.1
    max_goal_steps: int = 200
    max_nodes: int = 100_000
    shortcut_iterations: int = 100
    certify: bool = True
    certify_retries: int = 3
    escape: bool = True
    exact_approach: float = 0.05

    def __post_init__(self) -> None:
        positive = ("step", "max_step_position", "max_step_rotation", "position_tolerance", "rotation_tolerance",
                    "rotation_weight")
        check_fields(self, time_budget_s=FINITE_POSITIVE, **dict.fromkeys(positive, POSITIVE),
                     damping=FINITE_NON_NEGATIVE, goal_probability=UNIT_INTERVAL, max_goal_steps=at_least(1),
                     max_nodes=at_least(2), shortcut_iterations=at_least(0), certify_retries=at_least(0),
                     exact_approach=NON_NEGATIVE)


class _Tree:
    """Nodes (N, dof) with parents, tool poses (N, T, 4, 4) and per-goal marks, in growing arrays."""

    def __init__(self, q_start: np.ndarray, tools: np.ndarray, capacity: int) -> None:
        self.q = np.empty((capacity, len(q_start)))
        self.parent = np.empty(capacity, dtype=np.int64)
        self.tools = np.empty((capacity,) + tools.shape)
        self.marked: dict[int, list[int]] = {}
        self.count = 0
        self.first = 0  # nodes before it are not extended (a start left along its escape edge)
        self.add(q_start, -1, tools)

    def add(self, q: np.ndarray, parent: int, tools: np.ndarray) -> int:
        if self.count == len(self.q):
            raise IndexError("tree full")
        i = self.count
        self.q[i], self.parent[i], self.tools[i] = q, parent, tools
        self.count += 1
        return i

    def mark(self, node: int, goal: int) -> None:
        self.marked.setdefault(goal, []).append(node)

    def path_to(self, i: int) -> np.ndarray:
        nodes = []
        while i >= 0:
            nodes.append(self.q[i])
            i = int(self.parent[i])
        return np.array(nodes[::-1])


class _PoseGoals:
    """One tool toward any of the world poses ``targets`` (k, 4, 4), or into a goal region:
    ``targets`` a function from a tool pose (4, 4) to the region's pose nearest to it (4, 4),
    each step aiming at the pose nearest to where the tool is. In a region a node's ``tools``
    are its tool pose and that nearest pose (2, 4, 4), so the nearest-node search calls no function."""

    def __init__(self, solver: ChainSolver, targets: np.ndarray | Callable[[np.ndarray], np.ndarray],
                 s: JPlusRRTSettings) -> None:
        self.solver, self.s = solver, s
        self.closest = targets if callable(targets) else None
        self.targets = solver.targets(targets) if self.closest is None else None
        self.count = 1 if self.targets is None else len(self.targets)
        self._scratch = (np.empty((len(solver.table), 3, 4)), np.empty((4, 4)), np.empty((6, solver.n)), np.empty(6))
        self._limits = (solver.model.lower[solver.var_q], solver.model.upper[solver.var_q])

    def tools(self, q: np.ndarray) -> np.ndarray:
        tool = self.solver.tool_pose(q)
        return tool[None] if self.closest is None else np.stack((tool, self._nearest(tool)))

    def _nearest(self, tool: np.ndarray) -> np.ndarray:
        """The region's pose (4, 4) nearest to the tool pose (4, 4)."""
        return check_one_pose(self.closest(tool), "J+-RRT: the pose of the goal region nearest to the tool")

    def distance(self, tools: np.ndarray, g: int) -> np.ndarray:
        return _se3_distance(tools[:, 0], self.targets[g] if self.closest is None else tools[:, 1],
                             self.s.rotation_weight)

    def step(self, q: np.ndarray, tools: np.ndarray, g: int) -> tuple[np.ndarray, float, float]:
        """(q' (dof,), position and rotation error at q), the node's ``tools`` at q."""
        solver, s = self.solver, self.s
        frames, pose, jac, err = self._scratch
        ik_kernels.chain_pose_jacobian(q, solver.T_world_root, solver.table, solver.var_of_q, solver.T_tip_tcp,
                                       frames, pose, jac)
        ik_kernels.pose_error(self.targets[g] if self.closest is None else tools[1], pose, err)
        pos_err, rot_err = np.linalg.norm(err[:3]), np.linalg.norm(err[3:])
        err[:3] *= min(1.0, s.max_step_position / max(pos_err, 1e-300))
        err[3:] *= min(1.0, s.max_step_rotation / max(rot_err, 1e-300))
        q_new = q.copy()
        var = solver.var_q  # the Jacobian's columns are in chain order
        q_new[var] += _limited_step(jac, err, q[var], *self._limits, s.damping)
        return q_new, pos_err, rot_err

    def info(self, q: np.ndarray, g: int) -> dict:
        return {}


class _GraspPairGoals:
    """Two tools at a grasp pair of one object; goal g = (object pose p, grasp i, grasp j).

    ``objects``: (m, 4, 4) object poses to choose from, or None: the object is free, at the
    pose where tool b holds it.
    """

    def __init__(self, pair: HandPair, grasps: Sequence[np.ndarray], objects: np.ndarray | None,
                 s: JPlusRRTSettings) -> None:
        self.pair, self.s = pair, s
        self.grasps = [arm.targets(g) for arm, g in zip(pair.arms, grasps)]
        self.objects = None if objects is None else pair.arms[0].targets(objects)
        self.shape = (1 if objects is None else len(self.objects), len(self.grasps[0]), len(self.grasps[1]))
        self.count = int(np.prod(self.shape))

    def tools(self, q: np.ndarray) -> np.ndarray:
        return self.pair.poses(q)

    def _object(self, tools: np.ndarray, g: int) -> tuple[np.ndarray, np.ndarray]:
        """The object pose(s) (..., 4, 4) goal g wants for tool poses (..., 2, 4, 4), and its grasps (2, 4, 4)."""
        p, i, j = np.unravel_index(g, self.shape)
        grasps = np.stack([self.grasps[0][i], self.grasps[1][j]])
        return (tools[..., 1, :, :] @ invert(grasps[1]) if self.objects is None else self.objects[p]), grasps

    def distance(self, tools: np.ndarray, g: int) -> np.ndarray:
        """Both tools' SE(3) distances to the goal's grasp poses (for a free object: tool a's to
        where tool b wants it, the distance of the two tools' relation from the goal's)."""
        T, grasps = self._object(tools, g)
        w = self.s.rotation_weight
        return _se3_distance(tools[:, 0], T @ grasps[0], w) + _se3_distance(tools[:, 1], T @ grasps[1], w)

    def step(self, q: np.ndarray, tools: np.ndarray, g: int) -> tuple[np.ndarray, float, float]:
        T, grasps = self._object(tools, g)
        q_new, _, pos_err, rot_err = self.pair.step(q, T, grasps, free_object=self.objects is None)
        return q_new, pos_err, rot_err

    def info(self, q: np.ndarray, g: int) -> dict:
        T, _ = self._object(self.pair.poses(q), g)
        p, i, j = np.unravel_index(g, self.shape)
        return {"grasps": (int(i), int(j)), "object_index": int(p), "T_world_object": T}


def jplus_rrt(ctx: PlanningContext, q_start: np.ndarray, target_poses: np.ndarray | Callable[[np.ndarray], np.ndarray],
              settings: JPlusRRTSettings = JPlusRRTSettings(), rng: np.random.Generator | int | None = None, *,
              T_tip_tcp: np.ndarray | None = None, chain: str | None = None) -> PlanResult:
    """Plan from ``q_start`` until the tool reaches any of ``target_poses`` (arguments in the
    order of :func:`~prehensile.planning.rrt_connect.rrt_connect`).

    Args:
        ctx: planning context; it plans exactly the joints of the tool's chain (in any order).
        q_start: (dof,) start configuration.
        target_poses: (k, 4, 4) world tool poses, e.g. ``T_world_object @ grasps``; or a goal
            region: a function from a world tool pose (4, 4) to the region's pose nearest to it
            (4, 4), each Jacobian step aiming at the pose nearest to the tool (reached within
            the tolerances of it; :func:`~prehensile.planning.to_pose.plan_to_pose` builds it
            for a :class:`~prehensile.scene.PoseGoal`).
        settings: :class:`JPlusRRTSettings`.
        rng: random source or seed (:func:`~prehensile.planning.seeding.planner_rng`: seed 0 if None).
        T_tip_tcp: (4, 4) tool frame on the chain's tip link.
        chain: the tool's chain (its tip link carries the tool); default: the chain of the
            planned joints, which must be unambiguous (SRDF groups with the same joints and
            different tips need a name).

    Returns:
        :class:`PlanResult`; ``goal_index`` is the grasp reached (0 for a region); ``info`` holds ``attempts``,
        ``refined`` (links planned on covering balls, see ``settings.certify_retries``) and,
        if certified, ``certify`` (the last :class:`~prehensile.planning.certify.CertifyReport`).
    """
    goals = _PoseGoals(_chain_solver(ctx, chain, T_tip_tcp), target_poses, settings)
    return _grow(ctx, q_start, goals, settings, rng)


def regrasp_jplus_rrt(ctx: PlanningContext, q_start: np.ndarray, arms: Sequence[ChainSolver],
                      grasps: Sequence[np.ndarray], objects: np.ndarray | None = None,
                      free: Sequence[str] | str | None = None, settings: JPlusRRTSettings = JPlusRRTSettings(),
                      rng: np.random.Generator | int | None = None) -> PlanResult:
    """Plan from ``q_start`` until both tools hold one object by a grasp pair.

    Args:
        ctx: planning context; it plans (at least) both arms' joints and ``free``.
        q_start: (dof,) start configuration.
        arms: the two arm solvers (tools at the hands' TCPs), e.g. [receiving, holding].
        grasps: per arm the grasp set T_object_tcp (k_h, 4, 4).
        objects: (m, 4, 4) world object poses to choose from (bimanual J+-RRT), or None: the
            object pose is free (hand-over, Regrasp-J+-RRT).
        free: further joints the Jacobian steps move with the arms (e.g. "Torso").

    Returns:
        :class:`PlanResult`; ``goal_index`` indexes (object pose, grasp a, grasp b) in C order,
        ``info`` holds ``grasps`` (i, j), ``object_index`` and ``T_world_object`` (4, 4) (for a
        free object: ``T_world_tcp_b @ inverse(g_b)`` at the last configuration), and those
        of :func:`jplus_rrt`.
    """
    s = settings
    pair = HandPair(arms, free, JacobianIKSettings(method="pinv", max_step_position=s.max_step_position,
                                                   max_step_rotation=s.max_step_rotation))
    ctx.check_solvers(arms, "regrasp J+-RRT", free=free)
    return _grow(ctx, q_start, _GraspPairGoals(pair, grasps, objects, s), replace(s, exact_approach=0.0), rng)


def _grow(ctx: PlanningContext, q_start: np.ndarray, goals, s: JPlusRRTSettings,
          rng: np.random.Generator | int | None) -> PlanResult:
    """The J+-RRT loop (Alg. 13) over ``goals`` (:class:`_PoseGoals` or :class:`_GraspPairGoals`),
    started over with a new tree after a path fails the exact certification, as
    :class:`~prehensile.planning.rrt_connect.RRTConnectSearch` does
    (:func:`~prehensile.planning.certify.refine_after_failure`)."""
    ctx.warm_up(s.certify or s.escape)
    start_time = clock()
    rng = planner_rng(rng)
    q_start = ctx.model.check_one(q_start, "q_start").copy()
    deadline = start_time + s.time_budget_s
    context, links, res, report = ctx, frozenset(), ctx.resolution, None
    iterations, checks, simplify_time, certify_time = 0, 0, 0.0, 0.0
    for attempt in range(s.certify_retries + 1):
        counted = int(context.counters[0])
        status, tree, reached, g, tried = _search(context, q_start, goals, s, rng, deadline, res)
        iterations += tried
        if status is PlanStatus.SUCCESS:
            status, path, simplify, certify, report = finish_path(context, tree.path_to(reached), rng,
                                                                  s.shortcut_iterations, s.certify, res)
            simplify_time, certify_time = simplify_time + simplify, certify_time + certify
        checks += int(context.counters[0]) - counted
        if status is not PlanStatus.CERTIFICATION_FAILED or attempt == s.certify_retries or clock() >= deadline:
            break
        context, links, res = refine_after_failure(ctx, context, links, res, report,
                                                   last=attempt + 1 == s.certify_retries)
    stats = PlanStats(iterations, 0 if tree is None else tree.count, checks, 0,
                      clock() - start_time - simplify_time - certify_time, simplify_time, certify_time)
    info = {"attempts": attempt + 1, "refined": tuple(sorted(links))} | ({} if report is None else {"certify": report})
    if status is PlanStatus.SUCCESS:
        return PlanResult(status, path, stats, g, info=info | goals.info(tree.q[reached], g))
    result = ctx.explain(PlanResult(status, np.zeros((0, ctx.model.dof)), stats, info=info), q_start)
    if status is PlanStatus.TIMEOUT and tree is not None and not result.info.get("reason"):
        result = replace(result, info={**result.info, "reason": _closest_approach(tree, goals)})
    return result


def _closest_approach(tree: _Tree, goals) -> str:
    """Why a search timed out, as far as its tree tells: how near its nearest node came to a goal."""
    near = [goals.distance(tree.tools[tree.first:tree.count], g) for g in range(goals.count)]
    g = int(np.argmin([d.min() for d in near]))
    node = tree.first + int(np.argmin(near[g]))
    _, position, rotation = goals.step(tree.q[node], tree.tools[node], g)
    return (f"no goal reached: the tool came within {1e3 * position:.1f} mm and {rotation:.3f} rad of one at best "
            f"({tree.count} nodes); the goal may be out of reach, or behind obstacles the Jacobian steps cannot pass")


def _search(ctx: PlanningContext, q_start: np.ndarray, goals, s: JPlusRRTSettings, rng: np.random.Generator,
            deadline: float, res: float) -> tuple[PlanStatus, _Tree | None, int, int, int]:
    """Grow a tree from q_start until a node reaches a goal or ``deadline`` (s,
    :func:`~prehensile.clock.clock`), motions checked at ``res`` (m): (SUCCESS, TIMEOUT or
    INVALID_START, the tree, the node that reached a goal, that goal, iterations)."""
    valid, escape = bool(ctx.is_valid(q_start)), None
    if not valid and s.escape and ctx.model.within_limits(q_start):  # random directions until the deadline
        escape = certified_escape(ctx, q_start, q_start, rng, ctx.end_margin, attempts=None, deadline=deadline)
    if not valid and escape is None:
        return PlanStatus.TIMEOUT if clock() >= deadline else PlanStatus.INVALID_START, None, -1, -1, 0
    tree = _Tree(q_start, goals.tools(q_start), s.max_nodes)
    if escape is not None:
        tree.add(escape, 0, goals.tools(escape))
        tree.first = 1
    iterations, bounds = 0, ctx.space.sampling_bounds(q_start[ctx.space.indices])
    try:
        while clock() < deadline:
            iterations += 1
            if rng.random() >= s.goal_probability:
                _extend_randomly(ctx, tree, goals, s.step, bounds, rng, res)
                continue
            g = int(rng.integers(goals.count))
            d = goals.distance(tree.tools[:tree.count], g)
            d[tree.marked.get(g, [])] = np.inf
            d[:tree.first] = np.inf
            node = int(np.argmin(d))
            if not np.isfinite(d[node]):
                continue
            reached = _extend_to_goal(ctx, tree, node, g, goals, s, res)
            if reached >= 0:
                return PlanStatus.SUCCESS, tree, reached, g, iterations
    except IndexError:  # the tree is full: report like a timeout
        pass
    return PlanStatus.TIMEOUT, tree, -1, -1, iterations


def _extend_randomly(ctx: PlanningContext, tree: _Tree, goals, step: float, bounds: tuple[np.ndarray, np.ndarray],
                     rng: np.random.Generator, res: float) -> None:
    """One RRT step from the node nearest to a uniform sample within ``bounds`` (lower, upper) (n,)
    (workspace-weighted metric), checked at ``res`` (m)."""
    idx, w = ctx.space.indices, ctx.space.weights
    sample = rng.uniform(*bounds)
    near = tree.first + int(np.argmin(np.abs(tree.q[tree.first:tree.count][:, idx] - sample) @ w))
    delta = sample - tree.q[near, idx]
    length = float(w @ np.abs(delta))
    if length == 0.0:
        return
    q_new = tree.q[near].copy()
    q_new[idx] += delta * min(1.0, step / length)
    if ctx.check_motion(tree.q[near], q_new, res):
        tree.add(q_new, near, goals.tools(q_new))


def _extend_to_goal(ctx: PlanningContext, tree: _Tree, node: int, g: int, goals, s: JPlusRRTSettings,
                    res: float) -> int:
    """ExtendToGoal (Alg. 14): Jacobian steps from ``node`` toward goal g, each new
    configuration a tree node; the node reaching it, or -1 when a step is blocked (collision,
    or an error that keeps growing) or the steps run out. A step after which the error grew
    (the linearisation failed: a large rotation, a joint held at its limit) is taken again
    half as long from the node before it, up to :data:`_HALVINGS` times. Steps stay within
    the joint limits (a goal whose every IK solution has a joint at its limit stays
    reachable). Within ``s.exact_approach`` of the goal a step the balls block may pass on the
    exact geometry. Motions are checked at ``res`` (m)."""
    space, last, halvings = ctx.space, np.inf, 0
    for _ in range(s.max_goal_steps):
        q_new, pos_err, rot_err = goals.step(tree.q[node], tree.tools[node], g)
        if pos_err <= s.position_tolerance and rot_err <= s.rotation_tolerance:
            return node
        error = pos_err + s.rotation_weight * rot_err
        if error < last:
            base, last, halvings = node, error, 0
            q_new[space.indices] = np.clip(q_new[space.indices], space.lower, space.upper)
        elif halvings < _HALVINGS:  # halfway from the node before to this one, which overshot
            base, halvings = int(tree.parent[node]), halvings + 1
            q_new = 0.5 * (tree.q[base] + tree.q[node])
        else:
            tree.mark(node, g)
            return -1
        if not _step_free(ctx, tree.q[base], q_new, res, pos_err <= s.exact_approach):
            tree.mark(base, g)
            return -1
        node = tree.add(q_new, base, goals.tools(q_new))
        tree.mark(node, g)
    return -1


def _limited_step(jac: np.ndarray, err: np.ndarray, q: np.ndarray, lower: np.ndarray, upper: np.ndarray,
                  damping: float) -> np.ndarray:
    """The damped least-squares step dq (n,) toward the twist ``err`` (6,) with Jacobian ``jac``
    (6, n) (``damping`` λ; 0: the pseudoinverse) that keeps q + dq within [lower, upper] (n,):
    a joint the step would take past a limit moves to it and is held there, and the others
    solve for the rest of the error again (the clamping loop of Baerlocher & Boulic 2004).
    Clamping after the step would leave the error at a joint limit undone."""
    dq, free = np.zeros(len(q)), np.ones(len(q), dtype=bool)
    while free.any():
        J, rest = jac[:, free], err - jac[:, ~free] @ dq[~free]
        dq[free] = J.T @ np.linalg.solve(J @ J.T + damping**2 * np.eye(6), rest) if damping > 0 else \
            np.linalg.pinv(J) @ rest
        over = free & ((q + dq < lower) | (q + dq > upper))
        if not over.any():
            break
        dq[over] = np.clip(q[over] + dq[over], lower[over], upper[over]) - q[over]
        free &= ~over
    return dq


def _step_free(ctx: PlanningContext, q: np.ndarray, q_new: np.ndarray, res: float, exact: bool) -> bool:
    """The motion q -> q_new (dof,) is free for the balls (checked at ``res`` m), or (if
    ``exact``) certified on the exact geometry where they block it."""
    return bool(ctx.check_motion(q, q_new, res)) or exact and certify_path(ctx, np.stack((q, q_new))).ok


def _chain_solver(ctx: PlanningContext, chain: str | None, T_tip_tcp: np.ndarray | None) -> ChainSolver:
    """The solver of ``chain`` (default: the chain whose joints the context plans), checked to
    move exactly the planned joints."""
    model, planned = ctx.model, set(ctx.space.indices.tolist())
    if chain is None:
        matches = [name for name, c in model.chains.items() if {model.joint_index(j) for j in c.joint_names} == planned]
        if not matches:
            raise PrehensileError(f"J+-RRT: the planned joints {ctx.space.joint_names} are not a chain of "
                                  f"'{model.name}'; chains: {', '.join(model.chains)}")
        if len({model.chains[name].tip_link for name in matches}) > 1:
            raise PrehensileError(f"J+-RRT: the chains {', '.join(matches)} all move the planned joints but end at "
                                  "different links; name the tool's chain (chain=...)")
        chain = matches[0]
    solver = ChainSolver(model, chain, T_tip_tcp=T_tip_tcp, T_world_root=ctx.T_world_base)
    if set(solver.var_q.tolist()) != planned:
        raise PrehensileError(f"J+-RRT: chain '{chain}' moves {', '.join(solver.chain.joint_names)}, the context "
                              f"plans {', '.join(ctx.space.joint_names)}: plan exactly the chain's joints")
    return solver


def _se3_distance(poses: np.ndarray, targets: np.ndarray, rotation_weight: float) -> np.ndarray:
    """(N,) ``|Δt| + rotation_weight * angle`` between poses (N, 4, 4) and targets (N or 1, 4, 4)
    or (4, 4) (Vahrenkamp A.3.2)."""
    targets = np.broadcast_to(targets, poses.shape)
    cos = np.clip((np.einsum("nij,nij->n", poses[:, :3, :3], targets[:, :3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    return np.linalg.norm(poses[:, :3, 3] - targets[:, :3, 3], axis=1) + rotation_weight * np.arccos(cos)
