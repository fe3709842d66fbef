"""The last steps every planner shares: shorten the path found, then certify it exactly."""

from __future__ import annotations

import numpy as np

from prehensile.clock import clock
from prehensile.planning.certify import CertifyReport, rework_certified
from prehensile.planning.context import PlanningContext
from prehensile.planning.result import PlanStatus
from prehensile.planning.shortcut import MIN_GAIN, shortened

SHORTCUT_RETRIES = 3  # shortcuts made again after one failed certification (see rework_certified)
SHORTCUT_TIME_S = 0.05  # s of random shortcut attempts per try


def finish_path(ctx: PlanningContext, path: np.ndarray, rng: np.random.Generator, shortcut_iterations: int = 100,
                certify: bool = True, resolution: float | None = None
                ) -> tuple[PlanStatus, np.ndarray, float, float, CertifyReport | None]:
    """Shortcut ``path`` (N, dof), its edges checked at ``resolution`` (m, default the
    context's), and certify the result against the exact geometry; a shortened path that fails
    is made again on covering balls, then the path as found is certified
    (:func:`~prehensile.planning.certify.rework_certified`).

    Returns:
        (SUCCESS or CERTIFICATION_FAILED, path (M >= 2, dof), shortcut time s, certification
        time s, the path's :class:`CertifyReport` or None if not ``certify``); a start that is
        its own goal (N = 1) gives the path [start, start], as
        :func:`~prehensile.planning.rrt_connect.rrt_connect` does.
    """
    start = clock()
    path = np.concatenate((path, path)) if len(path) == 1 else path

    def shorten(context: PlanningContext, edge_res: float) -> np.ndarray:
        if shortcut_iterations == 0:
            return path
        return shortened(context, path, rng, shortcut_iterations, SHORTCUT_TIME_S, edge_res, None, MIN_GAIN)

    resolution = ctx.resolution if resolution is None else resolution
    if not certify:
        return PlanStatus.SUCCESS, shorten(ctx, resolution), clock() - start, 0.0, None
    path_out, report, certify_time = rework_certified(ctx, path, shorten, resolution, SHORTCUT_RETRIES)
    status = PlanStatus.SUCCESS if report.ok else PlanStatus.CERTIFICATION_FAILED
    return status, path_out, clock() - start - certify_time, certify_time, report
