"""FK reach samples of an arm chain: where its tool can be, as a reachability stand-in.

:func:`reach_samples` runs FK on random configurations of a chain and hashes the tool poses
by position voxel; a target with no sample near it is taken as unreachable, otherwise the
nearest sample seeds the IK. The substitute here for Vahrenkamp 2011's reachability grids
(§3.2); used by the hand-over IK (:func:`~prehensile.ik.hybrid.solve_regrasp_ik`).
"""

from __future__ import annotations

import weakref
from typing import NamedTuple

import numpy as np
from numba import njit

from prehensile.ik.jacobian import ChainSolver
from prehensile.ik.kernels import chain_pose_jacobian
from prehensile.kinematics.kernels import FAST

REACH_SAMPLES, REACH_VOXEL, REACH_ROTATION_WEIGHT = 1 << 15, 0.05, 0.1
"""Reachability samples per chain, their voxel (m), and m per rad in the seed metric."""
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
    REACH_ROTATION_WEIGHT * angle``) seeds the IK (:func:`nearest_sample`)."""
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
        to_frame(frames[base], pose, out[s])
    return out


@njit(cache=True, fastmath=FAST)
def to_frame(F, T, out):
    """out (4, 4) = inverse(F) @ T for a frame F (3, 4) (rotation | translation) and a pose T (4, 4)."""
    for r in range(3):
        for c in range(4):
            s = 0.0
            for k in range(3):
                s += F[k, r] * (T[k, c] - (F[k, 3] if c == 3 else 0.0))
            out[r, c] = s
    out[3, 0], out[3, 1], out[3, 2], out[3, 3] = 0.0, 0.0, 0.0, 1.0


@njit(cache=True, fastmath=FAST)
def nearest_sample(reach, target):
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
