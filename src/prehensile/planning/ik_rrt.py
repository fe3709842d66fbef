"""IK-RRT, bimanual IK-RRT, hand-over (regrasp) IK-RRT and Multi-EEF-RRT.

Vahrenkamp 2011 §4.2-4.4 (Alg. 16, 17). The goal is a workspace set (grasps of an object);
goal configurations are sampled by a randomized IK *during* planning and all become roots of
the goal tree of a bidirectional search. Here the bidirectional search is the compiled
RRT-Connect (:class:`~prehensile.planning.rrt_connect.RRTConnectSearch`): rounds of IK
sampling and search alternate, each new IK sample joins the goal tree as a root, the trees
are kept from round to round and the round's budget doubles. As in the thesis, the search is
probabilistically complete when the IK sampler is.

The goal samplers: :func:`grasp_sampler` (one arm, a grasp set: IK-RRT),
:func:`dual_arm_sampler` (both arms, sampled hip: bimanual IK-RRT, Alg. 17) and
:func:`regrasp_sampler` (free object pose: hand-over, §4.4.2; grasp pairs whose hands would
overlap and arm samples in self-collision are dropped once, up front). :func:`multi_eef_rrt`
runs one search per end effector round-robin in one thread and keeps the first success
("winner takes all", §4.3; the thesis uses one thread per hand).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from prehensile.clock import clock
from prehensile.collision.sphere_checker import SphereChecker
from prehensile.errors import PrehensileError
from prehensile.ik.complete import CompleteIKSettings, solve_ik_complete
from prehensile.ik.hand_pair import check_arm_pair
from prehensile.ik.hybrid import HybridIKSettings, ObjectRegion, solve_ik_hybrid, solve_regrasp_ik
from prehensile.ik.jacobian import ChainSolver
from prehensile.ik.reach import ReachSamples, reach_samples
from prehensile.kinematics.forward import forward_kinematics
from prehensile.planning.context import PlanningContext
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus
from prehensile.planning.rrt_connect import RRTConnectSearch, RRTConnectSettings
from prehensile.planning.seeding import planner_rng
from prehensile.settings import FINITE_POSITIVE, POSITIVE, at_least, check_fields
from prehensile.spatial.transforms import invert

@dataclass(frozen=True, eq=False)
class GoalSampler:
    """Goal configurations for :func:`ik_rrt`, drawn by an IK during planning.

    ``draw(rng, call, attempts, budget)`` returns one goal configuration (dof,) or None, and
    what it reached (grasp indices, object pose, ...): ``call`` is its number in the query (0
    first), ``attempts`` a fixed amount of IK work (its unit is the sampler's) and ``budget``
    a time limit (s). ``info["grasp"]`` is the planners' ``goal_index``: the target pose
    reached, or for two hands the pair of poses reached as one index in C order
    (:func:`_pair_info`, as in J+-RRT). Goals must be valid (``PlanningContext.is_valid``);
    the one-arm sampler also keeps goals only the conservative balls reject (``is_usable_end``:
    a hand around an object), the two-hand samplers do not: their hands are close in every
    solution, and each such goal would need a certified escape of both arms, dearer than
    another IK sample (Regrasp-IK-RRT on ARMAR-III took up to 3.7x as long).

    Attributes:
        who: the sampler's name in error messages.
        q_ref: (dof,) the values its goals keep in the joints the IK does not move.
        draw: the sampling function.
    """

    who: str
    q_ref: np.ndarray
    draw: Callable[[np.random.Generator, int, int, float], tuple[np.ndarray | None, dict]]

    def __call__(self, rng: np.random.Generator, call: int, attempts: int, budget: float
                 ) -> tuple[np.ndarray | None, dict]:
        return self.draw(rng, call, attempts, budget)

    def check_start(self, ctx: PlanningContext, q_start: np.ndarray) -> None:
        """Raise PrehensileError if ``q_ref`` and the start differ in joints ``ctx`` does not
        plan: every goal would move them, and the planner refuses such goals."""
        q_start = ctx.model.check_one(q_start, f"{self.who}: q_start")
        fixed = ctx.space.fixed
        differ = fixed[np.abs(self.q_ref[fixed] - q_start[fixed]) > 1e-9]
        if differ.size:
            raise PrehensileError(f"{self.who}: q_ref and the start differ in joints the context does not plan "
                                  f"({', '.join(ctx.model.joint_names[i] for i in differ)}; planned: "
                                  f"{', '.join(ctx.space.joint_names)}): its goals would move them")


@dataclass(frozen=True)
class IKRRTSettings:
    """Settings of :func:`ik_rrt` and :func:`multi_eef_rrt`.

    Sampling and search rounds are counted in attempts and iterations, not seconds, so a
    seed gives the same path on any machine unless a time limit cuts in.

    Attributes:
        time_budget_s: total budget (s), IK sampling included.
        ik_attempts: IK attempts per goal sample (random restarts of :func:`grasp_sampler`,
            free-joint samples of :func:`dual_arm_sampler`, batches of 16 object poses of
            :func:`regrasp_sampler`).
        ik_budget_s: time limit of one goal sample (s), a safeguard.
        first_round_iterations: search iterations of the first round; they double every round.
        rrt: settings of the bidirectional search (shortcutting, certification, step; its
            time budget is not used).
    """

    time_budget_s: float = 5.0
    ik_attempts: int = 8
    ik_budget_s: float = 1.0
    first_round_iterations: int = 256
    rrt: RRTConnectSettings = RRTConnectSettings()

    def __post_init__(self) -> None:
        check_fields(self, time_budget_s=FINITE_POSITIVE, ik_attempts=at_least(1), ik_budget_s=POSITIVE,
                     first_round_iterations=at_least(1))


MAX_ROUND_ITERATIONS = 1 << 40  # the rounds' doubling stops here (no search gets near it in its budget)


class _Search:
    """One IK-RRT: the search, what each goal configuration found so far reached, and the next
    round's budget."""

    def __init__(self, ctx: PlanningContext, q_start: np.ndarray, sampler: GoalSampler, settings: IKRRTSettings,
                 rng: np.random.Generator) -> None:
        self.ctx, self.sampler, self.settings = ctx, sampler, settings
        self.search = RRTConnectSearch(ctx, q_start, settings.rrt, rng)
        self.infos: list[dict] = []
        self.calls = 0  # goal samples drawn
        self.round_iterations = settings.first_round_iterations
        self.iterations = self.nodes = self.checks = 0
        self.simplify_s = self.certify_s = 0.0

    def step(self, rng: np.random.Generator, deadline: float) -> PlanResult | None:
        """Sample one goal, then search a round; a finished PlanResult, or None to go on."""
        q, info = self.sampler(rng, self.calls, self.settings.ik_attempts,
                               min(self.settings.ik_budget_s, max(deadline - clock(), 0.0)))
        self.calls += 1
        if q is not None:
            self.infos.append(info)
            self.search.add_goals(q, deadline)
        remaining = deadline - clock()
        if not self.infos or remaining <= 0:
            return None
        result = self.search.solve(remaining, self.round_iterations)
        # a round that ended before searching (e.g. every goal rejected) does not grow the next
        if result.stats.iterations:
            self.round_iterations = min(2 * self.round_iterations, MAX_ROUND_ITERATIONS)
        s = result.stats
        self.iterations += s.iterations
        self.nodes = max(self.nodes, s.nodes)
        self.checks += s.collision_checks
        self.simplify_s += s.simplify_time_s
        self.certify_s += s.certify_time_s
        if result.status in (PlanStatus.TIMEOUT, PlanStatus.CERTIFICATION_FAILED, PlanStatus.INVALID_GOAL):
            return None
        goal = self.infos[result.goal_index] if result.success else {}  # stats: the caller's _total_stats
        return PlanResult(result.status, result.path, PlanStats(), goal.get("grasp", -1),
                          info={"goal": goal, "goal_configuration": result.goal_index,
                                "goal_configurations": len(self.infos)})


def _total_stats(searches: Sequence[_Search], elapsed_s: float) -> PlanStats:
    """Statistics of a query summed over its searches (one per hand); the search time is the
    time ``elapsed_s`` (s) less simplification and certification (so it includes IK sampling)."""
    simplify_s, certify_s = sum(s.simplify_s for s in searches), sum(s.certify_s for s in searches)
    return PlanStats(sum(s.iterations for s in searches), sum(s.nodes for s in searches),
                     sum(s.checks for s in searches), sum(len(s.infos) for s in searches),
                     elapsed_s - simplify_s - certify_s, simplify_s, certify_s)


def ik_rrt(ctx: PlanningContext, q_start: np.ndarray, sampler: GoalSampler, settings: IKRRTSettings = IKRRTSettings(),
           rng: np.random.Generator | int | None = None) -> PlanResult:
    """Plan from ``q_start`` to any goal configuration the IK ``sampler`` finds.

    Returns:
        :class:`PlanResult`; ``goal_index`` is the target pose reached, for two hands the
        pair (i, j) of their pose sets' poses as the index ``i * k_b + j`` (as in
        :func:`~prehensile.planning.jplus_rrt.jplus_rrt` and its bimanual variants), ``info``
        holds what the winning sample reached (``info["goal"]``, e.g. the grasp pair), which
        of the goal configurations sampled it was (``goal_configuration``) and how many were
        (``goal_configurations``); ``stats`` count the IK sampling as search time. TIMEOUT or
        NO_GOAL_CONFIGURATION (IK found nothing) when the budget runs out; INVALID_START (with
        ``info["reason"]``) for a start outside the limits or in collision.

    Raises:
        PrehensileError: ``sampler`` is not a :class:`GoalSampler`, or its ``q_ref`` and
            ``q_start`` differ in joints the context does not plan.
    """
    return multi_eef_rrt(ctx, q_start, {"": sampler}, settings, rng)


def multi_eef_rrt(ctx: PlanningContext | dict[str, PlanningContext], q_start: np.ndarray,
                  samplers: dict[str, GoalSampler], settings: IKRRTSettings = IKRRTSettings(),
                  rng: np.random.Generator | int | None = None) -> PlanResult:
    """Multi-EEF-RRT: one IK-RRT per end effector, round-robin; the first path wins.

    Args:
        ctx: one context for all, or one per end effector (each hand plans its own chain).
        samplers: end-effector name -> goal sampler for that hand.
        rng: random source or seed (:func:`~prehensile.planning.seeding.planner_rng`: seed 0 if None).

    Returns:
        :class:`PlanResult` as of :func:`ik_rrt`, with ``end_effector`` the hand that grasps;
        ``stats`` are totals over the hands' searches.
    """
    if not samplers:
        raise PrehensileError("multi_eef_rrt: no goal samplers given (samplers: end-effector name -> sampler)")
    if isinstance(ctx, dict) and set(samplers) - set(ctx):
        raise PrehensileError(f"multi_eef_rrt: no context for {', '.join(sorted(set(samplers) - set(ctx)))}; "
                              f"contexts: {', '.join(sorted(ctx))}")
    for context in (ctx.values() if isinstance(ctx, dict) else (ctx,)):
        context.warm_up(settings.rrt.certify or settings.rrt.escape)
    start = clock()
    deadline = start + settings.time_budget_s
    rng = planner_rng(rng)
    contexts = ctx if isinstance(ctx, dict) else {name: ctx for name in samplers}
    for name, sampler in samplers.items():  # a start only the balls reject is left to the search's certified escape
        context = contexts[name]
        if not isinstance(sampler, GoalSampler):
            who = f"multi_eef_rrt: the sampler of {name!r}" if name else "ik_rrt: the sampler"
            raise PrehensileError(f"{who} is a {type(sampler).__name__}, not a GoalSampler (grasp_sampler, "
                                  "dual_arm_sampler, regrasp_sampler or GoalSampler(who, q_ref, draw))")
        sampler.check_start(context, q_start)
        if not context.is_usable_end(q_start):
            return context.explain(PlanResult(PlanStatus.INVALID_START, np.zeros((0, len(q_start))), PlanStats(),
                                              end_effector=name), q_start)
    searches = {name: _Search(contexts[name], q_start, sampler, settings, rng) for name, sampler in samplers.items()}
    while clock() < deadline:
        for name, search in searches.items():
            result = search.step(rng, deadline)
            if result is not None:
                stats = _total_stats(list(searches.values()), clock() - start)
                return contexts[name].explain(dataclasses.replace(result, stats=stats, end_effector=name), q_start)
    stats = _total_stats(list(searches.values()), clock() - start)
    if stats.ik_solutions:
        result = PlanResult(PlanStatus.TIMEOUT, np.zeros((0, len(q_start))), stats)
    else:
        samples = sum(search.calls for search in searches.values())
        result = PlanResult(PlanStatus.NO_GOAL_CONFIGURATION, np.zeros((0, len(q_start))), stats, info={
            "reason": f"no valid goal configuration: IK failed on all {samples} goal samples (up to "
                      f"{settings.ik_attempts} IK attempts each); the targets may be out of reach, or every "
                      "solution found collides"})
    return contexts[next(iter(samplers))].explain(result, q_start)


def _random_seed(solvers: Sequence[ChainSolver], q_ref: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """q_ref with the solvers' chain joints drawn uniformly (different IK solutions per call)."""
    q = q_ref.copy()
    for solver in solvers:
        q[solver.var_q] = rng.uniform(solver.lower, solver.upper)
    return q


def grasp_sampler(ctx: PlanningContext, solver: ChainSolver, target_poses: np.ndarray, q_ref: np.ndarray,
                  more_targets: Callable[[np.random.Generator], np.ndarray] | None = None) -> GoalSampler:
    """IK-RRT goals: one arm, any of the world tool poses (k, 4, 4) (e.g. object pose x grasps;
    positions (k, 3) for a position-only solver).

    With ``more_targets`` the first sample aims at ``target_poses`` and every later one at the
    targets ``more_targets(rng)`` returns (same kind), e.g. random poses of a goal region
    (``grasp`` is then the index in the targets of its own sample).
    """
    q_ref = ctx.check_solvers([solver], "grasp_sampler", q_ref)
    first = solver.targets(target_poses)

    def sample(rng: np.random.Generator, call: int, attempts: int, budget: float):
        # the first seed is q_ref itself: the solution nearest to it (q_ref when it reaches a pose)
        seed = q_ref if call == 0 else _random_seed([solver], q_ref, rng)
        targets = first if more_targets is None or call == 0 else solver.targets(more_targets(rng))
        settings = CompleteIKSettings(time_budget_s=max(budget, 1e-6), max_restarts=attempts)
        result = solve_ik_complete(solver, targets, seed, rng, settings, is_valid=ctx.is_usable_end)
        return (result.q, {"grasp": result.target_index}) if result.success else (None, {})

    return GoalSampler("grasp_sampler", q_ref, sample)


def dual_arm_sampler(ctx: PlanningContext, arms: Sequence[ChainSolver], target_poses: Sequence[np.ndarray],
                     q_ref: np.ndarray, free: Sequence[str] | str | None = None) -> GoalSampler:
    """Bimanual IK-RRT goals: both hands on their pose sets, free joints (e.g. the hip) sampled."""
    q_ref = ctx.check_solvers(arms, "dual_arm_sampler", q_ref, free)
    check_arm_pair(arms, "dual_arm_sampler")

    def sample(rng: np.random.Generator, call: int, attempts: int, budget: float):
        result = solve_ik_hybrid(arms, target_poses, free, _random_seed(arms, q_ref, rng), rng,
                                 HybridIKSettings(time_budget_s=max(budget, 1e-6), max_samples=attempts),
                                 is_valid=ctx.is_valid)
        return (result.q, _pair_info(result.target_indices, target_poses)) if result.success else (None, {})

    return GoalSampler("dual_arm_sampler", q_ref, sample)


def _pair_info(indices: tuple[int, int], pose_sets: Sequence[np.ndarray]) -> dict:
    """What a two-hand goal reached: ``grasps`` (i, j), the pose of each hand's set (k_a, 4, 4),
    (k_b, 4, 4), and ``grasp`` = i * k_b + j, the pair as one index."""
    sizes = tuple(len(np.reshape(poses, (-1, 4, 4))) for poses in pose_sets)
    return {"grasps": indices, "grasp": int(np.ravel_multi_index(indices, sizes))}


def regrasp_sampler(ctx: PlanningContext, arms: Sequence[ChainSolver], grasps: Sequence[np.ndarray],
                    region: ObjectRegion | None, q_ref: np.ndarray, free: Sequence[str] | str | None = None
                    ) -> GoalSampler:
    """Hand-over goals: an object pose in ``region`` (None: anywhere) where both hands hold
    their grasps (:func:`~prehensile.ik.hybrid.solve_regrasp_ik`).

    Found once here, with the joints not solved at ``q_ref``: the grasp pairs whose hands do
    not overlap (:func:`separate_grasp_pairs`) and, per arm, the reachability samples at which
    it is free of the robot (:func:`self_free_reach`).
    """
    q_ref = ctx.check_solvers(arms, "regrasp_sampler", q_ref, free)
    check_arm_pair(arms, "regrasp_sampler")
    pairs = separate_grasp_pairs(ctx, arms, grasps, q_ref)
    reach = [self_free_reach(ctx, arm, q_ref) for arm in arms]

    def sample(rng: np.random.Generator, call: int, attempts: int, budget: float):
        result, T_world_object = solve_regrasp_ik(arms, grasps, region, free, q_ref, rng,
                                                  time_budget_s=max(budget, 1e-6), pairs=pairs, reach=reach,
                                                  is_valid=ctx.is_valid, max_batches=attempts)
        if not result.success:
            return None, {}
        return result.q, {**_pair_info(result.target_indices, grasps), "T_world_object": T_world_object}

    return GoalSampler("regrasp_sampler", q_ref, sample)


def separate_grasp_pairs(ctx: PlanningContext, arms: Sequence[ChainSolver], grasps: Sequence[np.ndarray],
                         q_ref: np.ndarray | None = None) -> np.ndarray:
    """(P, 2) the grasp pairs (index per hand into ``grasps`` (k_h, 4, 4), T_object_tcp) at which
    the two hands, with what they hold, do not overlap on the sphere model of ``ctx``.

    A hand is every link (attached objects included) that no planned joint moves relative to
    the arm's tool, posed at ``q_ref`` (dof,) (default: the context's reference configuration;
    only its joints not planned matter); at a grasp pair the relative pose of the two tools is
    fixed, ``inverse(g_a) @ g_b``, so a pair whose hands overlap there fails every validity
    check and is not worth an IK attempt.
    """
    q_ref = ctx.space.q_ref if q_ref is None else q_ref
    balls = [_hand_balls(ctx, arm, q_ref) for arm in arms]
    (links_a, centers_a, radii_a), (links_b, centers_b, radii_b) = balls
    checked = ~ctx.acm[links_a[:, None], links_b[None, :]]
    grasp_sets = [arm.targets(g) for arm, g in zip(arms, grasps)]
    pairs = []
    for i, g_a in enumerate(grasp_sets[0]):
        T = invert(g_a) @ grasp_sets[1]  # (k_b, 4, 4): tool b in the frame of tool a
        centers = np.einsum("kij,nj->kni", T[:, :3, :3], centers_b) + T[:, None, :3, 3]
        gap = np.linalg.norm(centers_a[None, :, None] - centers[:, None], axis=-1) - radii_a[:, None] - radii_b
        pairs += [(i, j) for j in np.flatnonzero(~np.any((gap < 0.0) & checked, axis=(1, 2)))]
    return np.array(pairs, dtype=np.int64).reshape(-1, 2)


def self_free_reach(ctx: PlanningContext, arm: ChainSolver, q_ref: np.ndarray | None = None) -> ReachSamples:
    """The arm's reachability samples (:func:`~prehensile.ik.reach.reach_samples`) at which the
    links it moves, with their held objects, touch neither each other nor the links that no
    other planned joint moves relative to the arm's base (the body), on the sphere model with
    the other joints at ``q_ref`` (dof,) (default: the context's reference configuration).
    Obstacles, and links that other planned joints move (the other arm), are not considered:
    they are elsewhere at the goal.

    Raises:
        PrehensileError: every sample collides (the body, at q_ref, meets the arm's first links).
    """
    model, q_ref = ctx.collision_model, ctx.space.q_ref if q_ref is None else q_ref
    reach = reach_samples(arm)
    checker = SphereChecker(model, [], ctx.T_world_base, ctx.sphere_model, ctx.acm | ~_arm_pairs(ctx, arm))
    q = np.tile(q_ref, (len(reach.values), 1))
    q[:, arm.var_q] = reach.values
    free = checker.is_free(q)
    if not free.any():
        raise PrehensileError(f"self_free_reach: at every reachability sample of chain '{arm.chain.name}' its links "
                              "collide with the robot's body on the sphere model, with the other joints at q_ref; "
                              "check q_ref and the link pairs the SRDF disables")
    return reach.subset(free)


def _arm_pairs(ctx: PlanningContext, arm: ChainSolver) -> np.ndarray:
    """(L, L) bool, symmetric: the link pairs of :func:`self_free_reach`, between a link the
    arm's joints move and a link whose pose relative to the arm's base only they change."""
    model, planned = ctx.collision_model, set(ctx.space.indices.tolist())
    own = set(arm.var_q.tolist())
    below = model.variables_to_root(arm.chain.base_link)
    moving = [model.variables_to_root(link) & planned for link in range(model.n_links)]
    moved = np.array([bool(variables & own) for variables in moving])
    steady = np.array([not variables - own - below for variables in moving])
    pairs = moved[:, None] & steady[None, :]
    return pairs | pairs.T


def _hand_balls(ctx: PlanningContext, arm: ChainSolver, q_ref: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Links (B,), centres in the tool frame (B, 3) and radii (B,) of the balls rigid with the
    tool, posed at q_ref (dof,)."""
    model, planned = ctx.collision_model, set(ctx.space.indices.tolist())

    def deepest_planned(link: int) -> int:
        return next((k for k in model.path_to_root(link) if model.joint_q_index[k] in planned), -1)

    hand = deepest_planned(model.link_index(arm.chain.tip_link))
    rigid = [link for link in range(model.n_links) if deepest_planned(link) == hand]
    spheres = ctx.sphere_model
    keep = np.isin(spheres.sphere_link, rigid)
    links = spheres.sphere_link[keep]
    poses = forward_kinematics(model, q_ref, arm.T_world_root)[links]
    T_tool_link = invert(arm.tool_pose(q_ref)) @ poses
    centers = np.einsum("nij,nj->ni", T_tool_link[:, :3, :3], spheres.centers[keep]) + T_tool_link[:, :3, 3]
    return links, centers, spheres.radii[keep]
