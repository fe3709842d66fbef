"""Hybrid IK: sample the free joints (e.g. the hip), solve each arm, for one or two hands.

Vahrenkamp 2011 §3.3 (Alg. 4-7): a chain splits into free joints, sampled at random, and
arm chains solved by an IK solver. The thesis uses the closed-form 7-DoF ARMAR-III arm
solver; here each arm is solved by the Jacobian solver with a few random restarts
(:func:`~prehensile.ik.complete.solve_ik_complete`), which works for any arm. With one arm
this is ``SolveIkHybrid`` / ``GraspIK`` (a pose set: any pose will do); with two arms it is
the dual-arm IK of Alg. 7 (one pose set per hand, e.g. the left and right grasps of an
object). :func:`solve_regrasp_ik` is the hand-over IK (Alg. 8): the object pose is free, and
:class:`HandPair` solves it together with both arms and the free joints (compiled kernels
below), seeded from sampled reachability (:func:`reach_samples`) instead of the thesis's grids.
"""

from __future__ import annotations

import time
import weakref
from dataclasses import dataclass
from typing import Callable, NamedTuple, Sequence

import numpy as np
from numba import njit

from prehensile.errors import PrehensileError
from prehensile.ik.complete import CompleteIKSettings, solve_ik_complete
from prehensile.ik.jacobian import METHODS, ChainSolver, JacobianIKSettings
from prehensile.ik.kernels import _step, chain_pose_jacobian, pose_error
from prehensile.ik.result import IKResult, IKStatus
from prehensile.kinematics.forward import forward_kinematics
from prehensile.kinematics.kernels import FAST
from prehensile.model.robot_model import RobotModel
from prehensile.spatial.transforms import invert, rpy_to_matrix


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


_UNBOUNDED = (np.full(6, -np.inf), np.full(6, np.inf))  # object bounds without a region
REACH_SAMPLES, REACH_VOXEL, REACH_ROTATION_WEIGHT = 1 << 15, 0.05, 0.1
"""Reachability samples per chain, their voxel (m), and m per rad in the seed metric."""
FREE_CANDIDATES = 16
"""Free-object hand-over IK: object poses drawn per attempt, before the reachability test."""
_reach_cache: weakref.WeakKeyDictionary = weakref.WeakKeyDictionary()


class ReachSamples(NamedTuple):
    """Tool poses of sampled configurations of one chain, hashed by position voxel.

    Attributes:
        voxel: cell edge (m).
        origin, shape: (3,) grid corner (m, base-link frame) and cells per axis.
        starts: (C + 1,) first sample of each cell (C = prod(shape), cells in C order).
        poses: (M, 4, 4) tool poses in the chain's base-link frame, sorted by cell.
        values: (M, n) the chain's joint values of each sample.
        var_q: (n,) q index of each chain joint.
        base: index of the base link on the chain's path (``ChainSolver.table``).
        near: (*shape) bool, cells with a sample in them or in one of the 26 around them.
    """

    voxel: float
    origin: np.ndarray
    shape: np.ndarray
    starts: np.ndarray
    poses: np.ndarray
    values: np.ndarray
    var_q: np.ndarray
    base: int
    near: np.ndarray

    @staticmethod
    def hashed(voxel: float, poses: np.ndarray, values: np.ndarray, var_q: np.ndarray, base: int) -> ReachSamples:
        """Samples (tool poses (M, 4, 4) in the base-link frame, joint values (M, n)) hashed by cell."""
        origin = poses[:, :3, 3].min(axis=0) - voxel
        cell3 = np.floor((poses[:, :3, 3] - origin) / voxel).astype(np.int64)
        shape = cell3.max(axis=0) + 2
        cell = np.ravel_multi_index(cell3.T, shape)
        order = np.argsort(cell, kind="stable")
        starts = np.searchsorted(cell[order], np.arange(np.prod(shape) + 1))
        occupied = np.pad((np.diff(starts) > 0).reshape(shape), 1)
        near = np.zeros(shape, dtype=bool)
        for d in np.ndindex(3, 3, 3):
            near |= occupied[d[0]:d[0] + shape[0], d[1]:d[1] + shape[1], d[2]:d[2] + shape[2]]
        return ReachSamples(voxel, origin, shape, starts, np.ascontiguousarray(poses[order]),
                            np.ascontiguousarray(values[order]), var_q, base, near)

    def subset(self, keep: np.ndarray) -> ReachSamples:
        """The samples ``keep`` (M,) bool (e.g. those free of self-collision)."""
        return self.hashed(self.voxel, self.poses[keep], self.values[keep], self.var_q, self.base)

    def reachable(self, positions: np.ndarray) -> np.ndarray:
        """(N,) bool: a sample lies in the cell of each position (N, 3) (base frame) or around it."""
        cell3 = np.floor((positions - self.origin) / self.voxel).astype(np.int64)
        inside = np.all((cell3 >= 0) & (cell3 < self.shape), axis=-1)
        out = np.zeros(len(positions), dtype=bool)
        out[inside] = self.near[tuple(cell3[inside].T)]
        return out


def reach_samples(solver: ChainSolver) -> ReachSamples:
    """Where the chain's tool can be: FK of ``REACH_SAMPLES`` random configurations (fixed
    seed), kept in memory per model, chain and tool. A target with no sample in its cell or
    the 26 around it is taken as unreachable (a position-only test, the substitute here for
    Vahrenkamp's reachability grids, §3.2); otherwise the sample nearest to it (``|Δp| +
    REACH_ROTATION_WEIGHT * angle``) seeds the IK (:func:`_nearest_sample`)."""
    key = (solver.chain.name, solver.chain.base_link, solver.chain.tip_link, solver.T_tip_tcp.tobytes())
    cache = _reach_cache.setdefault(solver.model, {})
    if key not in cache:
        model = solver.model
        base = model.path_to_root(solver.tip_link)[::-1].index(model.link_index(solver.chain.base_link))
        values = np.random.default_rng(0).uniform(solver.lower, solver.upper, size=(REACH_SAMPLES, solver.n))
        poses = _base_tool_poses(model.neutral_configuration(), values, solver.table, solver.var_of_q, solver.var_q,
                                 solver.T_tip_tcp, base)
        cache[key] = ReachSamples.hashed(REACH_VOXEL, poses, values, solver.var_q, base)
    return cache[key]


class HandPair:
    """Two arms of one model solved together, with further joints (e.g. the hip) and,
    optionally, the object pose as unknowns.

    Both tools are to sit at their grasps of one object: ``T_world_tcp[h] = T_world_object @
    grasps[h]``. A step stacks both tools' errors (12,) (each clamped to the Cartesian step)
    over the Jacobian of the joint columns ``var_q``; a free object adds six columns, its world
    twist (v, w), which moves both targets: ``δp_h = v + w × (p_h - p_object)``, ``δR_h = w``.
    The step is the pseudoinverse or damped least-squares solution (method, steps, damping,
    tolerances and caps of the first arm's :class:`~prehensile.ik.jacobian.JacobianIKSettings`);
    joints stay in their limits, the object in its bounds (position box, rpy ranges).

    Args:
        arms: two :class:`ChainSolver` of one model with one root pose.
        free: further joints solved with the arms: a chain name, joint names, or None.
        settings: Jacobian settings of the joint solve (full poses); the first arm's if None.
    """

    def __init__(self, arms: Sequence[ChainSolver], free: Sequence[str] | str | None = None,
                 settings: JacobianIKSettings | None = None) -> None:
        if len(arms) != 2:
            raise PrehensileError(f"HandPair: expected two arm solvers, got {len(arms)}")
        a, b = arms
        if a.model is not b.model or not np.array_equal(a.T_world_root, b.T_world_root):
            raise PrehensileError("HandPair: both arms must belong to one model with one root pose")
        self.arms, self.model, self.settings = (a, b), a.model, a.settings if settings is None else settings
        if self.settings.position_only:
            raise PrehensileError("HandPair: grasps are full poses; the settings must not be position_only")
        extra = free_joint_indices(a.model, arms, free)
        self.var_q = np.array(list(dict.fromkeys([*a.var_q, *b.var_q, *extra])), dtype=np.int64)
        """(n,) q index of each joint column."""
        self.var_of_q = np.full(a.model.dof, -1, dtype=np.int64)
        self.var_of_q[self.var_q] = np.arange(len(self.var_q))
        lower, upper = a.model.lower[self.var_q], a.model.upper[self.var_q]
        self.lower = np.where(np.isfinite(lower), lower, -np.pi)
        self.upper = np.where(np.isfinite(upper), upper, np.pi)
        s = self.settings
        self._kernel_args = (a.table, b.table, self.var_of_q, self.var_q, a.T_world_root,
                             np.ascontiguousarray([a.T_tip_tcp, b.T_tip_tcp]), self.lower, self.upper)
        self._step_args = (s.max_step_position, s.max_step_rotation, METHODS[s.method], s.damping)

    def poses(self, q: np.ndarray) -> np.ndarray:
        """World poses (*batch, 2, 4, 4) of both tools for q (*batch, dof)."""
        return np.stack([arm.tool_pose(q) for arm in self.arms], axis=-3)

    def step(self, q: np.ndarray, T_world_object: np.ndarray, grasps: np.ndarray, free_object: bool
             ) -> tuple[np.ndarray, np.ndarray, float, float]:
        """One step from q (dof,) toward ``T_world_object @ grasps[h]`` (grasps (2, 4, 4)), the
        object pose moving too if ``free_object`` (without bounds).

        Returns:
            (q' (dof,), object pose' (4, 4), largest position error (m) and rotation error
            (rad) of the two tools at q, before the step).
        """
        q, T = np.array(q, dtype=float), np.array(T_world_object, dtype=float)
        pos_err, rot_err = _hands_step(q, T, np.ascontiguousarray(grasps, dtype=float), *self._kernel_args,
                                       free_object, *_UNBOUNDED, *self._step_args)
        return q, T, pos_err, rot_err

    def solve(self, q: np.ndarray, T_world_object: np.ndarray, seeds: np.ndarray, objects: np.ndarray,
              relative: bool, chosen: np.ndarray, grasp_sets: Sequence[np.ndarray],
              bounds: tuple[np.ndarray, np.ndarray], reach: Sequence[ReachSamples]) -> tuple[int, int, float, float]:
        """Solve the attempts in turn (compiled) until one converges, object pose free.

        Attempt r starts from the joint values ``seeds[r]`` (n,), except that each arm starts
        from its sample in ``reach[h]`` (:func:`reach_samples`) nearest to its target (the
        attempt is skipped if a target is out of reach), the object pose ``objects[r]`` (4, 4)
        (in the world, or if ``relative`` in the frame of arm b's base link) and the grasps
        ``chosen[r]`` (2,) (indices into the sets ``grasp_sets`` (k_h, 4, 4)).

        Args:
            q, T_world_object: (dof,) and (4, 4) outputs; ``q`` holds the other joints' values.

        Returns:
            (converged attempt or -1, iterations, position error m, rotation error rad).
        """
        s = self.settings
        return _hands_restarts(q, T_world_object, seeds, objects, relative, chosen, grasp_sets[0], grasp_sets[1],
                               reach[0], reach[1], *self._kernel_args,
                               bounds[0], bounds[1], *self._step_args, s.position_tolerance, s.rotation_tolerance,
                               s.iteration_cap, s.stall_cap)


def solve_regrasp_ik(arms: Sequence[ChainSolver], grasps: Sequence[np.ndarray], region: ObjectRegion | None,
                     free: Sequence[str] | str | None = None, q_seed: np.ndarray | None = None,
                     rng: np.random.Generator | int | None = None, time_budget_s: float = 0.5, batch: int = 16,
                     is_valid: Callable[[np.ndarray], bool] | None = None, pairs: np.ndarray | None = None,
                     reach: Sequence[ReachSamples] | None = None) -> tuple[IKResult, np.ndarray | None]:
    """Hand-over IK (Vahrenkamp Alg. 8): an object pose where both hands hold it.

    The thesis samples object poses, keeps those where both grasps are reachable
    (reachability grids), moves them by hill climbing on the grids (``OptimizeGraspingPose``)
    and then solves a dual-arm IK. Here an attempt draws a grasp per hand, random free joints
    and an object pose: in ``region``, or (``region`` None, object free) where the second hand
    holds it at a random reachability sample (:func:`reach_samples`) of its arm. A
    position-only reachability test rejects the attempt or seeds each arm with its sample
    nearest to its grasp pose, and :class:`HandPair` then solves arms, free joints *and* object
    pose together (17 joints and 6 object coordinates on ARMAR-III), the object kept in the
    region. The first converged attempt that ``is_valid`` accepts is returned; attempts run
    ``batch`` at a time in one compiled call, the clock is read between calls.

    Args:
        arms: the two arm solvers (tools at the hands' TCPs).
        grasps: per arm the grasp set T_object_tcp (k, 4, 4).
        region: where the object may be; None: anywhere.
        free: further joints solved with the arms (e.g. "Torso"), seeded at random.
        q_seed: (dof,) values of every other joint; neutral if None.
        time_budget_s: wall-time budget (s).
        batch: attempts per compiled call.
        is_valid: acceptance test of a solution (dof,), e.g. a collision filter.
        pairs: (P, 2) the grasp pairs (index per hand) worth trying; all if None.
        reach: per arm the samples that seed it: :func:`reach_samples` (the default) or a
            subset (e.g. without self-collisions).

    Returns:
        (result, T_world_object (4, 4) or None); ``result.target_indices`` are the grasps,
        ``restarts`` the attempts before the accepted one. UNREACHABLE if ``pairs`` is empty.
    """
    start = time.perf_counter()
    rng = np.random.default_rng(rng)
    pair = HandPair(arms, free)
    grasp_sets = [np.ascontiguousarray(arm.targets(g)) for arm, g in zip(arms, grasps)]
    if pairs is None:
        pairs = np.stack(np.meshgrid(*[np.arange(len(g)) for g in grasp_sets], indexing="ij"), -1).reshape(-1, 2)
    reach = [reach_samples(arm) for arm in arms] if reach is None else reach
    q0 = arms[0].seed(q_seed)
    bounds = _UNBOUNDED if region is None else region.bounds()
    T_a_b = _base_offset(pair, q0) if region is None else None
    q, T = q0.copy(), np.eye(4)
    attempts = iterations = 0
    while len(pairs) and time.perf_counter() - start < time_budget_s:
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
            found, its, pos_err, rot_err = pair.solve(q, T, seeds, objects, region is None, chosen, grasp_sets,
                                                      bounds, reach)
            iterations += its
            attempts += len(seeds) if found < 0 else found + 1
            if found < 0:
                break
            if is_valid is None or is_valid(q):
                indices = tuple(int(i) for i in chosen[found])
                return IKResult(IKStatus.SUCCESS, q.copy(), q[None].copy(), pos_err, rot_err, iterations,
                                time.perf_counter() - start, indices[0], attempts - 1, indices), T.copy()
            seeds, objects, chosen = seeds[found + 1:], objects[found + 1:], chosen[found + 1:]
    status = IKStatus.TIMEOUT if len(pairs) else IKStatus.UNREACHABLE
    return IKResult(status, q0, np.zeros((0, len(q0))), np.inf, np.inf, iterations, time.perf_counter() - start, 0,
                    attempts), None


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


@njit(cache=True, fastmath=FAST)
def _base_tool_poses(q0, values, table, var_of_q, var_q, T_tip_tcp, base):
    """(M, 4, 4) tool poses in the frame of link ``base`` (index on the chain path) for the
    chain joint values ``values`` (M, n), the other joints at q0 (dof,)."""
    q, out = q0.copy(), np.empty((values.shape[0], 4, 4))
    frames, pose, jac = np.empty((table.shape[0], 3, 4)), np.empty((4, 4)), np.empty((6, var_q.shape[0]))
    for s in range(values.shape[0]):
        for c in range(var_q.shape[0]):
            q[var_q[c]] = values[s, c]
        chain_pose_jacobian(q, np.eye(4), table, var_of_q, T_tip_tcp, frames, pose, jac)
        _to_frame(frames[base], pose, out[s])
    return out


@njit(cache=True, fastmath=FAST)
def _to_frame(F, T, out):
    """out (4, 4) = inverse(F) @ T for a frame F (3, 4) (rotation | translation) and a pose T (4, 4)."""
    for r in range(3):
        for c in range(4):
            s = 0.0
            for k in range(3):
                s += F[k, r] * (T[k, c] - (F[k, 3] if c == 3 else 0.0))
            out[r, c] = s
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@njit(cache=True, fastmath=FAST)
def _nearest_sample(reach, target):
    """Index of the sample of ``reach`` (:class:`ReachSamples`) nearest to ``target`` (4, 4,
    base frame) among the cells around it, -1 if they are empty."""
    voxel, origin, shape, starts, poses = reach.voxel, reach.origin, reach.shape, reach.starts, reach.poses
    best, best_d = -1, np.inf
    cell = np.floor((target[:3, 3] - origin) / voxel).astype(np.int64)
    for i in range(max(cell[0] - 1, 0), min(cell[0] + 2, shape[0])):
        for j in range(max(cell[1] - 1, 0), min(cell[1] + 2, shape[1])):
            for k in range(max(cell[2] - 1, 0), min(cell[2] + 2, shape[2])):
                c = (i * shape[1] + j) * shape[2] + k
                for s in range(starts[c], starts[c + 1]):
                    trace = 0.0
                    for a in range(3):
                        for b in range(3):
                            trace += poses[s, a, b] * target[a, b]
                    d = np.sqrt((poses[s, 0, 3] - target[0, 3]) ** 2 + (poses[s, 1, 3] - target[1, 3]) ** 2
                                + (poses[s, 2, 3] - target[2, 3]) ** 2)
                    d += REACH_ROTATION_WEIGHT * np.arccos(min(max(0.5 * (trace - 1.0), -1.0), 1.0))
                    if d < best_d:
                        best, best_d = s, d
    return best


@njit(cache=True, fastmath=FAST)
def _hands_error(q, T_o, grasps, table_a, table_b, var_of_q, T_world_root, tcp, frames_a, frames_b, poses, jac, err,
                 target):
    """Both tools' poses ``poses`` (2, 4, 4), Jacobians ``jac`` (2, 6, n) and errors ``err``
    (12,) toward ``T_o @ grasps[h]`` (``target`` (4, 4) scratch); returns the largest position
    (m) and rotation (rad) error."""
    chain_pose_jacobian(q, T_world_root, table_a, var_of_q, tcp[0], frames_a, poses[0], jac[0])
    chain_pose_jacobian(q, T_world_root, table_b, var_of_q, tcp[1], frames_b, poses[1], jac[1])
    pos, rot = 0.0, 0.0
    for h in range(2):
        _compose(T_o, grasps[h], target)
        e = err[6 * h:6 * h + 6]
        pose_error(target, poses[h], e)
        pos = max(pos, np.sqrt(e[0] ** 2 + e[1] ** 2 + e[2] ** 2))
        rot = max(rot, np.sqrt(e[3] ** 2 + e[4] ** 2 + e[5] ** 2))
    return pos, rot


@njit(cache=True, fastmath=FAST)
def _compose(A, B, out):
    """out (4, 4) = A @ B for poses A, B (4, 4)."""
    for r in range(3):
        for c in range(4):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c] + (A[r, 3] if c == 3 else 0.0)
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@njit(cache=True, fastmath=FAST)
def _hands_update(q, T_o, grasps, jac, err, var_q, lower, upper, lo, hi, max_step_pos, max_step_rot, method, damping,
                  Jw, A, x, dx):
    """Move q (dof,) and, if ``Jw`` (12, n + 6) has object columns, T_o (4, 4) in place by one
    step toward err (12,); ``Jw``, ``A`` (12, 12), ``x`` (12,), ``dx`` (cols,) are scratch."""
    n = var_q.shape[0]
    for k in range(4):  # clamp each tool's position and rotation error
        limit = max_step_pos if k % 2 == 0 else max_step_rot
        norm = np.sqrt(err[3 * k] ** 2 + err[3 * k + 1] ** 2 + err[3 * k + 2] ** 2)
        if norm > limit:
            for r in range(3 * k, 3 * k + 3):
                err[r] *= limit / norm
    Jw[:, :] = 0.0
    Jw[:6, :n] = jac[0]
    Jw[6:, :n] = jac[1]
    if Jw.shape[1] > n:  # the targets move with the object: -[[I, -[r]x], [0, I]] per tool
        for h in range(2):
            r0, r1, r2 = (T_o[0, 0] * grasps[h, 0, 3] + T_o[0, 1] * grasps[h, 1, 3] + T_o[0, 2] * grasps[h, 2, 3],
                          T_o[1, 0] * grasps[h, 0, 3] + T_o[1, 1] * grasps[h, 1, 3] + T_o[1, 2] * grasps[h, 2, 3],
                          T_o[2, 0] * grasps[h, 0, 3] + T_o[2, 1] * grasps[h, 1, 3] + T_o[2, 2] * grasps[h, 2, 3])
            for i in range(3):
                Jw[6 * h + i, n + i] = -1.0
                Jw[6 * h + 3 + i, n + 3 + i] = -1.0
            Jw[6 * h, n + 4], Jw[6 * h, n + 5] = -r2, r1
            Jw[6 * h + 1, n + 3], Jw[6 * h + 1, n + 5] = r2, -r0
            Jw[6 * h + 2, n + 3], Jw[6 * h + 2, n + 4] = -r1, r0
    _step(method, Jw, err, damping, A, x, dx)
    blocked = False  # joints at a limit that the step pushes further out drop out of this step
    for c in range(n):
        if (q[var_q[c]] <= lower[c] and dx[c] < 0.0) or (q[var_q[c]] >= upper[c] and dx[c] > 0.0):
            blocked = True
            Jw[:, c] = 0.0
    if blocked:
        _step(method, Jw, err, damping, A, x, dx)
    for c in range(n):
        q[var_q[c]] = min(max(q[var_q[c]] + dx[c], lower[c]), upper[c])
    if Jw.shape[1] > n:
        _move_object(T_o, dx[n:], lo, hi)


@njit(cache=True, fastmath=FAST)
def _move_object(T, twist, lo, hi):
    """T (4, 4) moved by the world twist (v, w) (6,) (Rodrigues), then held in the bounds (6,)
    of (position, rpy): the position clipped to its box; rpy, where outside, clipped."""
    wx, wy, wz = twist[3], twist[4], twist[5]
    angle = np.sqrt(wx * wx + wy * wy + wz * wz)
    if angle > 0.0:
        x, y, z = wx / angle, wy / angle, wz / angle
        c, s = np.cos(angle), np.sin(angle)
        t = 1.0 - c
        R = ((t * x * x + c, t * x * y - s * z, t * x * z + s * y),
             (t * x * y + s * z, t * y * y + c, t * y * z - s * x),
             (t * x * z - s * y, t * y * z + s * x, t * z * z + c))
        for col in range(3):
            a, b, d = T[0, col], T[1, col], T[2, col]
            for r in range(3):
                T[r, col] = R[r][0] * a + R[r][1] * b + R[r][2] * d
    for r in range(3):
        T[r, 3] = min(max(T[r, 3] + twist[r], lo[r]), hi[r])
    rpy = (np.arctan2(T[2, 1], T[2, 2]), np.arctan2(-T[2, 0], np.hypot(T[0, 0], T[1, 0])), np.arctan2(T[1, 0], T[0, 0]))
    roll, pitch, yaw = min(max(rpy[0], lo[3]), hi[3]), min(max(rpy[1], lo[4]), hi[4]), min(max(rpy[2], lo[5]), hi[5])
    if (roll, pitch, yaw) != rpy:
        cr, cp, cy = np.cos(roll), np.cos(pitch), np.cos(yaw)
        sr, sp, sy = np.sin(roll), np.sin(pitch), np.sin(yaw)
        T[0, 0], T[0, 1], T[0, 2] = cy * cp, cy * sp * sr - sy * cr, cy * sp * cr + sy * sr
        T[1, 0], T[1, 1], T[1, 2] = sy * cp, sy * sp * sr + cy * cr, sy * sp * cr - cy * sr
        T[2, 0], T[2, 1], T[2, 2] = -sp, cp * sr, cp * cr


@njit(cache=True)
def _hands_step(q, T_o, grasps, table_a, table_b, var_of_q, var_q, T_world_root, tcp, lower, upper, free_object, lo,
                hi, max_step_pos, max_step_rot, method, damping):
    """One step of :meth:`HandPair.step` in place; returns the errors before it."""
    n = var_q.shape[0]
    cols = n + 6 if free_object else n
    poses, jac, err, target = np.empty((2, 4, 4)), np.empty((2, 6, n)), np.empty(12), np.empty((4, 4))
    frames_a, frames_b = np.empty((table_a.shape[0], 3, 4)), np.empty((table_b.shape[0], 3, 4))
    pos, rot = _hands_error(q, T_o, grasps, table_a, table_b, var_of_q, T_world_root, tcp, frames_a, frames_b,
                            poses, jac, err, target)
    _hands_update(q, T_o, grasps, jac, err, var_q, lower, upper, lo, hi, max_step_pos, max_step_rot, method, damping,
                  np.empty((12, cols)), np.empty((12, 12)), np.empty(12), np.empty(cols))
    return pos, rot


@njit(cache=True)
def _hands_restarts(q, T_o, seeds, objects, relative, chosen, grasps_a, grasps_b, reach_a, reach_b, table_a, table_b,
                    var_of_q, var_q, T_world_root, tcp, lower, upper, lo, hi, max_step_pos, max_step_rot, method,
                    damping, tol_pos, tol_rot, max_iterations, stall_iterations):
    """:meth:`HandPair.solve`: each attempt iterates steps until both tools are within the
    tolerances (converged), the iteration cap, or ``stall_iterations`` without a 0.1% gain."""
    n = var_q.shape[0]
    poses, jac, err, target = np.empty((2, 4, 4)), np.empty((2, 6, n)), np.empty(12), np.empty((4, 4))
    frames_a, frames_b = np.empty((table_a.shape[0], 3, 4)), np.empty((table_b.shape[0], 3, 4))
    Jw, A, x, dx = np.empty((12, n + 6)), np.empty((12, 12)), np.empty(12), np.empty(n + 6)
    grasps, local = np.empty((2, 4, 4)), np.empty((4, 4))
    total, pos, rot = 0, np.inf, np.inf
    for a in range(seeds.shape[0]):
        for c in range(n):
            q[var_q[c]] = seeds[a, c]
        grasps[0], grasps[1] = grasps_a[chosen[a, 0]], grasps_b[chosen[a, 1]]
        chain_pose_jacobian(q, T_world_root, table_a, var_of_q, tcp[0], frames_a, poses[0], jac[0])
        chain_pose_jacobian(q, T_world_root, table_b, var_of_q, tcp[1], frames_b, poses[1], jac[1])
        if relative:  # objects[a] is in the frame of arm b's base link
            base = frames_b[reach_b.base]
            for r in range(3):
                for c in range(4):
                    T_o[r, c] = (base[r, 0] * objects[a, 0, c] + base[r, 1] * objects[a, 1, c]
                                 + base[r, 2] * objects[a, 2, c] + (base[r, 3] if c == 3 else 0.0))
            T_o[3, :] = objects[a, 3]
        else:
            T_o[:, :] = objects[a]
        reachable = True
        for reach, frames, h in ((reach_a, frames_a, 0), (reach_b, frames_b, 1)):
            _compose(T_o, grasps[h], target)
            _to_frame(frames[reach.base], target, local)
            s = _nearest_sample(reach, local)
            if s < 0:
                reachable = False
                break
            for c in range(reach.var_q.shape[0]):
                q[reach.var_q[c]] = reach.values[s, c]
        if not reachable:
            continue
        best, since_best = np.inf, 0
        for it in range(max_iterations + 1):
            pos, rot = _hands_error(q, T_o, grasps, table_a, table_b, var_of_q, T_world_root, tcp, frames_a,
                                    frames_b, poses, jac, err, target)
            if pos <= tol_pos and rot <= tol_rot:
                return a, total + it, pos, rot
            score = pos / tol_pos + rot / tol_rot
            if score < 0.999 * best:
                best, since_best = score, 0
            else:
                since_best += 1
            if since_best >= stall_iterations or it == max_iterations:
                break
            _hands_update(q, T_o, grasps, jac, err, var_q, lower, upper, lo, hi, max_step_pos, max_step_rot, method,
                          damping, Jw, A, x, dx)
        total += it
    return -1, total, pos, rot
