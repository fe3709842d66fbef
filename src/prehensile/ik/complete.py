"""Probabilistically complete IK: Jacobian solves from random restarts within a time budget.

Vahrenkamp 2011, A.4.3 (Alg. 32/33): start from the given seed, then from random
configurations, until a solve converges to a configuration that is inside the limits and
collision-free, or the budget is spent. Random restarts eventually start inside the basin of
attraction of any existing solution, hence "probabilistically complete".

Choices (the thesis leaves them open):

- The thesis aborts a solve as soon as an intermediate configuration collides; here only the
  final configuration is checked (intermediate configurations are not part of any motion),
  first against the sphere model (fast, conservative) and then, if given, the exact meshes.
- Seeds are drawn and solved in batches inside one compiled call (``batch`` seeds per call;
  the clock is read between calls, so a budget can be overrun by one call: up to ``batch``
  solves of ``max_iterations`` each, milliseconds for the transpose method).
- A pose set (e.g. the grasps of an object: any one will do) is tried pose by pose from the
  caller's seed, beginning with the pose nearest to the seed's tool (a seed already at a pose
  is its own solution), then a random pose per random seed.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import numpy as np

from prehensile.clock import clock
from prehensile.ik.jacobian import ChainSolver
from prehensile.ik.result import IKResult, IKStatus
from prehensile.settings import POSITIVE, at_least, check_fields, or_none
from prehensile.spatial.transforms import rotation_error


@dataclass(frozen=True)
class CompleteIKSettings:
    """Settings of :func:`solve_ik_complete`.

    Attributes:
        time_budget_s: wall-time budget (s).
        batch: random seeds solved per compiled call.
        max_restarts: cap on random restarts (None: only the budget limits them).
    """

    time_budget_s: float = 0.005
    batch: int = 2
    max_restarts: int | None = None

    def __post_init__(self) -> None:
        check_fields(self, time_budget_s=POSITIVE, batch=at_least(1), max_restarts=or_none(at_least(0)))


def solve_ik_complete(solver: ChainSolver, target: np.ndarray, q_seed: np.ndarray | None = None,
                      rng: np.random.Generator | int | None = None,
                      settings: CompleteIKSettings = CompleteIKSettings(),
                      is_valid: Callable[[np.ndarray], bool] | None = None) -> IKResult:
    """Solve ``target`` with random restarts until a valid solution is found or time runs out.

    Args:
        solver: the chain and Jacobian settings (:class:`~prehensile.ik.jacobian.ChainSolver`).
        target: world tool pose (4, 4) or pose set (k, 4, 4); positions with ``position_only``.
        q_seed: (dof,) first start and the values of the joints outside the chain.
        rng: random generator or seed for the restarts (the same seed gives the same result).
        is_valid: acceptance test of a converged full configuration (dof,), e.g.
            :func:`collision_filter`; None accepts every converged solution.

    Returns:
        :class:`IKResult`: SUCCESS, TIMEOUT (budget spent) or NOT_CONVERGED (``max_restarts``
        reached); ``q`` is then the configuration tried that came closest to its target (in
        units of the tolerances), and the errors are its own.
    """
    start = clock()
    targets = solver.targets(target)
    q0 = solver.seed(q_seed)
    seeds = np.repeat(q0[solver.var_q][None], len(targets), axis=0)
    first_target, restarts, iterations, random_round = _nearest_target(solver, q0, targets), 0, 0, False
    closest = (np.inf, q0, np.inf, np.inf, 0)  # miss, q, position and rotation errors, target index
    while True:
        chunk = seeds[:settings.batch]  # the clock is read between calls of at most ``batch`` solves
        q, attempt, index, its, pos_err, rot_err = solver.run(q0, chunk, targets, first_target)
        iterations += its
        miss = solver.miss(pos_err, rot_err)
        if miss < closest[0]:  # a converged one that ``is_valid`` rejects counts too
            closest = (miss, q, pos_err, rot_err, index)
        done = len(chunk) if attempt < 0 else attempt + 1
        if random_round:
            restarts += done
        if attempt >= 0 and (is_valid is None or is_valid(q)):
            return _result(solver, IKStatus.SUCCESS, q, pos_err, rot_err, index, iterations, start, restarts)
        seeds, first_target = seeds[done:], (first_target + done) % len(targets)  # the rest of the round
        if not len(seeds) and settings.max_restarts is not None and restarts >= settings.max_restarts:
            return _result(solver, IKStatus.NOT_CONVERGED, *closest[1:], iterations, start, restarts)
        if clock() - start >= settings.time_budget_s:
            return _result(solver, IKStatus.TIMEOUT, *closest[1:], iterations, start, restarts)
        if len(seeds):
            continue
        if not isinstance(rng, np.random.Generator):  # created only when needed: it costs ~20 us
            rng = np.random.default_rng(rng)
        n = settings.batch if settings.max_restarts is None else min(settings.batch, settings.max_restarts - restarts)
        seeds = rng.uniform(solver.lower, solver.upper, size=(n, solver.n))
        first_target, random_round = int(rng.integers(len(targets))), True


def _nearest_target(solver: ChainSolver, q: np.ndarray, targets: np.ndarray) -> int:
    """Index of the pose of ``targets`` (k, 4, 4) nearest to the tool at q (dof,), in
    tolerances (:meth:`~prehensile.ik.jacobian.ChainSolver.miss`)."""
    if len(targets) == 1:  # spares the forward kinematics of single-pose solves
        return 0
    tool = solver.tool_pose(q)
    position = np.linalg.norm(targets[:, :3, 3] - tool[:3, 3], axis=-1)
    rotation = np.linalg.norm(rotation_error(targets[:, :3, :3], tool[:3, :3]), axis=-1)
    return int(np.argmin([solver.miss(p, r) for p, r in zip(position, rotation)]))


def _result(solver: ChainSolver, status: IKStatus, q: np.ndarray, pos_err: float, rot_err: float, index: int,
            iterations: int, start: float, restarts: int) -> IKResult:
    ok = status is IKStatus.SUCCESS
    return IKResult(status, q, q[None] if ok else np.zeros((0, solver.model.dof)), float(pos_err),
                    0.0 if solver.settings.position_only else float(rot_err), int(iterations),
                    clock() - start, int(index), restarts)


def collision_filter(sphere_checker=None, exact_checker=None) -> Callable[[np.ndarray], bool]:
    """Acceptance test for :func:`solve_ik_complete`: free on the sphere model (fast,
    conservative), then on the exact meshes; either checker may be None."""

    def is_valid(q: np.ndarray) -> bool:
        if sphere_checker is not None and not bool(sphere_checker.is_free(q)):
            return False
        return exact_checker is None or bool(exact_checker.is_free(q))

    return is_valid
