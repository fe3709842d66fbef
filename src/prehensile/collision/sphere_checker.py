"""Fast batched collision checking of a robot's sphere model against world primitives.

Forward kinematics and every test run in one compiled kernel
(:mod:`prehensile.collision.sphere_kernels`) that stops at the first collision of each
configuration; the same kernel gives (scaled) clearances for the planners' motion checks.
Grasped objects join as extra links (:func:`prehensile.collision.attached.attach_objects`).
Boxes, spheres, cylinders and capsules are tested exactly (ball against solid).
Mesh obstacles are replaced by oriented boxes covering their triangles
(:func:`~prehensile.collision.sphere_fit.box_cover`; flat patches give flat boxes), which is
conservative for surface contact, the same notion of contact as coal's mesh checks; a robot
wholly inside a closed obstacle mesh is not detected by either checker.
"""

from __future__ import annotations

import functools
import math
from typing import Callable, Sequence

import numpy as np

from prehensile.collision import sphere_kernels as K
from prehensile.collision.acm import allowed_collision_matrix, rigid_bodies
from prehensile.collision.sphere_fit import box_cover, geometry_triangles
from prehensile.collision.spheres import SphereModel, generate_sphere_model
from prehensile.collision.world import Obstacle, check_obstacles
from prehensile.errors import PrehensileError
from prehensile.kinematics.forward import forward_kinematics
from prehensile.model.geometry import Box, Capsule, Cylinder, Geometry, Mesh, Sphere
from prehensile.model.robot_model import LIMIT_TOLERANCE, RobotModel
from prehensile.spatial.transforms import check_one_pose


def obstacle_arrays(obstacles: Sequence[Obstacle], mesh_boxes: int = 32) -> dict[str, np.ndarray]:
    """Flat obstacle arrays for the kernels (see :mod:`~prehensile.collision.sphere_kernels`).

    Returns:
        dict with ``otype`` (O,) int64, ``opose`` (O, 3, 4), ``oparam`` (O, 3), ``oaabb``
        (6, O') (m; rows: min xyz, max xyz; O' >= O, the multiple of
        :data:`~prehensile.collision.sphere_kernels.LANES` above O, the columns beyond O boxes
        far away) and ``oname`` (O,) names; a mesh obstacle expands into up to ``mesh_boxes``
        oriented boxes covering its triangles (:func:`box_cover`: flat patches get flat boxes).
    """
    types, poses, params, names = [], [], [], []
    for obstacle in obstacles:
        T = np.asarray(obstacle.T_world_shape, dtype=float)
        if T.shape != (4, 4) or not np.all(np.isfinite(T)):
            raise PrehensileError(f"obstacle '{obstacle.name}': T_world_shape must be a finite (4, 4) pose")
        shape = obstacle.shape
        if isinstance(shape, Mesh):
            box_poses, halves = box_cover(geometry_triangles(Geometry(shape)), mesh_boxes)
            for pose, half in zip(T @ box_poses, halves):
                types.append(K.BOX), poses.append(pose[:3]), params.append(half), names.append(obstacle.name)
            continue
        if isinstance(shape, Sphere):
            kind, param = K.SPHERE, [shape.radius, 0.0, 0.0]
        elif isinstance(shape, Box):
            kind, param = K.BOX, [0.5 * s for s in shape.size]
        elif isinstance(shape, Cylinder):
            kind, param = K.CYLINDER, [shape.radius, 0.5 * shape.length, 0.0]
        elif isinstance(shape, Capsule):
            kind, param = K.CAPSULE, [shape.radius, 0.5 * shape.length, 0.0]
        else:
            raise PrehensileError(f"obstacle '{obstacle.name}': unsupported shape {type(shape).__name__}")
        types.append(kind), poses.append(T[:3].copy()), params.append(param), names.append(obstacle.name)
    otype = np.array(types, dtype=np.int64)
    opose = np.array(poses, dtype=float).reshape(-1, 3, 4)
    oparam = np.array(params, dtype=float).reshape(-1, 3)
    oaabb = np.full((6, -(-max(len(otype), 1) // K.LANES) * K.LANES), K.FAR)
    for o in range(len(otype)):
        R, p, (a, b, c) = opose[o, :, :3], opose[o, :, 3], oparam[o]
        if otype[o] == K.SPHERE:
            half = np.full(3, a)
        elif otype[o] == K.BOX:
            half = np.abs(R) @ np.array([a, b, c])
        elif otype[o] == K.CYLINDER:  # disc extent a * sqrt(1 - n_i^2) plus axis extent b * |n_i|
            half = a * np.sqrt(np.clip(1.0 - R[:, 2] ** 2, 0.0, 1.0)) + b * np.abs(R[:, 2])
        else:
            half = b * np.abs(R[:, 2]) + a
        oaabb[:, o] = np.concatenate([p - half, p + half])
    return {"otype": otype, "opose": np.ascontiguousarray(opose), "oparam": oparam, "oaabb": oaabb,
            "oname": np.array(names, dtype=object)}


def _tree_distance(model: RobotModel, a: int, b: int) -> int:
    """Number of joints on the tree path between links a and b."""
    up_a, up_b = model.path_to_root(a), model.path_to_root(b)
    common = len(set(up_a) & set(up_b))
    return len(up_a) + len(up_b) - 2 * common


CHUNK = 8  # balls per chunk: the middle level of the bounding-ball hierarchy


@functools.lru_cache(maxsize=32)
def frames_and_groups(model: RobotModel, spheres: SphereModel) -> tuple[dict, dict]:
    """Kinematic frames (moving rigid bodies) and ball groups (links with balls) for the kernels.

    Links joined by fixed joints form one rigid body; its top link is the frame. Balls are
    moved into their body's frame, so FK computes one pose per moving body only. Frame 0 is
    the root body (its pose never changes). Each group's balls are sorted along its main axis
    and cut into chunks of ``CHUNK`` with a bounding ball each; ``order`` maps the kernels'
    balls to the sphere model's.

    Cached per (model, sphere model) object: they do not depend on the scene, so every
    checker of that robot with those balls shares the arrays (nothing writes them).
    """
    body = rigid_bodies(model)
    roots = [i for i in range(model.n_links) if body[i] == i]
    frame_of = {r: f for f, r in enumerate(roots)}
    T_body_link = np.tile(np.eye(4), (model.n_links, 1, 1))
    for i in range(model.n_links):
        if body[i] != i:
            T_body_link[i] = T_body_link[model.link_parent[i]] @ model.joint_origin[i]
    frames = {k: [] for k in ("parent", "jtype", "origin", "axis", "qidx", "mult", "offset")}
    for r in roots:
        p = int(model.link_parent[r])
        frames["parent"].append(-1 if p < 0 else frame_of[int(body[p])])
        frames["origin"].append(model.joint_origin[r] if p < 0 else T_body_link[p] @ model.joint_origin[r])
        frames["jtype"].append(model.joint_type[r])
        frames["axis"].append(model.joint_axis[r])
        frames["qidx"].append(model.joint_q_index[r])
        frames["mult"].append(model.joint_multiplier[r])
        frames["offset"].append(model.joint_offset[r])
    frames = {k: np.ascontiguousarray(v, dtype=np.int64 if k in ("parent", "jtype", "qidx") else float)
              for k, v in frames.items()}
    ranges = spheres.link_ranges()
    bcenter, bradius = spheres.link_bounds()
    links = [i for i in range(model.n_links) if ranges[i, 1] > ranges[i, 0]]
    links.sort(key=lambda i: (frame_of[int(body[i])], i))  # the kernels need groups sorted by frame
    order, g_bc, chunks = [], [], []
    for i in links:
        a, b = ranges[i]
        T = T_body_link[i]
        # balls sorted along the link's main axis, cut into chunks of CHUNK neighbours
        c = spheres.centers[a:b]
        axis = np.linalg.svd(c - c.mean(axis=0))[2][0] if b - a > 1 else np.zeros(3)
        sorted_balls = a + np.argsort(c @ axis, kind="stable")
        g_bc.append(T[:3, :3] @ bcenter[i] + T[:3, 3])
        chunks.append([(len(order) + k, len(order) + min(k + CHUNK, b - a)) for k in range(0, b - a, CHUNK)])
        order += list(sorted_balls)
    order = np.array(order, dtype=np.int64)
    T_ball = T_body_link[spheres.sphere_link[order]]
    centers = np.einsum("nij,nj->ni", T_ball[:, :3, :3], spheres.centers[order]) + T_ball[:, :3, 3]
    radii = spheres.radii[order]
    counts = np.array([b - a for a, b in (ranges[i] for i in links)], dtype=np.int64)
    stops = np.cumsum(counts)
    cranges = np.array([c for group in chunks for c in group], dtype=np.int64).reshape(-1, 2)
    cbcenter, cbradius = np.zeros((len(cranges), 3)), np.zeros(len(cranges))
    for k, (a, b) in enumerate(cranges):
        low, high = centers[a:b] - radii[a:b, None], centers[a:b] + radii[a:b, None]
        cbcenter[k] = 0.5 * (low.min(axis=0) + high.max(axis=0))
        cbradius[k] = np.max(np.linalg.norm(centers[a:b] - cbcenter[k], axis=1) + radii[a:b])
    chunk_stops = np.cumsum([len(group) for group in chunks]).astype(np.int64)
    groups = {
        "link": np.array(links, dtype=np.int64),
        "frame": np.array([frame_of[int(body[i])] for i in links], dtype=np.int64),
        "ranges": np.column_stack([stops - counts, stops]).astype(np.int64).reshape(-1, 2),
        "centers": np.ascontiguousarray(centers.reshape(-1, 3)),
        "radii": np.ascontiguousarray(radii),
        "bcenter": np.ascontiguousarray(np.array(g_bc, dtype=float).reshape(-1, 3)),
        "bradius": bradius[links] if links else np.zeros(0),
        "chunks": np.column_stack([chunk_stops - [len(g) for g in chunks], chunk_stops]).astype(np.int64)
        .reshape(-1, 2),
        "cranges": cranges, "cbcenter": cbcenter, "cbradius": cbradius,
        "order": order,
    }
    return frames, groups


class SphereChecker:
    """Batched, compiled collision checks of a robot's balls against world obstacles and itself.

    Args:
        model: the robot.
        obstacles: shapes fixed in the world.
        T_world_base: pose (4, 4) of the robot root; identity if None.
        spheres: the robot's sphere model; default :func:`generate_sphere_model` (cached,
            covering the collision geometry).
        acm: (L, L) bool allowed-collision matrix (True = skip); default
            :func:`~prehensile.collision.acm.allowed_collision_matrix`.
        mesh_boxes: oriented boxes per mesh obstacle (:func:`obstacle_arrays`).
        static_hit: whether the robot's root body meets an obstacle, if known (from the exact
            geometry: the balls only bound it); None: decided by the root body's balls.
        still: (L,) bool, the links whose balls are not tested against the world in each
            configuration: links that never move in the configurations checked, whose world
            contacts ``static_hit`` decides once (default: the root body, rigid with the world;
            a planning context adds the links its planned joints do not move).
    """

    def __init__(self, model: RobotModel, obstacles: Sequence[Obstacle], T_world_base: np.ndarray | None = None,
                 spheres: SphereModel | None = None, acm: np.ndarray | None = None, mesh_boxes: int = 32,
                 static_hit: bool | None = None, still: np.ndarray | None = None) -> None:
        self.model = model
        self.spheres = generate_sphere_model(model) if spheres is None else spheres
        if tuple(self.spheres.link_names) != tuple(model.link_names):
            raise PrehensileError("SphereChecker: the sphere model belongs to a different robot (link lists differ)")
        self.acm = allowed_collision_matrix(model) if acm is None else np.asarray(acm, dtype=bool)
        if self.acm.shape != (model.n_links, model.n_links):
            raise PrehensileError(f"SphereChecker: acm must be ({model.n_links}, {model.n_links}) for the links of "
                                  f"'{model.name}', got {self.acm.shape}")
        self.T_world_base = np.eye(4) if T_world_base is None else check_one_pose(T_world_base,
                                                                                  "SphereChecker: T_world_base")
        frames, groups = frames_and_groups(model, self.spheres)
        g_link = groups["link"]
        pairs = [(a, b) for a in range(len(g_link)) for b in range(a + 1, len(g_link))
                 if not self.acm[g_link[a], g_link[b]]]
        # links close in the tree touch most often: test them first (earlier exits);
        # the group with fewer balls goes first in a pair (it is the outer loop)
        pairs.sort(key=lambda p: (_tree_distance(model, int(g_link[p[0]]), int(g_link[p[1]])), p))
        count = lambda g: groups["ranges"][g, 1] - groups["ranges"][g, 0]  # noqa: E731
        pairs = [(a, b) if count(a) <= count(b) else (b, a) for a, b in pairs]
        self.obstacle_data = obstacle_arrays(check_obstacles(obstacles), mesh_boxes)
        d = self.obstacle_data
        # frame 0 is the model root: it never moves
        static = groups["frame"] == 0 if still is None else np.asarray(still, dtype=bool)[groups["link"]]
        pairs = np.array(pairs, dtype=np.int64).reshape(-1, 2)
        self.data = (
            self.T_world_base,
            *(frames[k] for k in ("parent", "jtype", "origin", "axis", "qidx", "mult", "offset")),
            groups["frame"], groups["ranges"], groups["centers"], groups["radii"], groups["bcenter"],
            groups["bradius"], ~static, groups["chunks"], groups["cranges"], groups["cbcenter"], groups["cbradius"],
            d["otype"], d["opose"], d["oparam"], d["oaabb"], groups["bradius"][pairs].sum(axis=1), pairs,
        )
        """The arrays of the compiled kernels (see :func:`~prehensile.collision.sphere_kernels.clearance`)."""
        self.group_links = groups["link"]
        """(G,) the link of each ball group of the kernels; ``data[-1]`` (P, 2) pairs groups."""
        self.ball_order = groups["order"]
        """(S,) the sphere model's ball behind each of the kernels' balls."""
        self._scratch = K.make_scratch(self.data)
        self._scales = K.unit_scales(self.data)
        world = self.data[:-1] + (np.zeros((0, 2), dtype=np.int64),)
        self._world_only = (world, K.unit_scales(world))
        self.screening = (model.lower - LIMIT_TOLERANCE, model.upper + LIMIT_TOLERANCE, self._scales,
                          self._world_only[1])
        """The arrays of :func:`~prehensile.collision.sphere_kernels.screen_one` after ``q``:
        (lower (dof,), upper (dof,), scales, world scales) (see :meth:`screen`)."""
        self._still = static
        # balls on the root body do not move: test them against the world once, here
        self.static_hit = self.still_hit(np.zeros(model.dof)) if static_hit is None else bool(static_hit)
        """True if the still links (the root body) meet an obstacle: every configuration collides."""

    def still_hit(self, q: np.ndarray) -> bool:
        """Whether a ball of the still links (see ``still``) meets an obstacle at q (dof,)."""
        return self._hits_world(q, self._still)

    def _hits_world(self, q: np.ndarray, groups: np.ndarray) -> bool:
        """Whether a ball of the groups marked in ``groups`` (G,) bool meets an obstacle at q (dof,)."""
        data = list(self.data)
        data[14] = groups  # gtest
        data[-1] = np.zeros((0, 2), dtype=np.int64)  # no self pairs
        return K.check_batch(q[None], tuple(data), self._scratch, K.unit_scales(tuple(data)),
                             np.empty(1, dtype=np.bool_), True) == 0

    def ball_contacts(self, q: np.ndarray) -> list[tuple[str, str]]:
        """Where the balls collide at one configuration q (dof,): (link, other link) for each
        pair of links the ACM does not skip whose balls overlap, and (link, "world") for each
        link whose balls meet an obstacle (still links, see ``still``, only if :attr:`static_hit`)."""
        q = self.model.check_one(q, "ball_contacts")
        if self.is_free(q):  # the compiled test answers the usual case in microseconds
            return []
        names = self.model.link_names
        out = [(names[a], names[b]) for a, b in np.argwhere(self.link_overlaps(q[None])[0])]
        tested = self.data[14] | self.static_hit  # the root body's balls count where static_hit says so
        for g in np.flatnonzero(tested):
            if self._hits_world(q, np.arange(len(tested)) == g):
                out.append((names[self.group_links[g]], "world"))
        return out

    def link_overlaps(self, q: np.ndarray) -> np.ndarray:
        """(B, L, L) bool for configurations q (B, dof): ``[k, a, b]`` = some ball of link a
        overlaps some ball of link b > a at q[k] (pairs the ACM skips are False)."""
        q = self.model.check_configuration(q).reshape(-1, self.model.dof)
        s, n_links = self.spheres, self.model.n_links
        T = forward_kinematics(self.model, q, self.T_world_base)[:, s.sphere_link]
        c = np.einsum("bnij,nj->bni", T[..., :3, :3], s.centers) + T[..., :3, 3]
        la, lb = np.broadcast_arrays(s.sphere_link[:, None], s.sphere_link[None])
        i, j = np.nonzero((la < lb) & ~self.acm[la, lb])  # the ball pairs tested
        a, b, reach2 = s.sphere_link[i], s.sphere_link[j], (s.radii[i] + s.radii[j]) ** 2
        out = np.zeros((len(q), n_links, n_links), dtype=bool)
        chunk = max(1, 2**22 // max(3 * len(i), 1))  # configurations per (chunk, pairs, 3) table
        for first in range(0, len(q), chunk):
            d = c[first:first + chunk, i] - c[first:first + chunk, j]
            k, p = np.nonzero(np.einsum("bpx,bpx->bp", d, d) < reach2)
            out[first + k, a[p], b[p]] = True
        return out

    def _batch(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(q, its rows (B, dof) contiguous) for configurations q (*batch, dof); a robot without
        joints (dof 0) included."""
        q = self.model.check_configuration(q)
        return q, np.ascontiguousarray(q.reshape(math.prod(q.shape[:-1]), self.model.dof))

    def is_free(self, q: np.ndarray) -> np.ndarray:
        """(*batch,) bool: no ball meets an obstacle or a ball of a non-allowed link, for q
        (*batch, dof) (rad or m)."""
        q, flat = self._batch(q)
        out = np.empty(len(flat), dtype=np.bool_)
        if self.static_hit:
            out[:] = False
        else:
            K.check_batch(flat, self.data, self._scratch, self._scales, out, False)
        return out.reshape(q.shape[:-1])

    def single_test(self) -> Callable[[np.ndarray], bool]:
        """A test ``free(q) -> bool`` of one configuration q (dof,) float64, as :meth:`is_free`
        but with nothing checked and the arrays bound once: for callbacks from other libraries
        (OMPL's state validity), where the per-call cost counts (half that of ``is_free``). The
        test is compiled (or loaded from numba's cache) here, before any caller's clock starts."""
        if self.static_hit:
            return lambda q: False
        data, scratch, scales = self.data, self._scratch, self._scales
        K.free_one(np.zeros(self.model.dof), data, scratch, scales)
        return lambda q: K.free_one(q, data, scratch, scales)

    def clearance(self, q: np.ndarray, cap: float = np.inf, self_pairs: bool = True) -> np.ndarray:
        """(*batch,) smallest distance (m) between a ball and an obstacle or (if ``self_pairs``)
        a ball of a non-allowed link, for q (*batch, dof); values above ``cap`` come back as ``cap``.

        Negative means a collision (the value is then some negative distance, not the depth).
        Balls on the root body are not measured against the world (they never move; see
        :attr:`static_hit`).
        """
        q, flat = self._batch(q)
        data, scales = (self.data, self._scales) if self_pairs else self._world_only
        out = np.empty(len(flat))
        if self.static_hit:
            out[:] = -np.inf
        else:
            K.clearance_batch(flat, data, self._scratch, float(cap), scales, out)
        return out.reshape(q.shape[:-1])

    def screen(self, q: np.ndarray, margin: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(inside, free, near), each (*batch,) bool, for q (*batch, dof): ``inside``: within the
        joint limits (as :meth:`RobotModel.within_limits`), ``free`` as :meth:`is_free`, ``near``:
        some ball is closer than ``margin`` (m) to an obstacle (as ``clearance(q, self_pairs=False)
        < margin``); one compiled call for the three, the tests a planner runs on a path's ends."""
        q, flat = self._batch(q)
        inside, free, near = (np.empty(len(flat), dtype=np.bool_) for _ in range(3))
        lower, upper, scales, world_scales = self.screening
        K.screen_batch(flat, lower, upper, self.data, self._scratch, scales, world_scales, float(margin), inside, free,
                       near)
        if self.static_hit:
            free[:], near[:] = False, True
        return inside.reshape(q.shape[:-1]), free.reshape(q.shape[:-1]), near.reshape(q.shape[:-1])

    def first_collision(self, q_path: np.ndarray) -> int:
        """Index of the first colliding configuration of q_path (N, dof), or -1 if all are free.

        Checks in order and stops at the first collision (an edge check for planners: pass
        the interpolated configurations of the edge).
        """
        q_path = self.model.check_configuration(q_path, "q_path")
        if q_path.ndim != 2:
            raise PrehensileError(f"q_path: expected shape (N, {self.model.dof}), got {q_path.shape}")
        if self.static_hit:
            return 0 if len(q_path) else -1
        out = np.empty(len(q_path), dtype=np.bool_)
        return int(K.check_batch(np.ascontiguousarray(q_path), self.data, self._scratch, self._scales, out, True))
