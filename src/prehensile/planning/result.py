"""Planner results: status, path and statistics (frozen dataclasses)."""

from __future__ import annotations

import enum
from dataclasses import dataclass, field

import numpy as np


class PlanStatus(enum.Enum):
    """Outcome of a planning query. Only ``SUCCESS`` carries a path."""

    SUCCESS = "success"
    TIMEOUT = "timeout"                        # budget spent without a path
    INVALID_START = "invalid_start"            # start outside the limits or in collision
    INVALID_GOAL = "invalid_goal"              # goal configuration outside the limits or in collision
    NO_GOAL_CONFIGURATION = "no_goal_configuration"  # IK found no valid goal configuration in the budget
    CERTIFICATION_FAILED = "certification_failed"    # the exact check rejected every path found


@dataclass(frozen=True)
class PlanStats:
    """Counters and timings of one planning query.

    Attributes:
        iterations: planner iterations (samples drawn).
        nodes: configurations in all trees at the end.
        collision_checks: configurations pushed through the sphere checker.
        ik_solutions: goal configurations found by IK (IK-based planners).
        plan_time_s: search time (s).
        simplify_time_s: shortcutting / smoothing time (s).
        certify_time_s: exact-model certification time (s).

    Times are wall time without numba compilation (:func:`prehensile.clock.clock`): a
    query's first call in a process does not spend its budget compiling kernels.
    """

    iterations: int = 0
    nodes: int = 0
    collision_checks: int = 0
    ik_solutions: int = 0
    plan_time_s: float = 0.0
    simplify_time_s: float = 0.0
    certify_time_s: float = 0.0

    @property
    def total_time_s(self) -> float:
        return self.plan_time_s + self.simplify_time_s + self.certify_time_s


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class PlanResult:
    """A planner's answer.

    Attributes:
        status: see :class:`PlanStatus`.
        path: (N >= 2, dof) full-model waypoints (rad or m) from start to goal, straight
            segments between them; (0, dof) unless ``status`` is SUCCESS.
        stats: :class:`PlanStats`.
        goal_index: which goal of a goal set was reached: the row of the goal configurations
            (:func:`~prehensile.planning.rrt_connect.rrt_connect`) or the target pose (J+-RRT,
            IK-RRT); for two hands the pair of poses as one index in C order (see ``info``);
            -1 if none.
        end_effector: the hand that grasps (Multi-EEF planners), "" otherwise.
        info: planner-specific extras (e.g. the grasp pair of a bimanual plan); a failure that
            an unusable start or goal explains has ``reason``, e.g. "start: joint j2 = 3.1
            outside its limits [-2.9, 2.9]" (see :attr:`blamed_ends`).
    """

    status: PlanStatus
    path: np.ndarray
    stats: PlanStats
    goal_index: int = -1
    end_effector: str = ""
    info: dict = field(default_factory=dict)

    @property
    def success(self) -> bool:
        return self.status is PlanStatus.SUCCESS

    @property
    def searched_out(self) -> bool:
        """A TIMEOUT after the search ran (iterations > 0): the start and goal were usable, so
        neither is the reason it failed."""
        return self.status is PlanStatus.TIMEOUT and self.stats.iterations > 0

    @property
    def blamed_ends(self) -> tuple[str, ...]:
        """The ends ("start", "goal") that may explain a failure: the one an INVALID status names;
        both for any other failure except :attr:`searched_out` (e.g. a TIMEOUT spent looking for
        a certified escape from an end that only the sphere model rejects); none on SUCCESS or
        NO_GOAL_CONFIGURATION (IK's failure)."""
        if self.success or self.searched_out or self.status is PlanStatus.NO_GOAL_CONFIGURATION:
            return ()
        return {PlanStatus.INVALID_START: ("start",), PlanStatus.INVALID_GOAL: ("goal",)}.get(self.status,
                                                                                           ("start", "goal"))
