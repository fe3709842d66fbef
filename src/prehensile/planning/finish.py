"""The last steps every planner shares: shorten the path found, then certify it exactly."""

from __future__ import annotations

import numpy as np

from prehensile.clock import clock
from prehensile.planning.certify import certify_path
from prehensile.planning.context import PlanningContext
from prehensile.planning.result import PlanStatus
from prehensile.planning.shortcut import shortcut


def finish_path(ctx: PlanningContext, path: np.ndarray, rng: np.random.Generator, shortcut_iterations: int = 100,
                certify: bool = True) -> tuple[PlanStatus, np.ndarray, float, float]:
    """Shortcut ``path`` (N, dof) and certify the result against the exact geometry.

    Returns:
        (SUCCESS or CERTIFICATION_FAILED, path (M, dof), shortcut time s, certification time s).
    """
    start = clock()
    if shortcut_iterations > 0:
        path = shortcut(ctx, path, rng, iterations=shortcut_iterations)
    simplified = clock()
    ok = certify_path(ctx, path).ok if certify else True
    status = PlanStatus.SUCCESS if ok else PlanStatus.CERTIFICATION_FAILED
    return status, path, simplified - start, clock() - simplified
