"""Jacobian IK: transpose, pseudoinverse and damped least squares on any chain of any model.

Bischoff 2016 §3.1-3.3 and Vahrenkamp 2011 A.4 (``MoveTCP``). Each iteration computes the
tool pose and its world-axes Jacobian J (6, n), the error e (position in m over the rotation
vector in rad), clamps e to a Cartesian step (Vahrenkamp's ``LimitCartesianStepSize``), and
steps the chain joints by

- ``transpose``: :math:`\\Delta q = \\alpha J^T e` with Buss's step
  :math:`\\alpha = \\langle e, J J^T e\\rangle / \\langle J J^T e, J J^T e\\rangle`;
- ``pinv``: :math:`\\Delta q = J^+ e` from the SVD (the right pseudoinverse, not the
  thesis's :math:`(J^T J)^{-1} J^T`, which is singular for a redundant arm);
- ``dls``: :math:`\\Delta q = J^T (J J^T + \\lambda^2 I)^{-1} e` with the damping grown with
  the error, :math:`\\lambda^2 = |e|^2 + \\lambda_0^2` (Sugihara 2011): near the target it is
  the pseudoinverse, far away or near singularities a cautious gradient step.

Joint limits are enforced after every step by clamping. A solve ends converged (both
tolerances met), at the iteration cap, or when the error stops improving (stalled against a
limit or a singularity); random restarts (:mod:`prehensile.ik.complete`) take it from there.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Sequence

import numpy as np

from prehensile.clock import clock
from prehensile.errors import PrehensileError
from prehensile.ik import kernels
from prehensile.ik.result import IKResult, IKStatus, check_target_poses, check_target_positions
from prehensile.kinematics.forward import link_pose
from prehensile.model.builder import resolve_chain
from prehensile.model.robot_model import Chain, RobotModel
from prehensile.settings import FINITE_NON_NEGATIVE, FINITE_POSITIVE, at_least, check_fields, or_none

METHODS = {"transpose": kernels.TRANSPOSE, "pinv": kernels.PSEUDOINVERSE, "dls": kernels.DAMPED}


@dataclass(frozen=True)
class JacobianIKSettings:
    """Settings of the Jacobian solvers.

    Attributes:
        method: "transpose", "pinv" or "dls".
        position_tolerance: m.
        rotation_tolerance: rad (ignored for position-only targets).
        max_iterations: iteration cap of one solve (one seed); None: 100 for ``dls`` and
            ``pinv``, 3000 for ``transpose`` (a gradient method: linear convergence).
        max_step_position: Cartesian step clamp, m per iteration.
        max_step_rotation: rotation step clamp, rad per iteration.
        weights: (6,) weights of the task rows: x, y, z (per m) and rotation about x, y, z
            (per rad, world axes); zero drops a row: it is neither solved for nor checked
            (the result's errors cover the rows kept).
        position_only: solve for the tool position only (rotation rows dropped).
        damping: lambda_0 of ``dls`` (m).
        gain: factor on every joint step.
        stall_iterations: stop after this many iterations without a 0.1% improvement; None:
            10 for ``dls`` and ``pinv``, 200 for ``transpose``.
    """

    method: str = "dls"
    position_tolerance: float = 1e-4
    rotation_tolerance: float = 1e-3
    max_iterations: int | None = None
    max_step_position: float = 0.2
    max_step_rotation: float = 1.0
    weights: tuple[float, ...] = (1.0, 1.0, 1.0, 1.0, 1.0, 1.0)
    position_only: bool = False
    damping: float = 1e-3
    gain: float = 1.0
    stall_iterations: int | None = None

    def __post_init__(self) -> None:
        if self.method not in METHODS:
            raise PrehensileError(f"IK method '{self.method}' is unknown; choose one of {', '.join(METHODS)}")
        check_fields(self, **dict.fromkeys(("position_tolerance", "rotation_tolerance", "max_step_position",
                                            "max_step_rotation", "gain"), FINITE_POSITIVE),
                     weights=(lambda w: len(w) == 6 and all(0 <= x < np.inf for x in w), "6 finite numbers >= 0"),
                     damping=FINITE_NON_NEGATIVE, max_iterations=or_none(at_least(1)),
                     stall_iterations=or_none(at_least(1)))

    @property
    def iteration_cap(self) -> int:
        return self.max_iterations if self.max_iterations is not None else (3000 if self.method == "transpose" else 100)

    @property
    def stall_cap(self) -> int:
        return self.stall_iterations if self.stall_iterations is not None else (200 if self.method == "transpose" else 10)

    def task_rows(self) -> tuple[np.ndarray, np.ndarray]:
        """Indices (m,) of the task rows in use and their weights (m,)."""
        rows = [r for r in range(3 if self.position_only else 6) if self.weights[r] > 0]
        if not rows:
            raise PrehensileError("IK weights: every task row has weight 0")
        return np.array(rows, dtype=np.int64), np.array([self.weights[r] for r in rows], dtype=float)


class ChainSolver:
    """Jacobian IK for one chain of a model: the packed chain plus settings, reusable.

    Args:
        model: the robot.
        chain: a chain name of the model, or None to give ``base``/``tip`` links instead
            (the actuated joints on the path between them are solved for).
        base, tip: links of an ad-hoc chain (any URDF).
        T_tip_tcp: (4, 4) tool frame on the tip link (identity by default).
        settings: :class:`JacobianIKSettings`.
        T_world_root: (4, 4) pose of the model's root in the world; targets are world poses.
    """

    def __init__(self, model: RobotModel, chain: str | None = None, *, base: str | None = None, tip: str | None = None,
                 T_tip_tcp: np.ndarray | None = None, settings: JacobianIKSettings = JacobianIKSettings(),
                 T_world_root: np.ndarray | None = None) -> None:
        if chain is not None:
            spec = model.chain(chain)
        elif base is not None and tip is not None:
            spec = resolve_chain(model, Chain(f"{base}->{tip}", base, tip, ()), f"ChainSolver: base '{base}', tip "
                                 f"'{tip}' of robot '{model.name}'")
        else:
            raise PrehensileError("ChainSolver: give a chain name or both base and tip links")
        self.model, self.chain, self.settings = model, spec, settings
        self.tip_link = model.link_index(spec.tip_link)
        path = model.path_to_root(self.tip_link)[::-1]  # root ... tip
        self.table = np.ascontiguousarray(model.joint_table[path])
        self.var_q = np.array([model.joint_index(j) for j in spec.joint_names], dtype=np.int64)
        if len(self.var_q) == 0:
            raise PrehensileError(f"chain '{spec.name}' of robot '{model.name}' has no actuated joints")
        self.var_of_q = np.full(model.dof, -1, dtype=np.int64)
        self.var_of_q[self.var_q] = np.arange(len(self.var_q))
        self.lower, self.upper = model.sampling_limits(self.var_q)
        """(n,) range of random seeds (:meth:`RobotModel.sampling_limits`); solutions keep the
        model's limits (none for a continuous joint)."""
        self._limits = (np.ascontiguousarray(model.lower[self.var_q]), np.ascontiguousarray(model.upper[self.var_q]))
        self.T_tip_tcp = np.eye(4) if T_tip_tcp is None else check_target_poses(T_tip_tcp, "T_tip_tcp")[0]
        self.T_world_root = np.eye(4) if T_world_root is None else check_target_poses(T_world_root, "T_world_root")[0]
        self.rows, self.row_weight = settings.task_rows()

    @property
    def n(self) -> int:
        """Number of chain joints."""
        return len(self.var_q)

    def tool_pose(self, q: np.ndarray) -> np.ndarray:
        """World pose (*batch, 4, 4) of the tool for full configurations q (*batch, dof)."""
        return self.T_world_root @ link_pose(self.model, q, self.chain.tip_link, self.T_tip_tcp)

    def targets(self, target: np.ndarray) -> np.ndarray:
        """Validated target poses (k, 4, 4); position targets (3,) / (k, 3) become poses with
        identity rotation (only valid with ``position_only``)."""
        target = np.asarray(target, dtype=float)
        if target.shape[-1:] == (3,) and target.ndim <= 2:
            if not self.settings.position_only:
                raise PrehensileError("a position target (3,) needs position_only=True; give a (4, 4) pose otherwise")
            points = check_target_positions(target)
            poses = np.tile(np.eye(4), (len(points), 1, 1))
            poses[:, :3, 3] = points
            return poses
        return check_target_poses(target)

    def seed(self, q_seed: np.ndarray | None) -> np.ndarray:
        """A full configuration (dof,) to start from, its chain joints clipped into their limits
        (a seed that reaches the target is then a solution); the neutral one if None."""
        if q_seed is None:
            return self.model.neutral_configuration()
        q = np.array(self.model.check_one(q_seed, "q_seed"), dtype=float)
        q[self.var_q] = np.clip(q[self.var_q], *self._limits)
        return q

    def run(self, q_seed: np.ndarray, seeds: np.ndarray, targets: np.ndarray, first_target: int = 0
            ) -> tuple[np.ndarray, int, int, int, float, float]:
        """Solve from each row of ``seeds`` (R, n) in turn until one converges (compiled loop).

        Returns:
            (q (dof,), converged attempt or -1, target index, iterations, position error m,
            rotation error rad): the converged configuration, else the attempt that came
            closest (:meth:`miss`), with its target index and errors.
        """
        s = self.settings
        q = np.empty(self.model.dof)
        attempt, index, iterations, pos_err, rot_err = kernels.solve_restarts(
            q, q_seed, seeds, targets, self.T_world_root, self.table, self.var_of_q, self.var_q, self.T_tip_tcp,
            *self._limits, self.rows, self.row_weight, s.position_tolerance,
            s.rotation_tolerance if not s.position_only else np.inf, s.iteration_cap, METHODS[s.method],
            s.max_step_position, s.max_step_rotation, s.damping, s.gain, s.stall_cap, first_target)
        return q, attempt, index, iterations, pos_err, rot_err

    def miss(self, position_error: float, rotation_error: float) -> float:
        """How far a configuration with these errors (m, rad) is from its target, in tolerances
        (:func:`~prehensile.ik.kernels.miss`)."""
        s = self.settings
        return float(kernels.miss(position_error, rotation_error, s.position_tolerance,
                                  np.inf if s.position_only else s.rotation_tolerance))

    def solve(self, target: np.ndarray, q_seed: np.ndarray | None = None) -> IKResult:
        """One local solve from ``q_seed`` (no restarts); a pose set is tried pose by pose.

        Args:
            target: world pose (4, 4) of the tool or a set (k, 4, 4); a position (3,) /
                (k, 3) with ``position_only``.
            q_seed: (dof,) start configuration; the neutral one if None.
        """
        start = clock()
        targets = self.targets(target)
        q0 = self.seed(q_seed)
        seeds = np.repeat(q0[self.var_q][None], len(targets), axis=0)
        q, attempt, index, iterations, pos_err, rot_err = self.run(q0, seeds, targets)
        status = IKStatus.SUCCESS if attempt >= 0 else IKStatus.NOT_CONVERGED
        return IKResult(status, q, q[None] if attempt >= 0 else np.zeros((0, self.model.dof)), float(pos_err),
                        float(rot_err) if not self.settings.position_only else 0.0, int(iterations),
                        clock() - start, int(index))


def solve_ik(model: RobotModel, chain: str, target: np.ndarray, q_seed: np.ndarray | None = None,
             settings: JacobianIKSettings = JacobianIKSettings(), T_tip_tcp: np.ndarray | None = None) -> IKResult:
    """One Jacobian IK solve of ``chain`` toward ``target`` from ``q_seed`` (see :class:`ChainSolver`)."""
    return ChainSolver(model, chain, T_tip_tcp=T_tip_tcp, settings=settings).solve(target, q_seed)


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
