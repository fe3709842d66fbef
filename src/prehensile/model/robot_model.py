"""The immutable robot description shared by every algorithm.

A model is a tree of links. Each link but the root is moved relative to its parent by one
joint: ``T_parent_link = joint_origin @ motion(joint_type, joint_axis, value)`` where
``value = joint_multiplier * q[joint_q_index] + joint_offset`` (fixed joints have no value;
mimic joints share the q index of the joint they follow). Links are stored parents-first, so a
single forward sweep computes all poses.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from types import MappingProxyType
from typing import Mapping

import numpy as np

from prehensile.errors import PrehensileError, UnknownFrameError
from prehensile.model.geometry import Geometry

LIMIT_TOLERANCE = 1e-9  # (rad or m) a value this far outside a joint's limits still counts as inside

FIXED, REVOLUTE, PRISMATIC = 0, 1, 2


@dataclass(frozen=True)
class Chain:
    """A named serial chain from ``base_link`` to ``tip_link`` driving the joints in ``joint_names``."""

    name: str
    base_link: str
    tip_link: str
    joint_names: tuple[str, ...]


@dataclass(frozen=True)
class EndEffector:
    """A hand or gripper. TCP and GCP are links (usually fixed frames in the hand).

    Attributes:
        name: end-effector name.
        base_link: link the hand is mounted on (the last link of the arm).
        tcp_link: the tool centre point frame.
        gcp_link: the grasp centre point frame (approach target of grasp planners).
        finger_joints: actuated joints of the hand.
        preshapes: named finger configurations, joint name -> value (rad or m).
        chain: name of the arm chain that carries the hand, "" if none.
    """

    name: str
    base_link: str
    tcp_link: str
    gcp_link: str = ""
    finger_joints: tuple[str, ...] = ()
    preshapes: Mapping[str, Mapping[str, float]] = field(default_factory=dict)
    chain: str = ""


def _frozen(array, dtype) -> np.ndarray:
    out = np.ascontiguousarray(array, dtype=dtype)
    out.setflags(write=False)
    return out


@dataclass(frozen=True, eq=False)
class RobotModel:
    """Kinematic tree, limits, geometry, chains and end effectors of one robot.

    Per-link arrays (L = number of links) describe the joint that moves the link:
    ``link_parent`` (L,) parent index (-1 for the root), ``joint_type`` (L,) FIXED / REVOLUTE /
    PRISMATIC, ``joint_origin`` (L, 4, 4) pose of the joint frame in the parent link,
    ``joint_axis`` (L, 3) unit axis in the joint frame, ``joint_q_index`` (L,) index into q
    (-1 for fixed), ``joint_multiplier`` and ``joint_offset`` (L,) for mimic joints.
    Per-DoF arrays (dof,) hold limits in rad or m: ``lower``, ``upper`` (+-inf for continuous
    joints), ``velocity_limit`` (rad/s or m/s); a mimic joint is bounded through its leader's
    limits only, as MoveIt's passive mimic joints are (the loaders warn when those take it past
    its own). ``source`` names the description file,
    ``srdf_source`` the SRDF applied to it (None if none was).
    """

    name: str
    source: str
    link_names: tuple[str, ...]
    link_joint_names: tuple[str, ...]
    link_parent: np.ndarray
    joint_type: np.ndarray
    joint_origin: np.ndarray
    joint_axis: np.ndarray
    joint_q_index: np.ndarray
    joint_multiplier: np.ndarray
    joint_offset: np.ndarray
    joint_names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity_limit: np.ndarray
    visuals: tuple[tuple[Geometry, ...], ...]
    collisions: tuple[tuple[Geometry, ...], ...]
    chains: Mapping[str, Chain] = field(default_factory=dict)
    end_effectors: Mapping[str, EndEffector] = field(default_factory=dict)
    disabled_collision_pairs: frozenset[frozenset[str]] = frozenset()
    srdf_source: str | None = None

    def __post_init__(self) -> None:
        for name, dtype in [
            ("link_parent", np.int64), ("joint_type", np.int64), ("joint_q_index", np.int64),
            ("joint_origin", float), ("joint_axis", float), ("joint_multiplier", float),
            ("joint_offset", float), ("lower", float), ("upper", float), ("velocity_limit", float),
        ]:
            object.__setattr__(self, name, _frozen(getattr(self, name), dtype))
        object.__setattr__(self, "chains", MappingProxyType(dict(self.chains)))
        object.__setattr__(self, "end_effectors", MappingProxyType(dict(self.end_effectors)))
        object.__setattr__(self, "_link_index", {n: i for i, n in enumerate(self.link_names)})
        object.__setattr__(self, "_joint_index", {n: i for i, n in enumerate(self.joint_names)})

    @cached_property
    def joint_table(self) -> np.ndarray:
        """The per-link joint arrays packed row-wise for the compiled kernels, shape (L, 20):
        parent, type, q index, multiplier, offset, axis (3), joint origin rows 0-2 (12)."""
        table = np.empty((self.n_links, 20))
        table[:, 0] = self.link_parent
        table[:, 1] = self.joint_type
        table[:, 2] = self.joint_q_index
        table[:, 3] = self.joint_multiplier
        table[:, 4] = self.joint_offset
        table[:, 5:8] = self.joint_axis
        table[:, 8:20] = self.joint_origin[:, :3, :].reshape(-1, 12)
        table.setflags(write=False)
        return table

    @cached_property
    def joint_travel(self) -> np.ndarray:
        """(L,) how far each link's prismatic joint can shift the link from the joint's origin
        (m: the largest value within its limits, times its mimic multiplier, plus its offset);
        0 for other joints."""
        travel = np.zeros(self.n_links)
        for i in np.flatnonzero(self.joint_type == PRISMATIC):
            q = self.joint_q_index[i]
            travel[i] = abs(self.joint_multiplier[i]) * max(abs(self.lower[q]), abs(self.upper[q])) \
                + abs(self.joint_offset[i])
        travel.setflags(write=False)
        return travel

    @cached_property
    def dof(self) -> int:
        """Number of configuration variables (length of q)."""
        return len(self.joint_names)

    @property
    def n_links(self) -> int:
        return len(self.link_names)

    @property
    def continuous(self) -> np.ndarray:
        """(dof,) bool: joints without position limits."""
        return ~np.isfinite(self.lower) | ~np.isfinite(self.upper)

    def link_index(self, name: str) -> int:
        """Index of link ``name`` in :attr:`link_names` (the order of FK output)."""
        try:
            return self._link_index[name]
        except KeyError:
            raise UnknownFrameError(
                f"robot '{self.name}' has no link '{name}'; links: {', '.join(self.link_names)}"
            ) from None

    def joint_index(self, name: str) -> int:
        """Index of joint ``name`` in q."""
        try:
            return self._joint_index[name]
        except KeyError:
            raise UnknownFrameError(
                f"robot '{self.name}' has no actuated joint '{name}'; joints: {', '.join(self.joint_names)}"
            ) from None

    def chain(self, name: str) -> Chain:
        """The chain called ``name``."""
        try:
            return self.chains[name]
        except KeyError:
            raise UnknownFrameError(
                f"robot '{self.name}' has no chain '{name}'; chains: {', '.join(self.chains) or '(none)'}"
            ) from None

    def end_effector(self, name: str) -> EndEffector:
        """The end effector called ``name``."""
        try:
            return self.end_effectors[name]
        except KeyError:
            raise UnknownFrameError(
                f"robot '{self.name}' has no end effector '{name}'; "
                f"end effectors: {', '.join(self.end_effectors) or '(none)'}"
            ) from None

    def chain_q_indices(self, name: str) -> np.ndarray:
        """Indices into q of the joints of chain ``name``, shape (n,)."""
        return np.array([self.joint_index(j) for j in self.chain(name).joint_names], dtype=np.int64)

    def path_to_root(self, link: str | int) -> list[int]:
        """Link indices from ``link`` up to the root, both included."""
        index = self.link_index(link) if isinstance(link, str) else int(link)
        path = []
        while index >= 0:
            path.append(index)
            index = int(self.link_parent[index])
        return path

    def variables_to_root(self, link: str | int) -> set[int]:
        """Indices into q of the variables of the joints from ``link`` up to the root (a mimic
        joint counts as its leader's; -1 stands for fixed joints): two links with the same set,
        less the variables held still, keep their relative pose."""
        return {int(self.joint_q_index[k]) for k in self.path_to_root(link)}

    def mimic_of(self, link: str | int) -> str | None:
        """Name of the joint whose variable moves ``link``'s joint if that joint is a mimic joint
        (it follows another joint, scaled or offset), else None."""
        index = self.link_index(link) if isinstance(link, str) else int(link)
        q_index = int(self.joint_q_index[index])
        if q_index < 0:
            return None
        leader = self.joint_names[q_index]
        mimics = (leader != self.link_joint_names[index] or self.joint_multiplier[index] != 1.0
                  or self.joint_offset[index] != 0.0)
        return leader if mimics else None

    @cached_property
    def mimic_joints(self) -> Mapping[str, tuple[int, float, float]]:
        """Mimic joint name -> (q index of the joint it follows, multiplier, offset): its value
        is ``multiplier * q[index] + offset`` (rad or m)."""
        return MappingProxyType({
            self.link_joint_names[link]: (int(self.joint_q_index[link]), float(self.joint_multiplier[link]),
                                          float(self.joint_offset[link]))
            for link in range(self.n_links) if self.mimic_of(link) is not None})

    def neutral_configuration(self) -> np.ndarray:
        """Zero clipped into the limits, shape (dof,)."""
        return np.clip(np.zeros(self.dof), self.lower, self.upper)

    def sampling_limits(self, indices: np.ndarray | None = None) -> tuple[np.ndarray, np.ndarray]:
        """(lower, upper) (n,) of uniform samples of the variables ``indices`` (all if None):
        the limits, and [-pi, pi] for a continuous joint (rad or m)."""
        lower, upper = (self.lower, self.upper) if indices is None else (self.lower[indices], self.upper[indices])
        return np.where(np.isfinite(lower), lower, -np.pi), np.where(np.isfinite(upper), upper, np.pi)

    def random_configurations(self, rng: np.random.Generator | int, n: int | None = None) -> np.ndarray:
        """Uniform samples within :meth:`sampling_limits`.

        Returns shape (dof,) when ``n`` is None, else (n, dof).
        """
        rng = np.random.default_rng(rng)
        lo, hi = self.sampling_limits()
        size = (self.dof,) if n is None else (n, self.dof)
        return rng.uniform(lo, hi, size=size)

    def within_limits(self, q: np.ndarray, tol: float = LIMIT_TOLERANCE) -> np.ndarray:
        """(*batch,) bool: q of shape (*batch, dof) lies within the position limits."""
        q = np.asarray(q, dtype=float)
        return ((q >= self.lower - tol) & (q <= self.upper + tol)).all(axis=-1)

    def check_configuration(self, q: np.ndarray, what: str = "q") -> np.ndarray:
        """Validate q of shape (*batch, dof): right length and finite; returns it as float64."""
        try:
            q = np.asarray(q, dtype=float)
        except (TypeError, ValueError):
            raise PrehensileError(f"{what}: expected numbers, got {q!r:.80}") from None
        if q.ndim == 0 or q.shape[-1] != self.dof:
            raise PrehensileError(
                f"{what}: expected shape (..., {self.dof}) for robot '{self.name}' "
                f"(joints: {', '.join(self.joint_names)}), got {q.shape}"
            )
        if not np.isfinite(q).all():
            raise PrehensileError(f"{what}: contains NaN or infinite values")
        return q

    def check_one(self, q: np.ndarray, what: str = "q") -> np.ndarray:
        """Validate one configuration q (dof,) (as :meth:`check_configuration`, and no batch)."""
        q = self.check_configuration(q, what)
        if q.shape != (self.dof,):
            raise PrehensileError(f"{what}: expected one configuration ({self.dof},) for robot '{self.name}', "
                                  f"got shape {q.shape}")
        return q

    def configuration_from_dict(self, values: Mapping[str, float], base: np.ndarray | None = None) -> np.ndarray:
        """q (dof,) with the named joints set and the rest taken from ``base`` (default neutral)."""
        q = self.neutral_configuration() if base is None else np.array(base, dtype=float)
        for joint, value in values.items():
            q[self.joint_index(joint)] = float(value)
        return q
