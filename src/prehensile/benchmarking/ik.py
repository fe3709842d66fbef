"""IK benchmark: our solvers and the peers on the same reachable targets of any chain.

Problem: ``n`` configurations of the chain's joints drawn uniformly within their limits (the
other joints neutral, seeded generator); their tool poses are the targets, so every target is
reachable. Every solver starts each target from the same configuration (the model's neutral
one) and gets ``time_budget_s`` per target where it takes a budget (restarts are seeded per
target, so a target's outcome does not depend on the others).

Success is decided here, not by the solver: the returned configuration must lie within the
joint limits and its tool pose, by our forward kinematics, must be within
``position_tolerance`` (m) and ``rotation_tolerance`` (rad, angle of the rotation between
target and reached orientation) of the target; FABRIK is checked on the position only and
marked ``position_only``. Times are wall clock per call, over all targets (solved or not);
``within_budget_rate`` counts the solved targets whose call also ended within the budget.
Ratios are our time / the peer's on the same targets (below 1: ours faster); ikpy, which
takes tens of milliseconds per call, runs on the first ``ikpy_targets`` targets only and its
ratios compare our times on that subset.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass
from typing import Callable

import numpy as np

from prehensile.benchmarking.ik_peers import PEERS, joint_values, make_peer
from prehensile.benchmarking.stats import machine, mean_or_none, median_seconds, ratio, time_summary, versions
from prehensile.errors import PrehensileError
from prehensile.ik import ChainSolver, CompleteIKSettings, JacobianIKSettings, solve_ik_complete
from prehensile.ik.analytic_nao import nao_arm_ik, nao_arm_ik_batch
from prehensile.ik.fabrik import FabrikSettings, fabrik
from prehensile.model.robot_model import RobotModel
from prehensile.spatial.transforms import rotation_error

JACOBIAN_METHODS = ("dls", "pinv", "transpose")
METHODS = JACOBIAN_METHODS + ("fabrik", "analytic")
POSITION_ONLY = ("fabrik",)

Solve = Callable[[np.ndarray, int], tuple[np.ndarray, int | None]]
Progress = Callable[[str, int, int], None]


@dataclass(frozen=True)
class IKBenchSettings:
    """Benchmark settings.

    Attributes:
        n: number of targets.
        methods: our solvers, from :data:`METHODS`.
        peers: peer solvers, from :data:`~prehensile.benchmarking.ik_peers.PEERS`.
        seed: seed of the targets and of every solver's restarts.
        time_budget_s: time budget per target (s) of the solvers that take one.
        ikpy_targets: ikpy runs on the first min(n, ikpy_targets) targets.
        position_tolerance: success tolerance (m), also given to every solver that takes one.
        rotation_tolerance: success tolerance (rad), likewise.
    """

    n: int = 10_000
    methods: tuple[str, ...] = ("dls",)
    peers: tuple[str, ...] = PEERS
    seed: int = 0
    time_budget_s: float = 0.005
    ikpy_targets: int = 200
    position_tolerance: float = 1e-4
    rotation_tolerance: float = 1e-3

    def __post_init__(self) -> None:
        for what, given, valid in (("method", self.methods, METHODS), ("peer", self.peers, PEERS)):
            unknown = [name for name in given if name not in valid]
            if unknown:
                raise PrehensileError(f"unknown {what} {', '.join(unknown)}; valid: {', '.join(valid)}")
        if not self.methods and not self.peers:
            raise PrehensileError("nothing to benchmark: give at least one method or peer")
        if self.n < 1 or self.ikpy_targets < 1:
            raise PrehensileError(f"n and ikpy_targets must be >= 1, got {self.n} and {self.ikpy_targets}")
        for name in ("time_budget_s", "position_tolerance", "rotation_tolerance"):
            if not getattr(self, name) > 0:
                raise PrehensileError(f"{name} must be positive, got {getattr(self, name)}")


@dataclass(frozen=True, eq=False)  # holds arrays: compared by identity
class IKProblem:
    """The benchmark's targets on one chain.

    Attributes:
        model: the robot; contains ``chain`` under ``chain.name``.
        solver: our chain solver, also the forward kinematics of the success check.
        q_start: (dof,) the start configuration of every solve (neutral).
        q_sampled: (n, dof) the configurations the targets were made from.
        targets: (n, 4, 4) tool poses in the model root frame.
        seeds: (n,) restart seed of each target.
    """

    model: RobotModel
    solver: ChainSolver
    q_start: np.ndarray
    q_sampled: np.ndarray
    targets: np.ndarray
    seeds: np.ndarray

    @property
    def chain(self):
        return self.solver.chain


def make_problem(model: RobotModel, base: str, tip: str, n: int, seed: int) -> IKProblem:
    """Reachable targets for the chain ``base`` -> ``tip`` (see the module docstring)."""
    solver = ChainSolver(model, base=base, tip=tip)
    model = _with_chain(model, solver.chain)
    solver = ChainSolver(model, _chain_name(model, solver.chain))
    rng = np.random.default_rng(seed)
    q_start = model.neutral_configuration()
    q_sampled = np.repeat(q_start[None], n, axis=0)
    q_sampled[:, solver.var_q] = rng.uniform(solver.lower, solver.upper, size=(n, solver.n))
    seeds = rng.integers(0, 2**31 - 1, size=n)
    return IKProblem(model, solver, q_start, q_sampled, solver.tool_pose(q_sampled), seeds)


def _chain_name(model: RobotModel, chain) -> str:
    """Name of a model chain with the same base, tip and joints as ``chain``, else ''."""
    for name, other in model.chains.items():
        if (other.base_link, other.tip_link, other.joint_names) == (chain.base_link, chain.tip_link, chain.joint_names):
            return name
    return ""


def _with_chain(model: RobotModel, chain) -> RobotModel:
    """``model``, with ``chain`` added under its name unless the model already has it (the
    analytic and FABRIK solvers take chain names)."""
    if _chain_name(model, chain):
        return model
    return dataclasses.replace(model, chains={**model.chains, chain.name: chain})


def _ours(problem: IKProblem, method: str, settings: IKBenchSettings) -> Solve:
    """A solve function (target, seed) -> (q, iterations) for one of our methods."""
    model, chain, q0 = problem.model, problem.chain, problem.q_start
    if method in JACOBIAN_METHODS:
        solver = ChainSolver(model, chain.name, settings=JacobianIKSettings(
            method=method, position_tolerance=settings.position_tolerance,
            rotation_tolerance=settings.rotation_tolerance))
        budget = CompleteIKSettings(time_budget_s=settings.time_budget_s)

        def solve(target: np.ndarray, seed: int) -> tuple[np.ndarray, int]:
            result = solve_ik_complete(solver, target, q0, rng=seed, settings=budget)
            return result.q, result.iterations

    elif method == "fabrik":
        fabrik_settings = FabrikSettings(tolerance=settings.position_tolerance)

        def solve(target: np.ndarray, seed: int) -> tuple[np.ndarray, int]:
            result = fabrik(model, chain.name, target[:3, 3], q_seed=q0, settings=fabrik_settings)
            return result.q, result.iterations

    else:
        tolerance = (settings.position_tolerance, settings.rotation_tolerance)

        def solve(target: np.ndarray, seed: int) -> tuple[np.ndarray, int]:
            return nao_arm_ik(model, chain.name, target, q0, tolerance).q, None

    return solve


def _measure(problem: IKProblem, solve: Solve, indices: np.ndarray, budget: float,
             progress: Callable[[int], None] | None) -> dict:
    """Time ``solve`` on the targets ``indices`` (after one untimed warm-up call)."""
    solve(problem.targets[indices[0]], int(problem.seeds[indices[0]]))
    q = np.empty((len(indices), problem.model.dof))
    seconds, iterations = np.empty(len(indices)), []
    for k, i in enumerate(indices):
        start = time.perf_counter()
        q[k], its = solve(problem.targets[i], int(problem.seeds[i]))
        seconds[k] = time.perf_counter() - start
        if its is not None:
            iterations.append(its)
        if progress is not None and (k % 50 == 49 or k == len(indices) - 1):
            progress(k + 1)
    return {"q": q, "seconds": seconds, "iterations": iterations, "over_budget": seconds > budget}


def verify(problem: IKProblem, q: np.ndarray, indices: np.ndarray, position_only: bool,
           settings: IKBenchSettings) -> np.ndarray:
    """(k,) bool: q (k, dof) is within the limits and reaches targets[indices] by our FK."""
    reached = problem.solver.tool_pose(q)
    target = problem.targets[indices]
    ok = problem.model.within_limits(q)
    ok &= np.linalg.norm(reached[:, :3, 3] - target[:, :3, 3], axis=1) <= settings.position_tolerance
    if not position_only:
        angle = np.linalg.norm(rotation_error(target[:, :3, :3], reached[:, :3, :3]), axis=1)
        ok &= angle <= settings.rotation_tolerance
    return ok


def _summary(problem: IKProblem, run: dict, indices: np.ndarray, kind: str, position_only: bool,
             settings: IKBenchSettings) -> dict:
    ok = verify(problem, run["q"], indices, position_only, settings)
    return {
        "kind": kind,
        "targets": int(len(indices)),
        "solved": int(ok.sum()),
        "success_rate": float(ok.mean()),
        "within_budget_rate": float((ok & ~run["over_budget"]).mean()),
        **time_summary(run["seconds"]),
        "iterations": mean_or_none(run["iterations"]),
        "position_only": position_only,
    }


def _analytic_batch(problem: IKProblem, settings: IKBenchSettings) -> dict:
    """All solutions of every target in one compiled call: time per target and FK check of
    every returned solution."""
    tolerance = (settings.position_tolerance, settings.rotation_tolerance)
    name, targets = problem.chain.name, problem.targets
    seconds = median_seconds(lambda: nao_arm_ik_batch(problem.model, name, targets, tolerance), repeats=5)
    solutions, counts = nao_arm_ik_batch(problem.model, name, targets, tolerance)
    rows, slots = np.nonzero(np.arange(solutions.shape[1])[None] < counts[:, None])
    q = np.repeat(problem.q_start[None], len(rows), axis=0)
    q[:, problem.solver.var_q] = solutions[rows, slots]
    ok = verify(problem, q, rows, False, settings)
    return {"us_per_target": seconds / len(targets) * 1e6, "success_rate": float(np.mean(counts > 0)),
            "solutions_mean": float(counts.mean()), "solutions_verified": float(ok.mean()) if len(ok) else None}


def run_ik_bench(model: RobotModel, base: str, tip: str, settings: IKBenchSettings = IKBenchSettings(),
                 progress: Progress | None = None) -> dict:
    """Run the benchmark (module docstring) and return its JSON-ready report.

    Args:
        model: the robot; the peers need it loaded from a URDF.
        base, tip: links of the chain (its actuated joints between them are solved for).
        settings: :class:`IKBenchSettings`.
        progress: called as ``progress(solver name, done, total)``.

    Raises:
        PrehensileError: unknown links, methods or peers; a method or peer that cannot handle
            the chain (analytic on a non-NAO arm, a peer on a non-URDF model).
    """
    problem = make_problem(model, base, tip, settings.n, settings.seed)
    everything = np.arange(settings.n)
    runs, methods = {}, {}
    solvers = [(m, "ours", everything, _ours(problem, m, settings)) for m in settings.methods]
    for name in settings.peers:
        peer = make_peer(name, problem.model, problem.chain, problem.q_start, settings.position_tolerance,
                         settings.rotation_tolerance)
        indices = everything[:settings.ikpy_targets] if name == "ikpy" else everything
        solvers.append((name, "peer", indices, lambda target, seed, peer=peer: peer.solve(
            target, settings.time_budget_s, seed)))
    for name, kind, indices, solve in solvers:
        tick = None if progress is None else (lambda done, name=name, total=len(indices): progress(name, done, total))
        runs[name] = _measure(problem, solve, indices, settings.time_budget_s, tick)
        methods[name] = _summary(problem, runs[name], indices, kind, name in POSITION_ONLY, settings)
    if "ikpy" in methods:
        methods["ikpy"]["note"] = f"first {len(runs['ikpy']['seconds'])} targets only (ikpy is slow and takes no time budget)"
    if "analytic" in methods:
        methods["analytic"]["batch"] = _analytic_batch(problem, settings)
    ratios = {}
    for name in settings.methods:
        ours = runs[name]["seconds"]
        entry = {}
        if "pinocchio" in runs:
            peer = runs["pinocchio"]["seconds"]
            entry["mean_vs_pinocchio"] = ratio(ours.mean(), peer.mean())
            entry["median_vs_pinocchio"] = ratio(np.median(ours), np.median(peer))
        if "ikpy" in runs:
            peer = runs["ikpy"]["seconds"]
            entry["mean_vs_ikpy_subset"] = ratio(ours[:len(peer)].mean(), peer.mean())
        ratios[name] = entry
    chain = problem.chain
    return {
        "robot": model.name,
        "source": str(model.source),
        "chain": {"name": chain.name, "base": chain.base_link, "tip": chain.tip_link,
                  "joints": list(chain.joint_names)},
        "n": settings.n,
        "seed": settings.seed,
        "time_budget_s": settings.time_budget_s,
        "tolerance": {"position_m": settings.position_tolerance, "rotation_rad": settings.rotation_tolerance},
        "start": {j: v for j, v in joint_values(problem.model, problem.q_start).items() if j in chain.joint_names},
        "methods": methods,
        "ratios": ratios,
        "machine": machine(),
        "versions": versions(),
    }
