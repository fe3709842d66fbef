"""J+-RRT: a unidirectional RRT toward a workspace goal, grown by Jacobian steps.

Vahrenkamp 2011 §4.1 (Alg. 13-15). The tree grows from the start by ordinary RRT steps; with
probability ``goal_probability`` a random grasp g is picked and the tree node whose tool pose
is nearest to g's target pose (SE(3) metric, §2.2) among the nodes not yet marked for g is
pulled toward it by pseudoinverse steps, ``c' = c + J^+(c) clamp(Δp)``, each new
configuration joining the tree. A blocked step (collision or joint limit) marks the node for
g, so that the same node is not pulled toward the same grasp again. No IK solver is needed;
the goal is reached when the tool is within the tolerances of a grasp pose.

The search loop runs in Python over compiled pieces (tool pose and Jacobian, motion checks);
the returned path is shortcut and certified with the exact geometry like every planner's.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from prehensile.errors import PrehensileError
from prehensile.ik import kernels as ik_kernels
from prehensile.ik.jacobian import ChainSolver
from prehensile.planning.context import PlanningContext
from prehensile.planning.finish import finish_path
from prehensile.planning.result import PlanResult, PlanStats, PlanStatus


@dataclass(frozen=True)
class JPlusRRTSettings:
    """Settings of :func:`jplus_rrt`.

    Attributes:
        time_budget_s: search budget (s).
        step: RRT extension step in the workspace-weighted metric (m).
        goal_probability: chance per iteration of an extension toward a grasp (r_ExtendToGoal).
        max_step_position, max_step_rotation: Cartesian step clamp of a Jacobian step (m, rad).
        position_tolerance, rotation_tolerance: goal reached (m, rad).
        rotation_weight: m per rad in the SE(3) metric of the nearest-node search.
        max_goal_steps: Jacobian steps per extension toward a grasp.
        max_nodes: tree capacity.
        shortcut_iterations: random shortcuts of the found path.
        certify: certify the path with the exact geometry before returning it.
    """

    time_budget_s: float = 5.0
    step: float = 0.05
    goal_probability: float = 0.2
    max_step_position: float = 0.03
    max_step_rotation: float = 0.15
    position_tolerance: float = 1e-3
    rotation_tolerance: float = 1e-2
    rotation_weight: float = 0.1
    max_goal_steps: int = 200
    max_nodes: int = 100_000
    shortcut_iterations: int = 100
    certify: bool = True


class _Tree:
    """Nodes (N, dof) with parents, tool poses and per-grasp marks, in growing arrays."""

    def __init__(self, q_start: np.ndarray, tool: np.ndarray, n_grasps: int, capacity: int) -> None:
        self.q = np.empty((capacity, len(q_start)))
        self.parent = np.empty(capacity, dtype=np.int64)
        self.tool = np.empty((capacity, 4, 4))
        self.marked = np.zeros((capacity, n_grasps), dtype=bool)
        self.count = 0
        self.add(q_start, -1, tool)

    def add(self, q: np.ndarray, parent: int, tool: np.ndarray) -> int:
        if self.count == len(self.q):
            raise IndexError("tree full")
        i = self.count
        self.q[i], self.parent[i], self.tool[i] = q, parent, tool
        self.count += 1
        return i

    def path_to(self, i: int) -> np.ndarray:
        nodes = []
        while i >= 0:
            nodes.append(self.q[i])
            i = int(self.parent[i])
        return np.array(nodes[::-1])


def jplus_rrt(ctx: PlanningContext, q_start: np.ndarray, target_poses: np.ndarray, T_tip_tcp: np.ndarray | None = None,
              settings: JPlusRRTSettings = JPlusRRTSettings(), rng: np.random.Generator | int | None = None) -> PlanResult:
    """Plan from ``q_start`` until the tool reaches any of ``target_poses``.

    Args:
        ctx: planning context; its planned joints must be one chain of the model (the tool's).
        q_start: (dof,) start configuration.
        target_poses: (k, 4, 4) world tool poses, e.g. ``T_world_object @ grasps``.
        T_tip_tcp: (4, 4) tool frame on the chain's tip link.

    Returns:
        :class:`PlanResult`; ``goal_index`` is the grasp reached.
    """
    start_time = time.perf_counter()
    rng = np.random.default_rng(rng)
    solver = _chain_solver(ctx, T_tip_tcp)
    targets = solver.targets(target_poses)
    q_start = np.array(ctx.model.check_configuration(q_start, "q_start"), dtype=float)
    counted = int(ctx.counters[0])
    if not ctx.is_valid(q_start):
        return _result(PlanStatus.INVALID_START, ctx, None, 0, 0, counted, start_time)
    s = settings
    tree = _Tree(q_start, solver.tool_pose(q_start), len(targets), s.max_nodes)
    idx, w = ctx.space.indices, ctx.space.weights
    lower, upper = ctx.space.lower, ctx.space.upper
    pose, jac = np.empty((4, 4)), np.empty((6, solver.n))
    frames, err = np.empty((len(solver.table), 3, 4)), np.empty(6)

    def tool_and_jacobian(q):
        ik_kernels.chain_pose_jacobian(q, solver.T_world_root, solver.table, solver.var_of_q, solver.T_tip_tcp,
                                       frames, pose, jac)
        return pose.copy()

    iterations = 0
    try:
        while time.perf_counter() - start_time < s.time_budget_s:
            iterations += 1
            if rng.random() >= s.goal_probability:  # ordinary RRT extension
                sample = rng.uniform(lower, upper)
                near = _nearest(tree, idx, w, sample)
                step = sample - tree.q[near, idx]
                length = float(w @ np.abs(step))
                if length == 0.0:
                    continue
                q_new = tree.q[near].copy()
                q_new[idx] += step * min(1.0, s.step / length)
                if ctx.check_motion(tree.q[near], q_new):
                    tree.add(q_new, near, solver.tool_pose(q_new))
                continue
            g = int(rng.integers(len(targets)))
            node = _nearest_pose(tree, g, targets[g], s.rotation_weight)
            if node < 0:
                continue
            for _ in range(s.max_goal_steps):  # ExtendToGoal
                q = tree.q[node]
                tool_and_jacobian(q)
                ik_kernels.pose_error(targets[g], pose, err)
                pos_err, rot_err = np.linalg.norm(err[:3]), np.linalg.norm(err[3:])
                if pos_err <= s.position_tolerance and rot_err <= s.rotation_tolerance:
                    path = tree.path_to(node)
                    return _finish(ctx, path, rng, s, iterations, tree.count, counted, start_time, g)
                err[:3] *= min(1.0, s.max_step_position / max(pos_err, 1e-300))
                err[3:] *= min(1.0, s.max_step_rotation / max(rot_err, 1e-300))
                q_new = q.copy()
                q_new[idx] = q[idx] + np.linalg.pinv(jac) @ err
                if np.any(q_new[idx] < lower) or np.any(q_new[idx] > upper) or not ctx.check_motion(q, q_new):
                    tree.marked[node, g] = True
                    break
                node = tree.add(q_new, node, tool_and_jacobian(q_new))
                tree.marked[node, g] = True
    except IndexError:  # the tree is full: report like a timeout
        pass
    return _result(PlanStatus.TIMEOUT, ctx, None, iterations, tree.count, counted, start_time)


def _chain_solver(ctx: PlanningContext, T_tip_tcp: np.ndarray | None) -> ChainSolver:
    """The solver of the chain whose joints the context plans."""
    for name, chain in ctx.model.chains.items():
        joints = np.array([ctx.model.joint_index(j) for j in chain.joint_names], dtype=np.int64)
        if np.array_equal(np.sort(joints), np.sort(ctx.space.indices)):
            return ChainSolver(ctx.model, name, T_tip_tcp=T_tip_tcp, T_world_root=ctx.T_world_base)
    raise PrehensileError(f"J+-RRT: the planned joints {ctx.space.joint_names} are not a chain of "
                          f"'{ctx.model.name}'; chains: {', '.join(ctx.model.chains)}")


def _nearest(tree: _Tree, idx: np.ndarray, w: np.ndarray, sample: np.ndarray) -> int:
    """Index of the node nearest to ``sample`` (n,) in the workspace-weighted metric."""
    return int(np.argmin(np.abs(tree.q[:tree.count][:, idx] - sample) @ w))


def _nearest_pose(tree: _Tree, g: int, target: np.ndarray, rotation_weight: float) -> int:
    """Node not marked for grasp g whose tool pose is nearest to ``target`` (4, 4) in the SE(3)
    metric ``|Δt| + rotation_weight * angle`` (Vahrenkamp A.3.2); -1 if all are marked."""
    tools = tree.tool[:tree.count]
    cos = np.clip((np.einsum("nij,ij->n", tools[:, :3, :3], target[:3, :3]) - 1.0) / 2.0, -1.0, 1.0)
    d = np.linalg.norm(tools[:, :3, 3] - target[:3, 3], axis=1) + rotation_weight * np.arccos(cos)
    d[tree.marked[:tree.count, g]] = np.inf
    i = int(np.argmin(d))
    return i if np.isfinite(d[i]) else -1


def _finish(ctx, path, rng, s, iterations, nodes, counted, start_time, goal_index) -> PlanResult:
    plan_time = time.perf_counter() - start_time
    status, path, simplify_time, certify_time = finish_path(ctx, path, rng, s.shortcut_iterations, s.certify)
    stats = PlanStats(iterations, nodes, int(ctx.counters[0]) - counted, 0, plan_time, simplify_time, certify_time)
    return PlanResult(status, path if status is PlanStatus.SUCCESS else np.zeros((0, ctx.model.dof)), stats,
                      goal_index if status is PlanStatus.SUCCESS else -1)


def _result(status, ctx, path, iterations, nodes, counted, start_time) -> PlanResult:
    stats = PlanStats(iterations, nodes, int(ctx.counters[0]) - counted, 0, time.perf_counter() - start_time)
    return PlanResult(status, np.zeros((0, ctx.model.dof)), stats)
