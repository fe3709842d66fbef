"""Hybrid IK: sample the free joints (e.g. the hip), solve each arm, for one or two hands.

Vahrenkamp 2011 §3.3 (Alg. 4-7): a chain splits into free joints, sampled at random, and
arm chains solved by an IK solver. The thesis uses the closed-form 7-DoF ARMAR-III arm
solver; here each arm is solved by the Jacobian solver with a few random restarts
(:func:`~prehensile.ik.complete.solve_ik_complete`), which works for any arm. With one arm
this is ``SolveIkHybrid`` / ``GraspIK`` (a pose set: any pose will do); with two arms it is
the dual-arm IK of Alg. 7 (one pose set per hand, e.g. the left and right grasps of an
object). :func:`solve_regrasp_ik` is the hand-over IK (Alg. 8): the object pose is free, and
:class:`~prehensile.ik.hand_pair.HandPair` solves it together with both arms and the free
joints, seeded from sampled reachability (:func:`~prehensile.ik.reach.reach_samples`)
instead of the thesis's grids.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Callable, Sequence

import numpy as np

from prehensile.clock import clock
from prehensile.errors import PrehensileError
from prehensile.ik import kernels
from prehensile.ik.complete import CompleteIKSettings, solve_ik_complete
from prehensile.ik.hand_pair import UNBOUNDED, HandPair
from prehensile.ik.jacobian import ChainSolver, free_joint_indices
from prehensile.ik.reach import ReachSamples, reach_samples
from prehensile.ik.result import IKResult, IKStatus
from prehensile.kinematics.forward import forward_kinematics
from prehensile.settings import POSITIVE, at_least, check_fields, or_none
from prehensile.spatial.transforms import invert, rpy_to_matrix


@dataclass(frozen=True)
class HybridIKSettings:
    """Settings of :func:`solve_ik_hybrid`.

    Attributes:
        time_budget_s: wall-time budget (s).
        arm_restarts: random restarts per arm for one sample of the free joints.
        max_samples: cap on the samples of the free joints (None: only the budget limits them);
            with a cap that the budget does not cut, a seed gives the same result.
    """

    time_budget_s: float = 0.05
    arm_restarts: int = 4
    max_samples: int | None = None

    def __post_init__(self) -> None:
        check_fields(self, time_budget_s=POSITIVE, arm_restarts=at_least(0), max_samples=or_none(at_least(1)))


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
        :class:`IKResult` with ``target_indices`` the pose reached per arm; TIMEOUT (budget
        spent) or NOT_CONVERGED (``max_samples`` reached) if none. An attempt (one sample of
        the free joints) ends at the first arm that fails; a failed result reports the attempt
        that tried the most arms and, of those, came closest (its worst arm, in tolerances:
        :meth:`~prehensile.ik.jacobian.ChainSolver.miss`): ``q`` with the failing arm at its
        closest, the largest errors over the arms tried (an attempt whose first arm failed
        reports that arm's errors; both inf, and ``q`` the seed, if no arm was tried at all) and
        the target indices of the arms tried (fewer than the arms when one failed).
    """
    if len(arms) != len(targets) or not arms:
        raise PrehensileError(f"solve_ik_hybrid: {len(arms)} arms but {len(targets)} targets")
    for i, a in enumerate(arms):  # solving one arm after another must not move the ones solved
        for b in arms[i + 1:]:
            shared = np.intersect1d(a.var_q, b.var_q)
            if shared.size:
                raise PrehensileError(f"solve_ik_hybrid: arm chains '{a.chain.name}' and '{b.chain.name}' share "
                                      f"{', '.join(a.model.joint_names[j] for j in shared)}; give those as free "
                                      "joints and chains without them")
    start = clock()
    model = arms[0].model
    rng = np.random.default_rng(rng)
    poses = [arm.targets(t) for arm, t in zip(arms, targets)]
    free_q = free_joint_indices(model, arms, free)
    lower, upper = model.sampling_limits(free_q)
    q = arms[0].seed(q_seed)
    samples, iterations = 0, 0
    closest = ((len(arms), np.inf), q.copy(), np.inf, np.inf, ())  # (arms not tried, miss), q, errors, targets
    while True:
        if samples:
            q[free_q] = rng.uniform(lower, upper)
        samples += 1
        reached, errors, misses, attempt, solved = [], [], [], q, 0
        for arm, arm_targets in zip(arms, poses):
            remaining = settings.time_budget_s - (clock() - start)
            if remaining <= 0:
                break
            result = solve_ik_complete(arm, arm_targets, q, rng, CompleteIKSettings(
                time_budget_s=remaining, max_restarts=settings.arm_restarts))
            iterations += result.iterations
            attempt = result.q  # the failing arm at its closest, the arms before it solved
            reached.append(result.target_index)
            errors.append((result.position_error, result.rotation_error))
            misses.append(arm.miss(result.position_error, result.rotation_error))
            if not result.success:
                break
            q, solved = result.q, solved + 1
        untried = len(arms) - len(errors)
        pos, rot = (max((e[k] for e in errors), default=np.inf) for k in (0, 1))
        if solved == len(arms) and (is_valid is None or is_valid(q)):
            return IKResult(IKStatus.SUCCESS, q.copy(), q[None].copy(), pos, rot, iterations,
                            clock() - start, reached[0], samples - 1, tuple(reached))
        key = (untried, max(misses, default=np.inf))
        if key < closest[0]:  # a solution that is_valid rejects counts too
            closest = (key, attempt.copy(), pos, rot, tuple(reached))
        capped = settings.max_samples is not None and samples >= settings.max_samples
        if capped or clock() - start >= settings.time_budget_s:
            _, q_closest, pos, rot, reached = closest
            return IKResult(IKStatus.NOT_CONVERGED if capped else IKStatus.TIMEOUT, q_closest,
                            np.zeros((0, model.dof)), pos, rot, iterations, clock() - start,
                            reached[0] if reached else 0, samples - 1, reached)


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

    def sample(self, rng: np.random.Generator, n: int | None = None) -> np.ndarray:
        """A random world object pose (4, 4) in the region, or n of them (n, 4, 4)."""
        size = () if n is None else (n,)
        pose = np.tile(np.eye(4), size + (1, 1))
        pose[..., :3, :3] = rpy_to_matrix(rng.uniform(self.rpy_lower, self.rpy_upper, size=size + (3,)))
        pose[..., :3, 3] = rng.uniform(self.lower, self.upper, size=size + (3,))
        return pose

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(6,) lower and upper bounds of (position m, rpy rad)."""
        return np.array(self.lower + self.rpy_lower, dtype=float), np.array(self.upper + self.rpy_upper, dtype=float)


FREE_CANDIDATES = 16
"""Free-object hand-over IK: object poses drawn per attempt, before the reachability test."""


def solve_regrasp_ik(arms: Sequence[ChainSolver], grasps: Sequence[np.ndarray], region: ObjectRegion | None,
                     free: Sequence[str] | str | None = None, q_seed: np.ndarray | None = None,
                     rng: np.random.Generator | int | None = None, time_budget_s: float = 0.5, batch: int = 16,
                     is_valid: Callable[[np.ndarray], bool] | None = None, pairs: np.ndarray | None = None,
                     reach: Sequence[ReachSamples] | None = None, max_batches: int | None = None
                     ) -> tuple[IKResult, np.ndarray | None]:
    """Hand-over IK (Vahrenkamp Alg. 8): an object pose where both hands hold it.

    The thesis samples object poses, keeps those where both grasps are reachable
    (reachability grids), moves them by hill climbing on the grids (``OptimizeGraspingPose``)
    and then solves a dual-arm IK. Here an attempt draws a grasp per hand, random free joints
    and an object pose: in ``region``, or (``region`` None, object free) where the second hand
    holds it at a random reachability sample (:func:`~prehensile.ik.reach.reach_samples`) of
    its arm. A position-only reachability test rejects the attempt or seeds each arm with its
    sample nearest to its grasp pose, and :class:`~prehensile.ik.hand_pair.HandPair` then
    solves arms, free joints *and* object pose together (17 joints and 6 object coordinates
    on ARMAR-III), the object kept in the region. The first converged attempt that
    ``is_valid`` accepts is returned; attempts run ``batch`` at a time in one compiled call,
    the clock is read between calls.

    Args:
        arms: the two arm solvers (tools at the hands' TCPs).
        grasps: per arm the grasp set T_object_tcp (k, 4, 4).
        region: where the object may be; None: anywhere.
        free: further joints solved with the arms (e.g. "Torso"), seeded at random.
        q_seed: (dof,) values of every other joint; neutral if None.
        time_budget_s: wall-time budget (s).
        batch: attempts per compiled call.
        max_batches: cap on the batches of attempts (None: only the budget limits them); with
            a cap that the budget does not cut, a seed gives the same result.
        is_valid: acceptance test of a solution (dof,), e.g. a collision filter.
        pairs: (P, 2) the grasp pairs (index per hand) worth trying; all if None.
        reach: per arm the samples that seed it: :func:`~prehensile.ik.reach.reach_samples`
            (the default) or a subset (e.g. without self-collisions).

    Returns:
        (result, T_world_object (4, 4) or None); ``result.target_indices`` are the grasps,
        ``restarts`` the attempts before the accepted one. UNREACHABLE if ``pairs`` is empty,
        else TIMEOUT (budget spent) or NOT_CONVERGED (``max_batches`` tried) if none. A failed
        result reports the attempt that came closest (in tolerances, as
        :func:`~prehensile.ik.kernels.miss`; a solution that ``is_valid`` rejects counts too):
        its ``q``, the larger errors of the two hands and its grasps (the object pose is None);
        errors inf and ``q`` the seed if no attempt passed the reachability test.
    """
    start = clock()
    rng = np.random.default_rng(rng)
    pair = HandPair(arms, free)
    grasp_sets = [np.ascontiguousarray(arm.targets(g)) for arm, g in zip(arms, grasps)]
    if pairs is None:
        pairs = np.stack(np.meshgrid(*[np.arange(len(g)) for g in grasp_sets], indexing="ij"), -1).reshape(-1, 2)
    reach = [reach_samples(arm) for arm in arms] if reach is None else reach
    q0 = arms[0].seed(q_seed)
    bounds = UNBOUNDED if region is None else region.bounds()
    T_a_b = _base_offset(pair, q0) if region is None else None
    q, T = q0.copy(), np.eye(4)
    closest = (np.inf, q0, np.inf, np.inf, ())  # miss, q, errors, grasps
    attempts = iterations = batches = 0
    while len(pairs) and clock() - start < time_budget_s and (max_batches is None or batches < max_batches):
        batches += 1
        if region is None:  # held by hand b at one of its samples (in its base frame)
            chosen = pairs[rng.integers(len(pairs), size=FREE_CANDIDATES * batch)]
            tools = reach[1].poses[rng.integers(len(reach[1].poses), size=len(chosen))]
            objects = tools @ invert(grasp_sets[1][chosen[:, 1]])
            if T_a_b is not None:  # where hand a cannot be near its grasp, no IK is tried
                keep = reach[0].reachable((T_a_b @ objects @ grasp_sets[0][chosen[:, 0]])[:, :3, 3])
                attempts += len(keep) - np.count_nonzero(keep)
                objects, chosen = objects[keep][:batch], chosen[keep][:batch]
        else:
            chosen = pairs[rng.integers(len(pairs), size=batch)]
            objects = region.sample(rng, batch)
        objects, chosen = np.ascontiguousarray(objects), np.ascontiguousarray(chosen, dtype=np.int64)
        seeds = rng.uniform(pair.lower, pair.upper, size=(len(chosen), len(pair.var_q)))
        while len(seeds):
            found, nearest, its, pos_err, rot_err = pair.solve(q, T, seeds, objects, region is None, chosen,
                                                               grasp_sets, bounds, reach)
            iterations += its
            attempts += len(seeds) if found < 0 else found + 1
            if found >= 0 and (is_valid is None or is_valid(q)):
                indices = tuple(int(i) for i in chosen[found])
                return IKResult(IKStatus.SUCCESS, q.copy(), q[None].copy(), pos_err, rot_err, iterations,
                                clock() - start, indices[0], attempts - 1, indices), T.copy()
            miss = kernels.miss(pos_err, rot_err, pair.settings.position_tolerance, pair.settings.rotation_tolerance)
            if miss < closest[0]:  # q holds attempt ``nearest`` (a solution is_valid rejected, if found)
                closest = (miss, q.copy(), pos_err, rot_err, tuple(int(i) for i in chosen[nearest]))
            if found < 0:
                break
            seeds, objects, chosen = seeds[found + 1:], objects[found + 1:], chosen[found + 1:]
    status = (IKStatus.UNREACHABLE if not len(pairs) else
              IKStatus.NOT_CONVERGED if max_batches is not None and batches >= max_batches else IKStatus.TIMEOUT)
    _, q_closest, pos_err, rot_err, indices = closest
    return IKResult(status, q_closest, np.zeros((0, len(q0))), pos_err, rot_err, iterations, clock() - start,
                    indices[0] if indices else 0, attempts, indices), None


def _base_offset(pair: HandPair, q: np.ndarray) -> np.ndarray | None:
    """Pose (4, 4) of arm b's base link in arm a's, if no joint solved by ``pair`` moves one
    relative to the other (e.g. both arms on the torso, the hip solved), else None."""
    model = pair.model
    bases = [model.link_index(arm.chain.base_link) for arm in pair.arms]
    between = set(model.path_to_root(bases[0])) ^ set(model.path_to_root(bases[1]))
    if np.isin([model.joint_q_index[k] for k in between], pair.var_q).any():
        return None
    poses = forward_kinematics(model, q)[bases]
    return invert(poses[0]) @ poses[1]

