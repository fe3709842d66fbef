"""The IK peers of ``prehensile bench ik``: a pinocchio damped-least-squares solver and ikpy.

Both are built from the robot's URDF (``model.source``) and mapped to our chain by joint
names; both start from the same configuration and get the same targets as our solvers, and
both return a full configuration of *our* model, which the runner verifies with our forward
kinematics (neither peer's own success flag is trusted).

**pinocchio DLS with random restarts** (:class:`PinocchioDLS`), the classic pinocchio IK loop
made competitive: a reduced model holding only the chain joints (``pin.buildReducedModel``,
every other joint locked at the start configuration), one ``computeFrameJacobian`` call per
iteration (it also updates the tool placement) in ``LOCAL_WORLD_ALIGNED`` axes, the error
:math:`e = [p^* - p;\\ \\log_3(R^* R^\\top)]` (the quantity both tolerances are stated in; the
linear part of ``log6`` is not the position error), the full step
:math:`\\Delta q = J^\\top (J J^\\top + \\lambda^2 I)^{-1} e` integrated with ``pin.integrate``
and clamped into the joint limits. The example's fixed small step (``DT = 0.1``) and fixed
damping converge far slower; here the step is full, the error clamped to 0.2 m / 1 rad per
iteration, :math:`\\lambda^2 = |e|^2 + 10^{-6}`, joints at a limit that the step pushes
further out are dropped from it (the step recomputed without their columns), and a solve stops
after 100 iterations or 10 without a 0.1 % improvement -- the same choices as our ``dls``, so
that the comparison measures the implementations. The 6 x 6 system goes to LAPACK's
``dposv`` (a fifth of ``np.linalg.solve``'s call overhead). Restarts come from
``pin.randomConfiguration`` of the reduced model (the chain's limits), seeded by ``pin.seed``;
the clock is read every iteration.

**ikpy** (:class:`IkpyPeer`): the chain parsed from the URDF along the path root -> tip
(``base_elements``), joints outside our chain masked inactive and held at the start values,
solved in 6-D with ``inverse_kinematics_frame(..., orientation_mode="all")`` (scipy
least squares, one start, no time limit; ikpy has neither restarts nor a budget).
"""

from __future__ import annotations

import importlib.util
import math
import time

import numpy as np
from scipy.linalg.lapack import dposv

from prehensile.errors import PrehensileError
from prehensile.model.robot_model import Chain, RobotModel

PEERS = ("pinocchio", "ikpy")


def _urdf(model: RobotModel, peer: str) -> str:
    if not str(model.source).lower().endswith(".urdf"):
        raise PrehensileError(f"peer {peer}: needs the robot as a URDF, got {model.source}")
    return str(model.source)


def joint_values(model: RobotModel, q: np.ndarray) -> dict[str, float]:
    """Value (rad or m) of every moving joint of the model at q (dof,), mimic joints included."""
    return {name: float(model.joint_multiplier[link] * q[model.joint_q_index[link]] + model.joint_offset[link])
            for link, name in enumerate(model.link_joint_names) if name and model.joint_q_index[link] >= 0}


class PinocchioDLS:
    """Damped least squares on pinocchio with random restarts (see the module docstring).

    Args:
        model: our robot (from a URDF).
        chain: the chain (resolved: base, tip and joint names).
        q_start: (dof,) start configuration; joints outside the chain stay at its values.
        position_tolerance: m.
        rotation_tolerance: rad.
    """

    name = "pinocchio"
    max_iterations, stall_iterations = 100, 10
    max_step_position, max_step_rotation, damping = 0.2, 1.0, 1e-3

    def __init__(self, model: RobotModel, chain: Chain, q_start: np.ndarray, position_tolerance: float,
                 rotation_tolerance: float) -> None:
        import pinocchio as pin

        full = pin.buildModelFromUrdf(_urdf(model, self.name))
        values = joint_values(model, q_start)
        missing = [j for j in chain.joint_names if not full.existJointName(j)]
        if missing:
            raise PrehensileError(f"peer pinocchio: {model.source} has no joints {', '.join(missing)}")
        reference = pin.neutral(full)
        for j in range(1, full.njoints):
            _set(reference, full.joints[j], values.get(full.names[j], 0.0))
        tip = _unique_link_frames(pin, full, chain.tip_link)
        lock = [j for j in range(1, full.njoints) if full.names[j] not in chain.joint_names]
        self.pin = pin
        self.reduced = pin.buildReducedModel(full, lock, reference)
        self.data = self.reduced.createData()
        self.frame = self.reduced.getFrameId(tip)
        self.joints = [self.reduced.joints[self.reduced.getJointId(j)] for j in chain.joint_names]
        self.var_q = np.array([model.joint_index(j) for j in chain.joint_names])
        self.q_start = np.asarray(q_start, dtype=float)
        self.start = pin.neutral(self.reduced)
        for joint, name in zip(self.joints, chain.joint_names):
            _set(self.start, joint, values[name])
        self.lower, self.upper = self.reduced.lowerPositionLimit, self.reduced.upperPositionLimit
        # limits per velocity index (continuous joints, stored as (cos, sin), have none)
        nv, one = self.reduced.nv, [j for j in self.reduced.joints[1:] if j.nq == 1 and j.nv == 1]
        self.q_of_v = None if self.reduced.nq == nv else np.zeros(nv, dtype=int)
        self.lower_v, self.upper_v = np.full(nv, -np.inf), np.full(nv, np.inf)
        for j in one:
            self.lower_v[j.idx_v], self.upper_v[j.idx_v] = self.lower[j.idx_q], self.upper[j.idx_q]
            if self.q_of_v is not None:
                self.q_of_v[j.idx_v] = j.idx_q
        self.tolerance = (position_tolerance, rotation_tolerance)

    def solve(self, target: np.ndarray, time_budget_s: float, seed: int) -> tuple[np.ndarray, int]:
        """Solve for the tool pose ``target`` (4, 4) within ``time_budget_s``; restarts seeded by ``seed``.

        Returns:
            (q (dof,) of our model: the solution or the last configuration tried, iterations).
        """
        pin, model, data, frame = self.pin, self.reduced, self.data, self.frame
        start = time.perf_counter()
        R_t, p_t = target[:3, :3], target[:3, 3]
        tol_p, tol_r = self.tolerance
        e, eye = np.empty(6), np.eye(6)
        q, iterations, best, since_best, it = self.start.copy(), 0, math.inf, 0, 0
        pin.seed(int(seed))
        while True:
            J = pin.computeFrameJacobian(model, data, q, frame, pin.LOCAL_WORLD_ALIGNED)
            placement = data.oMf[frame]
            e[:3] = p_t - placement.translation
            e[3:] = pin.log3(R_t @ placement.rotation.T)
            pos, rot = math.sqrt(e[:3] @ e[:3]), math.sqrt(e[3:] @ e[3:])
            if pos <= tol_p and rot <= tol_r:
                break
            score = pos / tol_p + rot / tol_r
            best, since_best = (score, 0) if score < 0.999 * best else (best, since_best + 1)
            if time.perf_counter() - start >= time_budget_s:
                break
            if it >= self.max_iterations or since_best >= self.stall_iterations:
                q, best, since_best, it = pin.randomConfiguration(model), math.inf, 0, 0
                continue
            if pos > self.max_step_position:
                e[:3] *= self.max_step_position / pos
            if rot > self.max_step_rotation:
                e[3:] *= self.max_step_rotation / rot
            damping = (e @ e + self.damping ** 2) * eye
            dq = J.T @ dposv(J @ J.T + damping, e)[1]
            q_v = q if self.q_of_v is None else q[self.q_of_v]  # joints at a limit that dq pushes out drop out
            blocked = ((q_v <= self.lower_v) & (dq < 0)) | ((q_v >= self.upper_v) & (dq > 0))
            if blocked.any():
                J[:, blocked] = 0.0
                dq = J.T @ dposv(J @ J.T + damping, e)[1]
            q = np.clip(pin.integrate(model, q, dq), self.lower, self.upper)
            it += 1
            iterations += 1
        return self._ours(q), iterations

    def _ours(self, q_pin: np.ndarray) -> np.ndarray:
        q = self.q_start.copy()
        for index, joint in zip(self.var_q, self.joints):
            i = joint.idx_q
            q[index] = math.atan2(q_pin[i + 1], q_pin[i]) if joint.nq == 2 else q_pin[i]
        return q


def _unique_link_frames(pin, full, tip_link: str) -> str:
    """Rename link frames that share a name with a joint frame (URDFs may name a link like its
    joint; ``buildReducedModel`` finds frames by name); returns the tip link's frame name."""
    names = [frame.name for frame in full.frames]
    tip = None
    for i, frame in enumerate(full.frames):
        if frame.type == pin.FrameType.BODY:
            if names.count(frame.name) > 1:
                frame.name += "#link"
                full.frames[i] = frame
            if names[i] == tip_link:
                tip = frame.name
    if tip is None:
        raise PrehensileError(f"peer pinocchio: no link frame '{tip_link}' in the URDF")
    return tip


def _set(q_pin: np.ndarray, joint, value: float) -> None:
    """Write a joint value into pinocchio's q; continuous joints are stored as (cos, sin)."""
    if joint.nq == 2:
        q_pin[joint.idx_q:joint.idx_q + 2] = math.cos(value), math.sin(value)
    elif joint.nq == 1:
        q_pin[joint.idx_q] = value


class IkpyPeer:
    """ikpy's 6-D IK on the same chain (see the module docstring); arguments as :class:`PinocchioDLS`."""

    name = "ikpy"

    def __init__(self, model: RobotModel, chain: Chain, q_start: np.ndarray) -> None:
        from ikpy.chain import Chain as IkpyChain
        from ikpy.link import OriginLink
        from ikpy.urdf.URDF import get_urdf_parameters

        path = model.path_to_root(chain.tip_link)[::-1]  # root ... tip
        elements = [model.link_names[path[0]]]
        for link in path[1:]:
            elements += [model.link_joint_names[link], model.link_names[link]]
        try:
            # after the given elements ikpy follows first children on its own: cut at the tip
            links = get_urdf_parameters(_urdf(model, self.name), base_elements=elements)[:len(path) - 1]
        except ValueError as err:
            raise PrehensileError(f"peer ikpy: cannot build chain {chain.name} from {model.source}: {err}") from None
        links = [_unit_axes(link) for link in links]
        if links[-1].joint_type != "fixed":  # ikpy never moves the last link: add a fixed tip
            links.append(type(links[-1])(name="tip", origin_translation=[0, 0, 0], origin_orientation=[0, 0, 0],
                                         rotation=None, translation=None, joint_type="fixed"))
        active = [False] + [link.name in chain.joint_names for link in links]
        self.chain = IkpyChain([OriginLink()] + links, active_links_mask=active, name=chain.name)
        values = joint_values(model, q_start)
        self.initial = np.array([0.0] + [values.get(link.name, 0.0) for link in links])
        self.columns = [(i, model.joint_index(link.name)) for i, link in enumerate(self.chain.links) if active[i]]
        self.q_start = np.asarray(q_start, dtype=float)

    def solve(self, target: np.ndarray, time_budget_s: float, seed: int) -> tuple[np.ndarray, None]:
        """One 6-D ikpy solve from the start (ikpy takes no budget or seed; both are ignored).

        Returns:
            (q (dof,) of our model, None: ikpy reports no iteration count).
        """
        solution = self.chain.inverse_kinematics_frame(target, initial_position=self.initial, orientation_mode="all")
        q = self.q_start.copy()
        for column, index in self.columns:
            q[index] = solution[column]
        return q, None


def _unit_axes(link):
    """The ikpy link with unit joint axes: a URDF's need not be, and ikpy would scale the
    motion by their length (it builds its transforms when a link is made, so a new one)."""
    axes = (link.rotation, link.translation)
    if all(axis is None or np.isclose(np.linalg.norm(axis), 1.0) for axis in axes):
        return link
    unit = [None if axis is None else np.asarray(axis, float) / np.linalg.norm(axis) for axis in axes]
    return type(link)(name=link.name, origin_translation=link.origin_translation,
                      origin_orientation=link.origin_orientation, rotation=unit[0], translation=unit[1],
                      bounds=link.bounds, joint_type=link.joint_type)


def make_peer(name: str, model: RobotModel, chain: Chain, q_start: np.ndarray, position_tolerance: float,
              rotation_tolerance: float) -> PinocchioDLS | IkpyPeer:
    """The peer called ``name`` (one of :data:`PEERS`) on ``chain``; PrehensileError for a
    chain with mimic joints (the peers load them as independent joints: another robot)."""
    below_base = set(model.path_to_root(chain.base_link))
    path = [link for link in model.path_to_root(chain.tip_link) if link not in below_base]
    mimics = [f"{model.link_joint_names[link]} (follows {model.mimic_of(link)})" for link in path
              if model.mimic_of(link)]
    if mimics:
        raise PrehensileError(f"peer {name}: the chain {chain.base_link} -> {chain.tip_link} has mimic joints "
                              f"{', '.join(mimics)}, which the peer loads as independent joints; leave it out "
                              "(--peers) or pick a chain without them")
    if importlib.util.find_spec(name) is None:  # each peer's module has its name
        raise PrehensileError(f"peer {name} is not installed: pip install 'prehensile[bench]' (or leave it out: "
                              "--peers none)")
    if name == "pinocchio":
        return PinocchioDLS(model, chain, q_start, position_tolerance, rotation_tolerance)
    if name == "ikpy":
        return IkpyPeer(model, chain, q_start)
    raise PrehensileError(f"unknown IK peer '{name}'; valid: {', '.join(PEERS)}")
