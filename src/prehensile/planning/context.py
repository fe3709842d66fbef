"""Planning context: the robot, the world, grasped objects and the compiled checkers, in one place.

A :class:`PlanningContext` holds what every planner query needs: the configuration space of
the planned joints, the sphere checker (planning), the exact checker and certifier and the
arrays the compiled planners run on. Grasped objects
(:class:`~prehensile.collision.attached.AttachedObject`) become extra links fixed to the link
that holds them, so both checkers, the metric and the motion bounds cover them without
special cases.

Motion bounds ("free bubbles", Vahrenkamp 2011 C.2 after Quinlan 1995): every ball b gets
per-joint weights ``W[b, k]`` (:func:`ball_joint_weights`, m per rad or m per m) bounding how
fast it moves when joint k turns, so a motion dq moves it by at most ``W[b] @ |dq|``. Against
another link only the joints that move one of the two but not both count (the joints above
both move them rigidly together): :func:`motion_weights` for pairs of links, and per-ball
tables by depth in the tree for the compiled motion check
(:func:`prehensile.planning.kernels.motion_free`). Both are far tighter than the
workspace-weighted metric for links close in the chain.
"""

from __future__ import annotations

import dataclasses
import functools
from typing import Sequence

import numpy as np

from prehensile.collision import sphere_kernels as SK
from prehensile.collision.acm import allowed_collision_matrix
from prehensile.collision.attached import AttachedObject, attach_objects
from prehensile.collision.sphere_checker import SphereChecker, frames_and_groups
from prehensile.collision.spheres import SphereModel, generate_sphere_model, pad_sphere_model, replace_link_balls
from prehensile.collision.world import Obstacle, check_obstacles
from prehensile.errors import PrehensileError
from prehensile.ik.jacobian import free_joint_indices
from prehensile.model.geometry import Mesh
from prehensile.model.robot_model import FIXED, PRISMATIC, REVOLUTE, RobotModel
from prehensile.planning.cspace import ConfigurationSpace
from prehensile.planning.result import PlanResult, PlanStatus
from prehensile.spatial.transforms import check_one_pose

EXPLAINED_GOALS = 5  # goals of a goal set whose rejection PlanningContext.explain puts in words
MIN_RESOLUTION = 1e-5  # m: finer checks only cost memory (the bisection queue) and time
OVERLAP_SAMPLES = 64  # random configurations PlanningContext.overlapping_links tests
OVERLAP_SHARE = 0.9  # a link pair whose balls overlap in more of them than this share is reported


def check_resolution(value: float, what: str) -> float:
    """``value`` (m) as a motion-check or certification resolution: finite, >= :data:`MIN_RESOLUTION`."""
    try:
        res = float(value)
    except (TypeError, ValueError):
        res = np.nan
    if not MIN_RESOLUTION <= res < np.inf:
        raise PrehensileError(f"{what}: must be a finite length >= {MIN_RESOLUTION} m, got {value!r}")
    return res


def ball_joint_weights(model: RobotModel, links: np.ndarray, centers: np.ndarray, radii: np.ndarray) -> np.ndarray:
    """(B, L) W[b, k]: how fast any point of ball b (on link ``links[b]``, centre (B, 3) in the
    link frame, radius (B,)) moves per unit motion of the joint of link k (m/rad or m/m; 0
    unless k is on the ball's path to the root).

    A revolute joint moves a point at its distance from the joint axis. While only fixed
    joints lie between, that is the ball centre's distance from the axis plus the radius;
    above a moving joint m it is bounded by the distance of m's origin from the axis plus a
    bound on the distance from m's origin to the ball (joint offsets and prismatic travel summed
    on the way down, triangle inequality), so it holds in every configuration. Prismatic: 1.
    Mimic multipliers scale both.
    """
    travel = model.joint_travel
    links, centers, radii = np.asarray(links, dtype=np.int64), np.asarray(centers, float), np.asarray(radii, float)
    W = np.zeros((len(links), model.n_links))
    for link in np.unique(links):  # the balls of one link share the walk to the root
        balls = np.flatnonzero(links == link)
        point, radius = centers[balls], radii[balls]
        # reach: bound on |p - origin of link k|; point: ball centres in link k's frame while the
        # path down to them is rigid; else anchor: the nearest moving joint's origin, below: reach from it
        reach, anchor, below, k = np.linalg.norm(point, axis=1) + radius, None, None, int(link)
        while k >= 0:
            kind, T = model.joint_type[k], model.joint_origin[k]
            if kind == REVOLUTE:
                axis = model.joint_axis[k] / np.linalg.norm(model.joint_axis[k])
                x, extra = (point, radius) if anchor is None else (anchor[None], below)
                W[balls, k] = abs(model.joint_multiplier[k]) * (np.linalg.norm(x - np.outer(x @ axis, axis), axis=1)
                                                                + extra)
            elif kind == PRISMATIC:
                W[balls, k] = abs(model.joint_multiplier[k])
            if kind == FIXED:
                if anchor is None:
                    point = point @ T[:3, :3].T + T[:3, 3]
                else:
                    anchor = T[:3, :3] @ anchor + T[:3, 3]
            else:
                anchor, below = T[:3, 3], reach + travel[k]
            reach = reach + float(np.linalg.norm(T[:3, 3]) + travel[k])
            k = int(model.link_parent[k])
    return W


@functools.lru_cache(maxsize=32)
def _kernel_ball_weights(model: RobotModel, spheres: SphereModel) -> np.ndarray:
    """:func:`ball_joint_weights` of the sphere kernels' balls (their order), with radius 0: a
    ball's distance to anything changes only as fast as its centre moves. Cached per (model,
    sphere model) object, like the kernels' ball groups: they do not depend on the scene."""
    order = frames_and_groups(model, spheres)[1]["order"]
    return ball_joint_weights(model, spheres.sphere_link[order], spheres.centers[order], np.zeros(len(order)))


@functools.lru_cache(maxsize=64)
def _refined_balls(balls: SphereModel, cover: SphereModel, links: frozenset) -> SphereModel:
    """:func:`replace_link_balls`, one object per (balls, cover, links), so that the refined
    contexts of every scene share its cached tables."""
    return replace_link_balls(balls, cover, set(links))


def motion_weights(model: RobotModel, link_weights: np.ndarray, pairs: np.ndarray) -> np.ndarray:
    """(P, dof) rows W with ``W[p] @ |dq|`` bounding the relative motion of pair p (m).

    Args:
        link_weights: (L, L) :func:`ball_joint_weights` of one ball per link containing its
            geometry (row 0 for links without).
        pairs: (P, 2) link indices (a, b); b = -1 means the world (fixed).

    A point of link a moves in the frame of the deepest common ancestor of a and b only
    through the joints between that ancestor and a, so the relative speed of a point of a and
    a point of b is at most the sum of their weights over the joints that move exactly one of
    them (variables shared by mimic joints add up).
    """
    above = np.zeros((model.n_links, model.n_links), dtype=bool)  # above[i, k]: link k on the way from i to the root
    for i in range(model.n_links):
        above[i, model.path_to_root(i)] = True
    variable = np.zeros((model.n_links, model.dof))  # variable[k, j]: link k's joint moves variable j
    moved = np.flatnonzero(model.joint_q_index >= 0)
    variable[moved, model.joint_q_index[moved]] = 1.0
    pairs = np.asarray(pairs, dtype=np.int64).reshape(-1, 2)
    a, b = pairs[:, 0], pairs[:, 1]
    above_a = above[a]
    above_b = above[b] & (b >= 0)[:, None]  # the world: no joints
    moving = (above_a & ~above_b) * link_weights[a] + (above_b & ~above_a) * link_weights[b]
    return moving @ variable


class PlanningContext:
    """Everything a planner query needs about one robot in one world.

    Args:
        model: the robot.
        obstacles: shapes fixed in the world.
        joints: the planned joints: a chain name, joint names, or None for all variables.
        q_ref: (dof,) values of the joints not planned (rad or m); neutral if None.
        T_world_base: (4, 4) pose of the robot root; identity if None.
        spheres: the robot's sphere model (planning); default generated from its geometry
            (:func:`~prehensile.collision.spheres.generate_sphere_model`).
        cover: balls covering the geometry (``covering``), for planning again when ``spheres``
            does not cover it (a spherized URDF) and a path fails the exact certification
            (see :meth:`refined`); default ``spheres`` padded to cover it
            (:func:`~prehensile.collision.spheres.pad_sphere_model`, cached on disk).
        acm: (L, L) allowed-collision matrix of ``model``; default from the model (SRDF).
        attached: grasped objects moving with their links.
        resolution: edge-check resolution (m): where the sphere clearance does not prove a
            segment free, it is sampled so that no ball moves more than this between checks.
        certify_resolution: the same for the exact certification (m).

    Attributes:
        space: :class:`ConfigurationSpace` of the planned joints (its model includes the
            attached objects as links; variables are the same as ``model``'s).
        spheres: :class:`SphereChecker` (robot balls, objects included, vs world and self).
        collision_model, sphere_model, acm: the model, balls and ACM with the objects attached.
        static_pairs: link pairs the planned joints do not move relative to each other; they,
            and the root body against the world, are decided on the exact geometry (the balls
            only bound them), so that a robot on a table or an arm beside a torso whose balls
            overlap can plan.
    """

    def __init__(self, model: RobotModel, obstacles: Sequence[Obstacle], joints: Sequence[str] | str | None = None,
                 q_ref: np.ndarray | None = None, T_world_base: np.ndarray | None = None,
                 spheres: SphereModel | None = None, acm: np.ndarray | None = None,
                 attached: Sequence[AttachedObject] = (), resolution: float = 0.005,
                 certify_resolution: float = 0.002, cover: SphereModel | None = None) -> None:
        resolution = check_resolution(resolution, "PlanningContext: resolution")
        certify_resolution = check_resolution(certify_resolution, "PlanningContext: certify_resolution")
        if cover is not None and not cover.covering:
            raise PrehensileError("PlanningContext: cover must be a covering sphere model (generated or padded)")
        if isinstance(attached, AttachedObject) or not all(isinstance(a, AttachedObject) for a in attached):
            raise PrehensileError("PlanningContext: attached must be a list of AttachedObject")
        if acm is not None and np.shape(acm) != (model.n_links, model.n_links):
            raise PrehensileError(f"PlanningContext: acm must be ({model.n_links}, {model.n_links}) for the links of "
                                  f"'{model.name}', got {np.shape(acm)}")
        self.model = model
        self.obstacles = check_obstacles(obstacles)
        self._mesh_world = any(isinstance(o.shape, Mesh) for o in self.obstacles)
        self.attached = tuple(attached)
        self.resolution = resolution
        self.certify_resolution = certify_resolution
        self.T_world_base = np.eye(4) if T_world_base is None else check_one_pose(T_world_base,
                                                                                  "PlanningContext: T_world_base")
        base_spheres = generate_sphere_model(model) if spheres is None else spheres
        if cover is None and not base_spheres.covering:
            cover = pad_sphere_model(base_spheres, model)
        base_acm = allowed_collision_matrix(model) if acm is None else np.asarray(acm, dtype=bool)
        self.collision_model, self.sphere_model, self.acm = attach_objects(model, base_spheres, base_acm, self.attached)
        centers, radii = self.sphere_model.link_bounds()
        self.space = ConfigurationSpace(self.collision_model, joints, q_ref, centers=centers, radii=radii)
        self._exact_checkers: dict = {}  # exact checker and certifier, shared with refined contexts
        moved_by = self._moved_by()
        self.static_pairs = self._static_pairs(moved_by)
        """(K, 2) link pairs with balls that the planned joints do not move relative to each other
        (a planned arm and the torso's other arm): left out of the ball checks, tested on the
        exact geometry once per value of the joints not planned (:meth:`static_free`)."""
        self.still_links = np.array([not joints for joints in moved_by], dtype=bool)
        """(L,) bool: the links the planned joints do not move (the root body, the legs of a
        humanoid planning an arm): left out of the balls' world tests; their world contacts are
        decided on the exact geometry once per value of the joints not planned (:meth:`static_free`),
        so that a robot standing on the floor can plan although its feet's balls reach into it."""
        self._static_free: dict[bytes, bool] = {}
        kernel_acm = self.acm.copy()
        kernel_acm[self.static_pairs[:, 0], self.static_pairs[:, 1]] = True
        kernel_acm[self.static_pairs[:, 1], self.static_pairs[:, 0]] = True
        self.spheres = SphereChecker(self.collision_model, self.obstacles, self.T_world_base, self.sphere_model,
                                     kernel_acm, static_hit=False, still=self.still_links)
        self.static_free(self.space.q_ref)  # tested now, outside the planners' clocks
        self.motion = self._motion_tables()
        """(Wball (dof, S), Wgroup (G, D), qgroup (G, D), pcut (P, 2), scales, queue (Q, 3),
        q (dof,), dq (dof + 1,), below (G, D + 1), first column 0) for
        :func:`prehensile.planning.kernels.motion_free`: per variable the weight of each ball
        of the sphere checker (all joints on its path); per group (link with balls) the moving
        joints on its path, leaf first, with their largest weight over the group's balls and
        their variables (padded with weight 0 and variable ``dof``); per self pair and side the
        number of those joints that move that side only (the ones below the deepest joint the
        two paths share); the scale arrays of
        :func:`~prehensile.collision.sphere_kernels.clearance`; work arrays (see
        :meth:`motion_arrays`)."""
        self.scratch = SK.make_scratch(self.spheres.data)
        self.end_margin = 0.5 * resolution
        """How far (m, half the resolution) a path's ends keep from the world; an end the balls hold
        nearer gets a certified escape (:func:`~prehensile.planning.certify.certified_escape`)."""
        self.end_screening = (*self.spheres.screening, self.end_margin)
        """:attr:`SphereChecker.screening` and :attr:`end_margin` (the ``screen`` of the planners' kernels)."""
        self.counters = np.zeros(1, dtype=np.int64)
        self._balls, self._cover = base_spheres, None if self.sphere_model.covering else cover
        self.cover_model = self.sphere_model if self.sphere_model.covering else None if cover is None else \
            attach_objects(model, cover, base_acm, self.attached)[1]
        """Balls covering the geometry, objects included (for the certifier's bounds), or None."""
        self._refine_args = (joints, q_ref, acm)
        self._refined: dict[frozenset, PlanningContext] = {}
        self._overlapping: list[tuple[str, str, int, int]] | None = None

    def _moved_by(self) -> list[frozenset]:
        """Per link, the links on its path to the root whose joints are planned."""
        model, planned = self.collision_model, set(self.space.indices.tolist())
        return [frozenset(k for k in model.path_to_root(link) if model.joint_q_index[k] in planned)
                for link in range(model.n_links)]

    def _static_pairs(self, moved_by: list[frozenset]) -> np.ndarray:
        """(K, 2) link pairs (ACM-allowed ones left out) with the same planned joints on their
        paths to the root (``moved_by``): nothing planned lies between them."""
        with_balls = np.unique(self.sphere_model.sphere_link)
        pairs = [(i, j) for a, i in enumerate(with_balls) for j in with_balls[a + 1:]
                 if not self.acm[i, j] and moved_by[i] == moved_by[j]]
        return np.array(pairs, dtype=np.int64).reshape(-1, 2)

    def static_free(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool for q (*batch, dof): no pair of :attr:`static_pairs` touches and no
        link of :attr:`still_links` meets the world on the exact geometry (remembered per value
        of the joints not planned)."""
        q = self.model.check_configuration(q)
        flat = q.reshape(-1, self.model.dof)
        fixed = flat[:, self.space.fixed]
        if len(flat) and (fixed == fixed[0]).all():  # the usual batch: one value of the joints not planned
            return np.full(q.shape[:-1], self._static_free_at(flat[0]))
        return np.array([self._static_free_at(row) for row in flat], dtype=bool).reshape(q.shape[:-1])

    def exact_screen(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool for q (*batch, dof): free of the contacts the balls cannot see, decided
        on the exact geometry: :meth:`static_free`, and in a world with meshes no geometry (a
        link, a held object) wholly inside a closed mesh, whose surface the balls see only
        when they cross it (:meth:`~prehensile.planning.certify.ExactCertifier.nested`)."""
        free = self.static_free(q)
        if not self._mesh_world:
            return free
        rows = self.model.check_configuration(q).reshape(-1, self.model.dof)
        nested = np.array([self.certifier.nested(row) for row in rows], dtype=bool).reshape(free.shape)
        return free & ~nested

    def balls_decide_ends(self, q: np.ndarray) -> bool:
        """Whether the sphere model alone tells which configurations with q's (dof,) values of
        the joints not planned can end a path (within the limits, free, clear of the world): no
        contact that only the exact geometry sees (:meth:`exact_screen`) is possible there, and
        the root body's balls are clear of the world."""
        return not (self._mesh_world or self.spheres.static_hit) and self._static_free_at(q)

    def _static_free_at(self, q: np.ndarray) -> bool:
        """:meth:`static_free` of one checked configuration q (dof,)."""
        key = q[self.space.fixed].tobytes()
        free = self._static_free.get(key)
        if free is None:
            free = self._static_free[key] = not self._static_contacts(q)
        return free

    def _static_contacts(self, q: np.ndarray) -> list[tuple[str, str, float]]:
        """Contacts of the :attr:`static_pairs`, and of the :attr:`still_links` with the world,
        at q (dof,) on the exact geometry (the world ones only where the balls meet it)."""
        names = self.collision_model.link_names
        static = {frozenset((names[i], names[j])) for i, j in self.static_pairs}
        contacts = [c for c in self.exact.collisions(q, "self") if frozenset(c[:2]) in static] if static else []
        if self.spheres.still_hit(q):
            still = {names[i] for i in np.flatnonzero(self.still_links)}
            contacts += [c for c in self.exact.collisions(q, "world") if c[0] in still]
        return contacts

    def _motion_tables(self) -> tuple:
        model, checker = self.collision_model, self.spheres
        granges, pairs = checker.data[9], checker.data[-1]
        W = _kernel_ball_weights(model, self.sphere_model)
        is_moving = np.isin(model.joint_type, (REVOLUTE, PRISMATIC))
        moving = np.flatnonzero(is_moving)
        to_variables = np.zeros((model.n_links, model.dof))  # joint weights -> variable weights
        to_variables[moving, model.joint_q_index[moving]] = 1.0
        Wball = (W @ to_variables).T
        paths = [[k for k in model.path_to_root(link) if is_moving[k]] for link in range(model.n_links)]  # leaf first
        group_link = checker.group_links
        depth = max((len(paths[link]) for link in group_link), default=0)
        Wgroup, qgroup = np.zeros((len(granges), depth)), np.full((len(granges), depth), model.dof, dtype=np.int64)
        for g, (link, (start, stop)) in enumerate(zip(group_link, granges)):
            path = paths[link]
            Wgroup[g, :len(path)] = np.max(W[start:stop][:, path], axis=0, initial=0.0)
            qgroup[g, :len(path)] = model.joint_q_index[path]
        pcut = np.array([[len(paths[group_link[g]]) - len(set(paths[group_link[i]]) & set(paths[group_link[j]]))
                          for g in (i, j)] for i, j in pairs], dtype=np.int64).reshape(-1, 2)
        scales = (np.empty(len(granges)), np.empty(len(pairs)), np.empty(len(W)))
        span = np.where(np.isfinite(model.upper - model.lower), model.upper - model.lower, 2 * np.pi)
        self._longest = float(np.max(span @ Wball, initial=0.0))  # farthest a ball can move on any segment
        return (np.ascontiguousarray(Wball), Wgroup, qgroup, pcut, scales, np.empty((0, 3)), np.empty(model.dof),
                np.zeros(model.dof + 1), np.zeros((len(granges), depth + 1)))

    def motion_arrays(self, resolution: float) -> tuple:
        """:attr:`motion` with a bisection queue long enough for edge checks at ``resolution`` (m):
        open intervals are separated by covered stretches of at least one resolution step."""
        need = int(self._longest / resolution) + 8
        if len(self.motion[5]) < need:
            self.motion = self.motion[:5] + (np.empty((need, 3)),) + self.motion[6:]
        return self.motion

    def refined(self, links: set[str]) -> PlanningContext | None:
        """The same query with the ``cover`` balls on ``links`` (names) and this context's
        balls elsewhere (built once per link set); None if this context's balls cover the
        geometry already.

        Planners turn to it when a path found on balls that do not cover the geometry fails the
        exact certification on those links: only where the balls proved wrong do they get the
        larger covering balls (counterexample-guided refinement), so the rest of the robot keeps
        its tighter fit.
        """
        if self._cover is None:
            return None
        key = frozenset(links) & frozenset(self.model.link_names)  # attached objects are covered already
        if key not in self._refined:
            joints, q_ref, acm = self._refine_args
            spheres = _refined_balls(self._balls, self._cover, key)
            context = PlanningContext(self.model, self.obstacles, joints, q_ref, self.T_world_base, spheres, acm,
                                      self.attached, self.resolution, self.certify_resolution, self._cover)
            context._exact_checkers = self._exact_checkers
            self._refined[key] = context
        return self._refined[key]

    @property
    def exact(self):
        """:class:`~prehensile.collision.exact.ExactChecker` on the true geometry (built on first use)."""
        if "exact" not in self._exact_checkers:
            from prehensile.collision.exact import ExactChecker

            self._exact_checkers["exact"] = ExactChecker(self.collision_model, self.obstacles, self.T_world_base,
                                                         self.acm)
        return self._exact_checkers["exact"]

    def is_valid(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool: q (*batch, dof) within the joint limits and free (sphere model; what
        it cannot see on the exact geometry, :meth:`exact_screen`)."""
        q = self.model.check_configuration(q, "PlanningContext.is_valid: q")
        return self.model.within_limits(q) & self.spheres.is_free(q) & self.exact_screen(q)

    def is_usable_end(self, q: np.ndarray) -> bool:
        """Whether q (dof,) can end a path: valid (:meth:`is_valid`), or within the limits and
        free on the exact geometry where only the conservative balls collide (a grasp around an
        object: planners leave it by a certified escape, see ``RRTConnectSettings.escape``)."""
        q = self.model.check_one(q)
        return bool(self.is_valid(q) or self.model.within_limits(q) and self.static_free(q) and self.exact.is_free(q))

    def check_solvers(self, solvers: Sequence, who: str, q_ref: np.ndarray | None = None,
                      free: Sequence[str] | str | None = None) -> np.ndarray | None:
        """Raise PrehensileError unless every IK solver (``ChainSolver``) places its chain's root
        where this context places the robot (``T_world_base``; its poses would otherwise be
        reached in the wrong place) and it and the ``free`` joints solved with it (a chain name,
        joint names or None) move only joints the context plans (its solutions would otherwise
        be goals the planner refuses). ``who`` names the caller in the message.
        Returns ``q_ref`` checked as one configuration (dof,) (None if not given)."""
        planned, names = set(self.space.indices.tolist()), self.model.joint_names
        for solver in solvers:
            unplanned = [names[i] for i in solver.var_q if i not in planned]
            if unplanned:
                raise PrehensileError(f"{who}: chain '{solver.chain.name}' moves {', '.join(unplanned)}, which the "
                                      f"context does not plan (planned: {', '.join(self.space.joint_names)})")
            if not np.allclose(solver.T_world_root, self.T_world_base, atol=1e-9):
                raise PrehensileError(f"{who}: the solver of chain '{solver.chain.name}' has T_world_root (top rows) "
                                      f"{np.round(solver.T_world_root[:3], 4).tolist()}, not the context's "
                                      f"T_world_base {np.round(self.T_world_base[:3], 4).tolist()}; "
                                      "build it with ChainSolver(..., T_world_root=ctx.T_world_base)")
        unplanned = [names[i] for i in free_joint_indices(self.model, solvers, free) if i not in planned]
        if unplanned:
            raise PrehensileError(f"{who}: the free joints {', '.join(unplanned)} are not planned by the context "
                                  f"(planned: {', '.join(self.space.joint_names)})")
        if q_ref is None:
            return None
        return self.model.check_one(q_ref, f"{who}: q_ref")

    def why_invalid(self, q: np.ndarray) -> str:
        """Why a planner may reject q (dof,) as a path end (INVALID_START / INVALID_GOAL), in
        words: the joints outside their limits, else the contacts on the exact geometry (link,
        what it touches, depth), else the links whose conservative balls collide although the
        geometry is free; "" if q is within the limits and the balls are free."""
        q = self.model.check_one(q, "why_invalid")
        names, lower, upper = self.model.joint_names, self.model.lower, self.model.upper
        outside = np.flatnonzero(~((q >= lower - 1e-9) & (q <= upper + 1e-9)))
        if len(outside):
            return "; ".join(f"joint {names[i]} = {q[i]:.4g} outside its limits [{lower[i]:.4g}, {upper[i]:.4g}]"
                             for i in outside)
        deepest: dict[tuple[str, str], float] = {}  # per pair of link and obstacle or link, over their parts
        for link, other, depth in self.exact.collisions(q):
            deepest[link, other] = max(depth, deepest.get((link, other), 0.0))
        if deepest:
            return "; ".join(f"{link} collides with {other} ({1e3 * depth:.3g} mm deep)"
                             for (link, other), depth in deepest.items())
        balls = self.spheres.ball_contacts(q)  # the still links' world contacts were decided exactly: above
        if balls:
            where = ", ".join(f"{a} with {b}" for a, b in balls)
            return (f"free on the exact geometry, but the sphere model's conservative balls collide ({where}); "
                    "a planner starts from such an end only along a certified escape motion, if it finds one "
                    "(RRTConnectSettings.escape)")
        return ""

    def overlapping_links(self) -> list[tuple[str, str, int, int]]:
        """Link pairs whose balls overlap almost everywhere: in more than :data:`OVERLAP_SHARE`
        of :data:`OVERLAP_SAMPLES` uniform samples of the planned joints (seed 0; the others at
        ``q_ref``), as (link, other link, samples where their balls overlap, samples where
        their exact geometry collides). Such a pair leaves a planner almost no free
        configuration: balls too coarse for links that nest closely, or a pair that cannot
        touch and is not disabled. Computed once per context."""
        if self._overlapping is None:
            q = np.repeat(self.space.q_ref[None], OVERLAP_SAMPLES, axis=0)
            lower, upper = self.model.sampling_limits(self.space.indices)
            q[:, self.space.indices] = np.random.default_rng(0).uniform(lower, upper, (OVERLAP_SAMPLES, len(lower)))
            counts = self.spheres.link_overlaps(q).sum(axis=0)
            pairs = np.argwhere(counts > OVERLAP_SHARE * OVERLAP_SAMPLES)
            names = self.collision_model.link_names
            contacts = [{frozenset((link, other)) for link, other, _ in self.exact.collisions(qk, kind="self")}
                        for qk in (q if len(pairs) else ())]
            self._overlapping = [(names[a], names[b], int(counts[a, b]),
                                  sum(frozenset((names[a], names[b])) in c for c in contacts)) for a, b in pairs]
        return self._overlapping

    def explain(self, result: PlanResult, q_start: np.ndarray, q_goal: np.ndarray | None = None) -> PlanResult:
        """``result`` with ``info["reason"]``: why its :attr:`~PlanResult.blamed_ends` are
        unusable (:meth:`why_invalid`), "start: ...; goal: ..." ("goal 2: ..." for row 2 of a
        goal set (k, dof): the first :data:`EXPLAINED_GOALS` of those :meth:`is_valid` rejects,
        then how many more); for a TIMEOUT also the link pairs whose balls overlap almost
        everywhere (:meth:`overlapping_links`); unchanged if there is no reason. q_start (dof,),
        q_goal (dof,) or (k, dof) as given to the planner (None: no goal configuration)."""
        if result.success:
            return result
        ends, more = [("start", q_start)] if "start" in result.blamed_ends else [], 0
        if "goal" in result.blamed_ends and q_goal is not None:
            if np.ndim(q_goal) == 1:
                ends.append(("goal", q_goal))
            else:  # the exact checks of why_invalid cost milliseconds each: not for thousands of goals
                goals = np.reshape(q_goal, (-1, self.model.dof))
                rejected = np.flatnonzero(~self.is_valid(goals))
                ends += [(f"goal {i}", goals[i]) for i in rejected[:EXPLAINED_GOALS]]
                more = len(rejected) - min(len(rejected), EXPLAINED_GOALS)
        reasons = [f"{name}: {why}" for name, q in ends if (why := self.why_invalid(q))]
        if more:
            reasons.append(f"{more} more goals rejected")
        if result.status is PlanStatus.TIMEOUT and self.overlapping_links():
            pairs = "; ".join(f"the balls of {a} and {b} overlap in {n} of {OVERLAP_SAMPLES} random configurations "
                              f"(their geometry collides in {exact})" for a, b, n, exact in self.overlapping_links())
            reasons.append(f"{pairs}: the sphere model leaves almost no free configuration (disable such a pair in "
                           "the SRDF if its links cannot touch, else give finer balls)")
        return dataclasses.replace(result, info={**result.info, "reason": "; ".join(reasons)}) if reasons else result

    def check_motion(self, qa: np.ndarray, qb: np.ndarray, resolution: float | None = None) -> bool:
        """True if both ends are valid and the straight segment qa -> qb (full configurations
        (dof,)) is free for the sphere model, proven by clearance bubbles or sampled at
        ``resolution`` (m, default the context's) where the clearance is small."""
        from prehensile.planning import kernels

        qa, qb = self.model.check_one(qa, "check_motion: qa"), self.model.check_one(qb, "check_motion: qb")
        res = self._motion_resolution(qa, qb, resolution)
        if not (self.model.within_limits(qa) and self.model.within_limits(qb) and self._static_free_at(qa)):
            return False
        return kernels.motion_free(qa, qb, res, self.spheres.data, self.scratch, self.motion_arrays(res),
                                   self.counters, kernels.NO_LIMIT, 2) == kernels.FREE

    def check_motions(self, qa: np.ndarray, qb: np.ndarray, resolution: float | None = None) -> np.ndarray:
        """(n,) bool: :meth:`check_motion` of each segment qa[k] -> qb[k] (full configurations
        (n, dof) each), in one compiled call."""
        from prehensile.planning import kernels

        qa = self.model.check_configuration(qa, "qa")
        qb = self.model.check_configuration(qb, "qb")
        if qa.ndim != 2 or qa.shape != qb.shape:
            raise PrehensileError(f"check_motions: expected qa and qb of one shape (n, {self.model.dof}), "
                                  f"got {qa.shape} and {qb.shape}")
        res = self._motion_resolution(qa, qb, resolution)
        out = np.zeros(len(qa), dtype=bool)
        rows = np.flatnonzero(self.model.within_limits(np.stack((qa, qb))).all(axis=0) & self.static_free(qa))
        free = np.zeros(len(rows), dtype=bool)
        kernels.motions_free(qa[rows], qb[rows], free, res, self.spheres.data, self.scratch, self.motion_arrays(res),
                             self.counters)
        out[rows] = free
        return out

    def _motion_resolution(self, qa: np.ndarray, qb: np.ndarray, resolution: float | None) -> float:
        """The resolution (m) of a motion check between qa and qb (checked configurations of one
        shape), which must agree in the joints not planned."""
        if np.any(np.abs(qa[..., self.space.fixed] - qb[..., self.space.fixed]) > 1e-9):
            raise PrehensileError("check_motion: qa and qb differ in joints the context does not plan")
        return self.resolution if resolution is None else check_resolution(resolution, "check_motion: resolution")

    def warm_up(self, certify: bool) -> None:
        """Build, if ``certify``, the exact certifier now (once per context; the robot's coal
        geometry once per model, :func:`~prehensile.collision.exact.robot_parts`): planners call
        this before their clock starts, so that this setup, like the context's own, stays out of
        their budgets and reported times."""
        if certify:
            _ = self.certifier

    @property
    def certifier(self):
        """The exact path certifier (:class:`~prehensile.planning.certify.ExactCertifier`), built on first use."""
        if "certifier" not in self._exact_checkers:
            from prehensile.planning.certify import ExactCertifier

            self._exact_checkers["certifier"] = ExactCertifier(self.collision_model, self.obstacles,
                                                               self.T_world_base, self.acm, self.cover_model,
                                                               self.exact.obstacle_parts)
        return self._exact_checkers["certifier"]
