"""Configuration space of the planned joints with the workspace-weighted metric.

Vahrenkamp 2011, appendix B.1/B.2: joint i gets the weight w_i, the largest distance any
point of the robot's surface can move per unit motion of that joint (m/rad for revolute,
m/m for prismatic joints). The distance ``d_WS(a, b) = sum_i w_i |a_i - b_i|`` then bounds
how far any surface point moves on the straight segment from a to b, so checking a segment
at configurations spaced ``resolution`` apart in ``d_WS`` guarantees that no surface point
moves more than ``resolution`` metres between two checks.

The weights here are computed from the geometry, not read from a table: for a revolute joint
the bound is the largest distance from the joint's origin to any ball of the sphere model on
a link it moves, summing the fixed link offsets on the tree path (triangle inequality), so it
holds for every configuration of the joints further out.
"""

from __future__ import annotations

from typing import Sequence

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.model.robot_model import PRISMATIC, REVOLUTE, RobotModel


IDLE_WEIGHT = 1e-3  # weight of a joint that moves no geometry, relative to the largest


def joint_weights(model: RobotModel, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """Worst-case surface displacement per unit motion of every variable, shape (dof,).

    A revolute joint that moves no geometry (a bare flange) bounds nothing; it gets
    :data:`IDLE_WEIGHT` times the largest weight (1 if no joint moves geometry), so that the
    metric still counts it (nearest neighbours, steps, path length).

    Args:
        centers: (L, 3) centre of a ball enclosing link i's geometry, in link i's frame (m).
        radii: (L,) radius of that ball (m); negative for links without geometry.
    """
    n = model.n_links
    # reach[j, d]: bound on |p - origin_j| for points p of link d moved by joint j
    children = [[] for _ in range(n)]
    for i in range(n):
        if model.link_parent[i] >= 0:
            children[model.link_parent[i]].append(i)
    travel = model.joint_travel
    weights = np.zeros(model.dof)
    for j in range(n):
        if model.joint_type[j] not in (REVOLUTE, PRISMATIC):
            continue
        bound = 0.0
        stack = [(j, 0.0)]  # (link, bound on the distance from joint j's origin to link's origin)
        while stack:
            link, offset = stack.pop()
            if radii[link] >= 0:
                bound = max(bound, offset + np.linalg.norm(centers[link]) + radii[link])
            for child in children[link]:
                stack.append((child, offset + np.linalg.norm(model.joint_origin[child][:3, 3]) + travel[child]))
        per_unit = bound if model.joint_type[j] == REVOLUTE else 1.0
        weights[model.joint_q_index[j]] += abs(model.joint_multiplier[j]) * per_unit
    moving = weights > 0.0
    weights[~moving] = IDLE_WEIGHT * weights.max() if moving.any() else 1.0
    return weights


class ConfigurationSpace:
    """The planned joints (a subset of the model's variables), their limits and metric.

    Planners work on "active" vectors (n,) of the planned joints; :meth:`full` expands them
    into model configurations (dof,) with the other joints at ``q_ref``. A continuous joint
    (no limits) is planned on the real line, unwrapped: a goal becomes the goals of
    :meth:`goal_turns` (either way round), and samples are drawn from one turn around the
    start (:meth:`sampling_bounds`).

    Args:
        model: the robot.
        joints: joint names, or the name of a chain of the model; all variables if None.
        q_ref: (dof,) values of the joints not planned (rad or m); neutral if None.
        centers, radii: per-link bounding balls for the weights (see :func:`joint_weights`),
            e.g. from :meth:`prehensile.collision.SphereModel.link_bounds`.
        weights: (n,) explicit weights overriding the computed ones (m per unit).
    """

    def __init__(self, model: RobotModel, joints: Sequence[str] | str | None = None, q_ref: np.ndarray | None = None,
                 centers: np.ndarray | None = None, radii: np.ndarray | None = None,
                 weights: np.ndarray | None = None) -> None:
        self.model = model
        if joints is None:
            indices = np.arange(model.dof)
        elif isinstance(joints, str):
            if joints not in model.chains and joints in model.joint_names:
                raise PrehensileError(f"ConfigurationSpace: '{joints}' is a joint, not a chain of robot "
                                      f"'{model.name}' (chains: {', '.join(model.chains) or '(none)'}); give joint "
                                      f"names as a list: ['{joints}']")
            indices = model.chain_q_indices(joints)
        else:
            indices = np.array([model.joint_index(j) for j in joints], dtype=np.int64)
        if len(indices) == 0 or len(set(indices.tolist())) != len(indices):
            raise PrehensileError(f"ConfigurationSpace: joints must be non-empty and distinct, got {joints!r}")
        self.indices = np.ascontiguousarray(indices, dtype=np.int64)
        self.fixed = np.setdiff1d(np.arange(model.dof), self.indices)
        """(dof - n,) indices of the variables not planned (held at ``q_ref``)."""
        self.q_ref = model.neutral_configuration() if q_ref is None else model.check_one(q_ref, "q_ref").copy()
        self.lower, self.upper = model.lower[self.indices], model.upper[self.indices]
        """(n,) limits of the planned joints (rad or m; +-inf for continuous joints)."""
        self.continuous = model.continuous[self.indices]
        """(n,) bool: the planned joints without limits."""
        self.has_continuous = bool(self.continuous.any())
        """Whether a planned joint is continuous (samples and goals then depend on the turn)."""
        if weights is None:
            if centers is None or radii is None:
                raise PrehensileError("ConfigurationSpace: give either weights or the link balls (centers, radii)")
            weights = joint_weights(model, np.asarray(centers, float), np.asarray(radii, float))[self.indices]
        weights = np.asarray(weights, dtype=float)
        if weights.shape != self.indices.shape or np.any(weights <= 0) or not np.all(np.isfinite(weights)):
            raise PrehensileError(f"ConfigurationSpace: weights must be {len(self.indices)} positive numbers, got {weights}")
        self.weights = np.ascontiguousarray(weights)

    @property
    def n(self) -> int:
        """Number of planned joints."""
        return len(self.indices)

    @property
    def joint_names(self) -> tuple[str, ...]:
        return tuple(self.model.joint_names[i] for i in self.indices)

    def active(self, q: np.ndarray) -> np.ndarray:
        """(*batch, n) planned-joint values of full configurations q (*batch, dof)."""
        return self.model.check_configuration(q)[..., self.indices]

    def full(self, qa: np.ndarray) -> np.ndarray:
        """(*batch, dof) full configurations: ``q_ref`` with the planned joints set to qa (*batch, n)."""
        qa = np.asarray(qa, dtype=float)
        if qa.shape[-1:] != (self.n,):
            raise PrehensileError(f"ConfigurationSpace.full: expected the {self.n} planned joints "
                                  f"({', '.join(self.joint_names)}) as (..., {self.n}), got shape {qa.shape}")
        out = np.broadcast_to(self.q_ref, qa.shape[:-1] + (self.model.dof,)).copy()
        out[..., self.indices] = qa
        return out

    def distance(self, a: np.ndarray, b: np.ndarray) -> np.ndarray:
        """Workspace-bounded distance (m) between active vectors a, b (*batch, n)."""
        return np.sum(self.weights * np.abs(np.asarray(b, float) - np.asarray(a, float)), axis=-1)

    def sampling_bounds(self, center: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (n,) of uniform samples: the limits, and for a continuous joint the
        turn ``center +- pi`` around the active vector ``center`` (n,)."""
        if not self.has_continuous:
            return self.lower, self.upper
        center = np.asarray(center, dtype=float)
        return (np.where(self.continuous, center - np.pi, self.lower),
                np.where(self.continuous, center + np.pi, self.upper))

    def goal_turns(self, goals: np.ndarray, ref: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Goals (k, dof) as reached from ``ref`` (dof,) either way round a continuous joint.

        Per goal: :meth:`nearest_turn` (the shorter way for every continuous joint), then for
        each continuous joint the same goal with that joint one turn the other way (the longer
        way, when the shorter one is blocked). Returns (goals (m, dof), row of ``goals`` of each
        (m,)); without continuous joints ``goals`` itself.
        """
        if not self.has_continuous:
            return goals, np.arange(len(goals))
        ref = ref[self.indices]
        near = self.nearest_turn(goals[:, self.indices], ref)
        out, rows = [near], [np.arange(len(near))]
        for j in np.flatnonzero(self.continuous):
            other = near.copy()
            other[:, j] -= 2 * np.pi * np.where(near[:, j] >= ref[j], 1.0, -1.0)
            out.append(other)
            rows.append(rows[0])
        rows = np.concatenate(rows)
        turned = goals[rows]
        turned[:, self.indices] = np.concatenate(out)
        return turned, rows

    def nearest_turn(self, qa: np.ndarray, ref: np.ndarray) -> np.ndarray:
        """Active vectors qa (*batch, n) with each continuous joint moved by whole turns (2 pi)
        to within pi of ``ref`` (n,): the same poses, reached from ref the shorter way round."""
        qa, ref = np.asarray(qa, dtype=float), np.asarray(ref, dtype=float)
        turns = np.round((qa - ref) / (2 * np.pi))
        return np.where(self.continuous, qa - 2 * np.pi * turns, qa)

    def interpolate(self, a: np.ndarray, b: np.ndarray, resolution: float) -> np.ndarray:
        """Configurations on the segment a -> b (n,), both ends included, spaced at most
        ``resolution`` (m) apart in the workspace-weighted distance; shape (k, n), k >= 2."""
        steps = max(int(np.ceil(float(self.distance(a, b)) / resolution)), 1)
        t = np.linspace(0.0, 1.0, steps + 1)[:, None]
        return (1.0 - t) * np.asarray(a, float) + t * np.asarray(b, float)

    def path_length(self, path: np.ndarray) -> float:
        """Workspace-weighted length (m) of a path of active vectors (N, n)."""
        path = np.asarray(path, float)
        return float((np.abs(path[1:] - path[:-1]) @ self.weights).sum())
