"""Hybrid IK: sample the free joints (e.g. the hip), solve each arm, for one or two hands.

Vahrenkamp 2011 §3.3 (Alg. 4-7): a chain splits into free joints, sampled at random, and
arm chains solved by an IK solver. The thesis uses the closed-form 7-DoF ARMAR-III arm
solver; here each arm is solved by the Jacobian solver with a few random restarts
(:func:`~prehensile.ik.complete.solve_ik_complete`), which works for any arm. With one arm
this is ``SolveIkHybrid`` / ``GraspIK`` (a pose set: any pose will do); with two arms it is
the dual-arm IK of Alg. 7 (one pose set per hand, e.g. the left and right grasps of an
object); :func:`solve_regrasp_ik` adds a free object pose for hand-over (Alg. 8, without the
reachability grids of that section: object poses are sampled in a given region).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.ik.complete import CompleteIKSettings, solve_ik_complete
from prehensile.ik.jacobian import ChainSolver
from prehensile.ik.result import IKResult, IKStatus
from prehensile.model.robot_model import RobotModel
from prehensile.spatial.transforms import rpy_to_matrix


@dataclass(frozen=True)
class HybridIKSettings:
    """Settings of :func:`solve_ik_hybrid`.

    Attributes:
        time_budget_s: wall-time budget (s).
        arm_restarts: random restarts per arm for one sample of the free joints.
    """

    time_budget_s: float = 0.05
    arm_restarts: int = 4


def free_joint_indices(model: RobotModel, arms: Sequence[ChainSolver], free: Sequence[str] | str | None) -> np.ndarray:
    """q indices (f,) of the free joints: a chain name, joint names, or None for none."""
    if free is None:
        return np.zeros(0, dtype=np.int64)
    indices = model.chain_q_indices(free) if isinstance(free, str) else np.array(
        [model.joint_index(j) for j in free], dtype=np.int64)
    for arm in arms:
        if np.intersect1d(indices, arm.var_q).size:
            raise PrehensileError(f"free joints and arm chain '{arm.chain.name}' overlap")
    return indices


def solve_ik_hybrid(arms: Sequence[ChainSolver], targets: Sequence[np.ndarray], free: Sequence[str] | str | None = None,
                    q_seed: np.ndarray | None = None, rng: np.random.Generator | int | None = None,
                    settings: HybridIKSettings = HybridIKSettings(),
                    is_valid: Callable[[np.ndarray], bool] | None = None) -> IKResult:
    """Sample the free joints, then solve every arm for its target; repeat until all succeed.

    Args:
        arms: one solver per arm; their chains must not share joints.
        targets: per arm a world pose (4, 4) or pose set (k, 4, 4) of its tool.
        free: joints sampled at random (a chain name or joint names), e.g. the hip; the
            first sample keeps ``q_seed``'s values.
        q_seed: (dof,) start and values of every other joint; neutral if None.
        rng: random generator or seed.
        is_valid: acceptance test of the combined configuration (dof,), e.g. a collision
            filter; each arm's own solution is not tested alone (the other arm may collide).

    Returns:
        :class:`IKResult` with ``target_indices`` the pose reached per arm; TIMEOUT if none.
    """
    if len(arms) != len(targets) or not arms:
        raise PrehensileError(f"solve_ik_hybrid: {len(arms)} arms but {len(targets)} targets")
    start = time.perf_counter()
    model = arms[0].model
    rng = np.random.default_rng(rng)
    poses = [arm.targets(t) for arm, t in zip(arms, targets)]
    free_q = free_joint_indices(model, arms, free)
    lower, upper = model.lower[free_q], model.upper[free_q]
    q = arms[0].seed(q_seed)
    samples, iterations, best = 0, 0, (np.inf, np.inf)
    while True:
        if samples:
            q[free_q] = rng.uniform(lower, upper)
        samples += 1
        reached, errors = [], []
        for arm, arm_targets in zip(arms, poses):
            remaining = settings.time_budget_s - (time.perf_counter() - start)
            if remaining <= 0:
                break
            result = solve_ik_complete(arm, arm_targets, q, rng, CompleteIKSettings(
                time_budget_s=remaining, max_restarts=settings.arm_restarts))
            iterations += result.iterations
            if not result.success:
                break
            q = result.q
            reached.append(result.target_index)
            errors.append((result.position_error, result.rotation_error))
        if len(reached) == len(arms):
            best = (max(e[0] for e in errors), max(e[1] for e in errors))
            if is_valid is None or is_valid(q):
                return IKResult(IKStatus.SUCCESS, q.copy(), q[None].copy(), best[0], best[1], iterations,
                                time.perf_counter() - start, reached[0], samples - 1, tuple(reached))
        if time.perf_counter() - start >= settings.time_budget_s:
            return IKResult(IKStatus.TIMEOUT, q.copy(), np.zeros((0, model.dof)), best[0], best[1], iterations,
                            time.perf_counter() - start, 0, samples - 1)


@dataclass(frozen=True)
class ObjectRegion:
    """Where a hand-over may happen: object positions in a world box, orientations as rpy
    ranges (rad) about the world axes.

    Attributes:
        lower, upper: (3,) corners of the position box (m).
        rpy_lower, rpy_upper: (3,) roll-pitch-yaw ranges (rad).
    """

    lower: tuple[float, float, float]
    upper: tuple[float, float, float]
    rpy_lower: tuple[float, float, float] = (-np.pi, -np.pi / 2, -np.pi)
    rpy_upper: tuple[float, float, float] = (np.pi, np.pi / 2, np.pi)

    def sample(self, rng: np.random.Generator) -> np.ndarray:
        """A random world object pose (4, 4) in the region."""
        pose = np.eye(4)
        pose[:3, :3] = rpy_to_matrix(rng.uniform(self.rpy_lower, self.rpy_upper))
        pose[:3, 3] = rng.uniform(self.lower, self.upper)
        return pose


def solve_regrasp_ik(arms: Sequence[ChainSolver], grasps: Sequence[np.ndarray], region: ObjectRegion,
                     free: Sequence[str] | str | None = None, q_seed: np.ndarray | None = None,
                     rng: np.random.Generator | int | None = None, time_budget_s: float = 0.5,
                     per_pose: HybridIKSettings = HybridIKSettings(time_budget_s=0.01),
                     is_valid: Callable[[np.ndarray], bool] | None = None) -> tuple[IKResult, np.ndarray | None]:
    """Hand-over IK (Vahrenkamp Alg. 8): a free object pose where both hands can grasp it.

    Args:
        arms: the two arm solvers (tools at the hands' TCPs).
        grasps: per arm the grasp set T_object_tcp (k, 4, 4).
        region: where the object may be.
        per_pose: budget of the dual-arm IK for one sampled object pose.

    Returns:
        (result, T_world_object (4, 4) or None); ``result.target_indices`` are the grasps.
    """
    start = time.perf_counter()
    rng = np.random.default_rng(rng)
    grasp_sets = [arm.targets(g) for arm, g in zip(arms, grasps)]
    attempts, iterations = 0, 0
    while time.perf_counter() - start < time_budget_s:
        T_world_object = region.sample(rng)
        attempts += 1
        budget = min(per_pose.time_budget_s, time_budget_s - (time.perf_counter() - start))
        result = solve_ik_hybrid(arms, [T_world_object @ g for g in grasp_sets], free, q_seed, rng,
                                 HybridIKSettings(max(budget, 1e-6), per_pose.arm_restarts), is_valid)
        iterations += result.iterations
        if result.success:
            return IKResult(IKStatus.SUCCESS, result.q, result.solutions, result.position_error, result.rotation_error,
                            iterations, time.perf_counter() - start, result.target_index, attempts - 1,
                            result.target_indices), T_world_object
    q = arms[0].seed(q_seed)
    return IKResult(IKStatus.TIMEOUT, q, np.zeros((0, len(q))), np.inf, np.inf, iterations,
                    time.perf_counter() - start, 0, attempts), None
