"""The peer planner: OMPL's RRT-Connect (C++, through its Python bindings) with our checker.

What OMPL gets, so that the comparison measures the planners and not the problem setup:

- **Space**: a ``RealVectorStateSpace`` of the planned joints with the same limits as our
  :class:`~prehensile.planning.cspace.ConfigurationSpace` (unbounded joints get +-pi there
  and here, widened to a start or goal beyond). OMPL's own metric (Euclidean in joint space)
  and its default range (20 % of the space's extent) are left as OMPL chooses them.
- **State validity**: our :class:`~prehensile.collision.sphere_checker.SphereChecker`,
  called once per state from C++ through a Python callback that copies the state into a
  configuration and runs the compiled test with its arrays bound once
  (:meth:`~prehensile.collision.sphere_checker.SphereChecker.single_test`). The callback
  costs some microseconds per state (half of what ``is_free`` on one configuration costs);
  :func:`validity_call_seconds` measures it so reports can say how much of OMPL's time it is.
- **Motion validation**: OMPL's ``DiscreteMotionValidator`` with a resolution giving the same
  guarantee as ours. We space checks ``resolution`` m apart in the workspace-weighted distance
  ``sum_i w_i |dq_i|`` (no surface point moves more than that between checks). Since
  ``sum_i w_i |dq_i| <= |w|_2 |dq|_2``, Euclidean steps of ``resolution / |w|_2`` rad keep the
  same bound; OMPL takes it as a fraction of the space's maximum extent. On random segments of
  the Panda this checks about 1.45x more states per segment than our spacing does (the price of
  OMPL's Euclidean metric, not a handicap we add).
- **Simplification**: ``SimpleSetup.simplifySolution()`` with its default (no duration:
  ``PathSimplifier::simplifyMax`` -- vertex reduction, shortcutting, B-spline smoothing,
  repeated while it improves), which is what a user of OMPL gets by default.
- **Start and goal** are checked first; if the spheres reject either, the peer returns
  INVALID_START / INVALID_GOAL at once (OMPL's RRT-Connect would spend the whole budget
  sampling for a valid goal). OMPL has no counterpart of our planner's exactly certified escape
  from endpoints that only the conservative balls reject, so such problems count as unsolved.
- **Seed**: OMPL seeds every planner's generator from one process-wide seed that can only be
  set before the first OMPL generator exists (``ompl.util.RNG.setSeed``); the first call here
  sets it to ``seed + 1`` (OMPL rejects 0). Runs in the same order with the same seed sample
  the same states.

Planning time is the wall time of ``solve`` (search) plus ``simplifySolution``, as for ours.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from prehensile.collision.sphere_checker import SphereChecker
from prehensile.errors import PrehensileError
from prehensile.planning.cspace import ConfigurationSpace
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus

_SEED: list[int] = []  # the process-wide OMPL seed once set


OMPL_LONGEST_BUDGET_S = 1e9
"""s: OMPL's deadline (the clock's nanoseconds since 1970 plus the budget, 64-bit) overflows
for budgets above about 7e9 s, and the solve then ends at once."""


@dataclass(frozen=True)
class OMPLSettings:
    """Settings of the OMPL peer.

    Attributes:
        time_budget_s: search time limit (s), at most :data:`OMPL_LONGEST_BUDGET_S` of it
            used; simplification is not limited.
        resolution: largest surface displacement between two checked states of a motion (m),
            the meaning our planner gives it; converted to OMPL's Euclidean segment length.
        simplify: run OMPL's default simplifier on a found path.
    """

    time_budget_s: float = 1.0
    resolution: float = 0.005
    simplify: bool = True


def _ompl():
    try:
        from ompl import base as ob
        from ompl import geometric as og
        from ompl import util as ou
    except ImportError:
        raise PrehensileError("the OMPL peer needs OMPL's Python bindings: pip install 'ompl>=2.0'") from None
    return ob, og, ou


def seed_ompl(seed: int) -> int:
    """Set OMPL's process-wide seed to ``seed + 1`` on the first call; returns the seed in use."""
    _, _, ou = _ompl()
    if not _SEED:
        ou.RNG.setSeed(int(seed) + 1)
        _SEED.append(int(seed) + 1)
    return _SEED[0]


def segment_fraction(space: ConfigurationSpace, resolution: float, lower: np.ndarray, upper: np.ndarray) -> float:
    """OMPL's longest valid segment for ``resolution`` m as a fraction of the extent of the
    bounds ``lower``, ``upper`` (n,) of its state space."""
    step = resolution / float(np.linalg.norm(space.weights))
    return step / float(np.linalg.norm(upper - lower))


def ompl_rrt_connect(space: ConfigurationSpace, checker: SphereChecker, q_start: np.ndarray, q_goal: np.ndarray,
                     settings: OMPLSettings = OMPLSettings(), seed: int = 0) -> PlanResult:
    """Plan from q_start (dof,) to q_goal (dof,) or any goal of a set (k, dof) with OMPL's
    RRT-Connect and our sphere checker.

    Args:
        space: the planned joints, their limits and metric; the other joints stay at ``space.q_ref``.
        checker: validity of full configurations.
        q_start, q_goal: full configurations (rad or m); only the planned joints are used. Goals
            the spheres reject are left out of a goal set (OMPL's ``GoalStates``).
        settings: see :class:`OMPLSettings`.
        seed: OMPL's process-wide seed (see :func:`seed_ompl`).

    Returns:
        :class:`PlanResult` with the (simplified) path as full configurations (N, dof); stats
        count validity calls as ``collision_checks`` and the final path's vertices as ``nodes``.
    """
    ob, og, ou = _ompl()
    seed_ompl(seed)
    ou.setLogLevel(ou.LOG_ERROR)
    ends = space.full(np.concatenate([space.active(q_start)[None], space.active(q_goal).reshape(-1, space.n)]))
    free = checker.is_free(ends) & space.model.within_limits(ends)
    if not free[0] or not free[1:].any():  # OMPL would spend its whole budget sampling for a valid goal
        status = PlanStatus.INVALID_START if not free[0] else PlanStatus.INVALID_GOAL
        return PlanResult(status, np.zeros((0, space.model.dof)), PlanStats(collision_checks=len(ends)))
    n = space.n
    state_space = ob.RealVectorStateSpace(n)
    bounds = ob.RealVectorBounds(n)
    # an unbounded (continuous) joint is sampled in one turn around the start, and its goal is
    # taken within pi of the start, as ours does
    active = space.active(ends[free])
    active[1:] = space.nearest_turn(active[1:], active[0])
    lower, upper = space.sampling_bounds(active[0])
    lower, upper = np.minimum(lower, active[1:].min(axis=0)), np.maximum(upper, active[1:].max(axis=0))
    for k in range(n):
        bounds.setLow(k, float(lower[k]))
        bounds.setHigh(k, float(upper[k]))
    state_space.setBounds(bounds)
    setup = og.SimpleSetup(state_space)
    q = np.array(space.q_ref, dtype=float)
    indices = [int(i) for i in space.indices]
    calls = [0]
    free = checker.single_test()

    def is_valid(state) -> bool:
        calls[0] += 1
        for k, i in enumerate(indices):
            q[i] = state[k]
        return free(q)

    setup.setStateValidityChecker(is_valid)
    info = setup.getSpaceInformation()
    info.setStateValidityCheckingResolution(segment_fraction(space, settings.resolution, lower, upper))
    start, goal = state_space.allocState(), ob.GoalStates(info)
    for k in range(n):
        start[k] = float(active[0, k])
    setup.setStartState(start)
    for row in active[1:]:
        state = state_space.allocState()
        for k in range(n):
            state[k] = float(row[k])
        goal.addState(state)
    setup.setGoal(goal)
    setup.setPlanner(og.RRTConnect(info))
    setup.setup()
    t0 = time.perf_counter()
    status = setup.solve(min(float(settings.time_budget_s), OMPL_LONGEST_BUDGET_S))
    t1 = time.perf_counter()
    solved = status == ob.PlannerStatus.EXACT_SOLUTION and setup.haveExactSolutionPath()
    if solved and settings.simplify:
        setup.simplifySolution()
    t2 = time.perf_counter()
    path = np.zeros((0, space.model.dof))
    if solved:
        solution = setup.getSolutionPath()
        states = [solution.getState(k) for k in range(solution.getStateCount())]
        path = space.full(np.array([[s[k] for k in range(n)] for s in states], dtype=float))
    stats = PlanStats(nodes=len(path), collision_checks=calls[0], plan_time_s=t1 - t0,
                      simplify_time_s=(t2 - t1) if solved else 0.0)
    return PlanResult(_status(ob, status) if not solved else PlanStatus.SUCCESS, path, stats)


def _status(ob, status) -> PlanStatus:
    """Our status for an OMPL planner status without an exact solution."""
    if status == ob.PlannerStatus.INVALID_START:
        return PlanStatus.INVALID_START
    if status == ob.PlannerStatus.INVALID_GOAL:
        return PlanStatus.INVALID_GOAL
    return PlanStatus.TIMEOUT


def validity_call_seconds(checker: SphereChecker, q: np.ndarray, repeats: int = 2000) -> float:
    """Mean time (s) of the peer's compiled test of one configuration q (dof,)
    (:meth:`SphereChecker.single_test`), the cost OMPL pays per state on top of its own work
    and the state's copy."""
    q, free = np.array(q, dtype=float), checker.single_test()
    free(q)
    start = time.perf_counter()
    for _ in range(repeats):
        free(q)
    return (time.perf_counter() - start) / repeats
