"""FABRIK iteration counts, success and limit compliance (Aristidou & Lasenby 2011, Bischoff 2016).

Run: ``python benchmarks/ik/fabrik_iterations.py [--targets 1000] [--seed 0] [--out FILE]``.

1. AL11 comparison chain: AL11 report a mean of 15.5 iterations for a chain of 10 joints. We
   build a URDF-free chain of 10 ball joints (each a universal joint, z then y, unlimited)
   joined by equal 0.1 m links, tip 0.1 m after the last joint (reach 1 m), start straight,
   tolerance 1e-3 of the reach; targets are FK of random configurations ("config") or uniform in
   the reach ball ("ball"). Our solver runs next to AL11 Algorithm 1 on the bare points (the
   reference: on ball joints the two should agree). The brief's alternative, 10 single hinges
   with alternating z/y axes, is reported too.
2. NAO arms, Panda, ARMAR-III: success within 1e-4 m from the default seed, iterations, and
   limit violations of the same solver on a copy of the model without limits
   ("plain_no_limits") against ours; the digest's setup (start (1.4, 0.2, -1.2, -0.5), 1 mm)
   for the NAO left arm; Panda and ARMAR with orientation. And the Bischoff digest's §4.5 check
   itself: 3-point FABRIK on the thesis's simplified NAO arm, angles from the points.
3. Kernel cost per iteration (best of 7 runs of a fixed iteration count).

Writes benchmarks/results/fabrik_iterations.json and prints a summary.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
import time
from pathlib import Path

import numpy as np
from numba import njit

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))
from common import machine  # noqa: E402

from prehensile import robots  # noqa: E402
from prehensile.ik import fabrik as fabrik_module  # noqa: E402
from prehensile.ik.fabrik import FabrikSettings, fabrik  # noqa: E402
from prehensile.kinematics import forward_kinematics  # noqa: E402
from prehensile.model.builder import JointSpec, LinkSpec, build_model  # noqa: E402
from prehensile.model.robot_model import Chain  # noqa: E402
from prehensile.storage import atomic_write_json  # noqa: E402

LINK = 0.1  # m


def _offset(x: float) -> np.ndarray:
    T = np.eye(4)
    T[0, 3] = x
    return T


def comparison_chain(ball: bool, n: int = 10):
    """n ball joints (universal: z then y) or n hinges (alternating z / y), links of LINK m."""
    links, joints, parent = [LinkSpec("base")], [], "base"
    for i in range(n):
        axes = [("z", (0, 0, 1)), ("y", (0, 1, 0))] if ball else [(("z", "y")[i % 2], ((0, 0, 1), (0, 1, 0))[i % 2])]
        for k, (name, axis) in enumerate(axes):
            child = f"l{i}{name}"
            links.append(LinkSpec(child))
            origin = _offset(LINK if i and k == 0 else 0.0)
            joints.append(JointSpec(f"j{i}{name}", "continuous", parent, child, origin, np.array(axis, float)))
            parent = child
    links.append(LinkSpec("tip"))
    joints.append(JointSpec("tip_joint", "fixed", parent, "tip", _offset(LINK)))
    name = "ball10" if ball else "hinge10"
    return build_model(name, f"<{name}>", links, joints, [Chain("arm", "base", "tip", ())])


@njit(cache=True)
def point_fabrik(points, target, tol, max_iterations):
    """AL11 Algorithm 1 on bare points (m + 1, 3), in place; returns the iterations used."""
    m = points.shape[0] - 1
    d = np.empty(m)
    for i in range(m):
        d[i] = np.sqrt(np.sum((points[i + 1] - points[i]) ** 2))
    base = points[0].copy()
    iterations = 0
    while np.sqrt(np.sum((points[m] - target) ** 2)) > tol and iterations < max_iterations:
        iterations += 1
        points[m] = target
        for i in range(m - 1, -1, -1):
            lam = d[i] / np.sqrt(np.sum((points[i + 1] - points[i]) ** 2))
            points[i] = (1 - lam) * points[i + 1] + lam * points[i]
        points[0] = base
        for i in range(m):
            lam = d[i] / np.sqrt(np.sum((points[i + 1] - points[i]) ** 2))
            points[i + 1] = (1 - lam) * points[i] + lam * points[i + 1]  # p_{i+1}, as in AL11
    return iterations


def stats(iterations: np.ndarray, success: np.ndarray) -> dict:
    ok = iterations[success]
    return {"success_rate": float(success.mean()), "mean_iterations": float(ok.mean()) if ok.size else None,
            "median_iterations": float(np.median(ok)) if ok.size else None,
            "p90_iterations": float(np.percentile(ok, 90)) if ok.size else None}


def comparison(n_targets: int, rng: np.random.Generator) -> dict:
    out = {}
    for ball in (True, False):
        model = comparison_chain(ball)
        tip = model.link_index("tip")
        reach, tol = 10 * LINK, 1e-3 * 10 * LINK
        settings = FabrikSettings(tolerance=tol, max_iterations=1000, stall_iterations=1000)
        q0 = model.neutral_configuration()
        frames = forward_kinematics(model, q0)
        joint_links = [model.link_index(f"l{i}z" if ball else f"l{i}{('z', 'y')[i % 2]}") for i in range(10)]
        seed_points = frames[joint_links + [tip], :3, 3]
        kinds = {"config": forward_kinematics(model, model.random_configurations(rng, n_targets))[:, tip, :3, 3]}
        if ball:
            direction = rng.normal(size=(n_targets, 3))
            direction /= np.linalg.norm(direction, axis=1, keepdims=True)
            kinds["ball"] = direction * reach * rng.uniform(0, 1, (n_targets, 1)) ** (1 / 3)
        for kind, targets in kinds.items():
            ours = [fabrik(model, "arm", t, q_seed=q0, settings=settings) for t in targets]
            row = {"ours": stats(np.array([r.iterations for r in ours]), np.array([r.success for r in ours]))}
            if ball:
                its = np.array([point_fabrik(seed_points.copy(), t, tol, 1000) for t in targets])
                row["al11_points"] = stats(its, its < 1000)
            out[f"{model.name}/{kind}"] = row
    return out


def robot_case(name: str, chain: str, n_targets: int, rng: np.random.Generator, orientation: bool = False,
               seed: dict | None = None, tolerance: float = 1e-4) -> dict:
    model = robots.load(name)
    plain = dataclasses.replace(model, lower=np.full(model.dof, -np.inf), upper=np.full(model.dof, np.inf))
    qi = model.chain_q_indices(chain)
    q = np.tile(model.neutral_configuration(), (n_targets, 1))
    q[:, qi] = model.random_configurations(rng, n_targets)[:, qi]
    poses = forward_kinematics(model, q)[:, model.link_index(model.chain(chain).tip_link)]
    if seed is None:  # fabrik's default seed, given explicitly so that both solvers start there
        q_seed = model.neutral_configuration()
        q_seed[qi] = 0.5 * (model.lower[qi] + model.upper[qi])
    else:
        q_seed = model.configuration_from_dict(seed)
    settings = FabrikSettings(tolerance=tolerance)
    rows = {}
    for label, solver_model in (("ours", model), ("plain_no_limits", plain)):
        start = time.perf_counter()
        results = [fabrik(solver_model, chain, T[:3, 3], q_seed=q_seed, settings=settings,
                          target_orientation=T[:3, :3] if orientation else None) for T in poses]
        elapsed = time.perf_counter() - start
        row = stats(np.array([r.iterations for r in results]), np.array([r.success for r in results]))
        row["limit_violations"] = int(np.sum(~model.within_limits(np.array([r.q for r in results]))))
        row["ms_per_solve"] = elapsed / n_targets * 1e3
        rows[label] = row
    return {"chain": chain, "targets": n_targets, "orientation": orientation, "tolerance_m": tolerance,
            "seed": seed or "default (chain joints mid-range)", **rows}


def _rot(axis: int, angle: float) -> np.ndarray:
    c, s = np.cos(angle), np.sin(angle)
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    R = np.eye(3)
    R[i, i], R[i, j], R[j, i], R[j, j] = c, -s, s, c
    return R


def digest_point_fabrik(n_targets: int, rng: np.random.Generator) -> dict:
    """The Bischoff digest's §4.5 check: 3-point FABRIK (shoulder, elbow, hand) on the thesis's
    simplified NAO left arm, no limit handling, start (1.4, 0.2, -1.2, -0.5), 1 mm, angles from
    the points by the digest's formulas; counts solutions outside the NAO limits."""
    nao = robots.load("nao")
    qi = nao.chain_q_indices("left_arm")
    lower, upper = nao.lower[qi], nao.upper[qi]
    S, upper_arm, lower_arm = np.array([0.0, 0.113, 0.100]), 0.105, 0.1137

    def points(q):
        R1 = _rot(1, q[0]) @ _rot(2, q[1])
        E = S + R1 @ [upper_arm, 0, 0]
        return np.array([S, E, E + R1 @ _rot(0, q[2]) @ _rot(2, q[3]) @ [lower_arm, 0, 0]])

    start = points(np.array([1.4, 0.2, -1.2, -0.5]))
    its, success, violations = [], 0, 0
    for q in rng.uniform(lower, upper, (n_targets, 4)):
        p = start.copy()
        target = points(q)[2]
        its.append(point_fabrik(p, target, 1e-3, 1000))
        u = (p[1] - p[0]) / np.linalg.norm(p[1] - p[0])
        f = (p[2] - p[1]) / np.linalg.norm(p[2] - p[1])
        t1, t2, t4 = np.arctan2(-u[2], u[0]), np.arcsin(u[1]), -np.arccos(np.clip(u @ f, -1, 1))
        f_local = (_rot(1, t1) @ _rot(2, t2)).T @ f
        angles = np.array([t1, t2, np.arctan2(-f_local[2], -f_local[1]), t4])
        success += np.linalg.norm(points(angles)[2] - target) <= 1e-3
        violations += not np.all((angles >= lower) & (angles <= upper))
    return {"targets": n_targets, "success_rate": success / n_targets, "mean_iterations": float(np.mean(its)),
            "median_iterations": float(np.median(its)), "limit_violations": int(violations)}


def us_per_iteration(name: str, chain: str, iterations: int = 2000) -> float:
    """Kernel time per iteration (us) toward a far target (no early stop), best of 7."""
    model = robots.load(name)
    base, table, joint_link, joint_q, lower, upper = fabrik_module._pack(model, chain)
    q0 = model.neutral_configuration()
    T_base = forward_kinematics(model, q0)[base]
    target = T_base[:3, 3] + np.array([0.05, 0.02, 0.01])
    times = []
    for _ in range(7):
        q = q0.copy()
        start = time.perf_counter()
        fabrik_module.solve_chain(q, T_base, table, joint_link, joint_q, lower, upper, target, np.eye(3), False, 0.25,
                                  0.0, 1.0, iterations, iterations)
        times.append(time.perf_counter() - start)
    return min(times) / iterations * 1e6


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", type=int, default=1000)
    parser.add_argument("--seed", type=int, default=0)
    default_out = Path(__file__).resolve().parents[1] / "results" / "fabrik_iterations.json"
    parser.add_argument("--out", type=Path, default=default_out)
    args = parser.parse_args()
    rng = np.random.default_rng(args.seed)
    n = args.targets
    digest_seed = {"LShoulderPitch": 1.4, "LShoulderRoll": 0.2, "LElbowYaw": -1.2, "LElbowRoll": -0.5}
    result = {
        "benchmark": "fabrik_iterations", "seed": args.seed, "machine": machine(),
        "al11_comparison": comparison(n, rng),
        "robots": {
            "nao/left_arm": robot_case("nao", "left_arm", n, rng),
            "nao/right_arm": robot_case("nao", "right_arm", n, rng),
            "nao/left_arm digest setup": robot_case("nao", "left_arm", 300, rng, seed=digest_seed, tolerance=1e-3),
            "panda/arm": robot_case("panda", "arm", n, rng),
            "armar3/TorsoRightArm": robot_case("armar3", "TorsoRightArm", n, rng),
            "panda/arm orientation": robot_case("panda", "arm", n, rng, orientation=True),
            "armar3/TorsoRightArm orientation": robot_case("armar3", "TorsoRightArm", n, rng, orientation=True),
        },
        "nao_digest_point_fabrik": digest_point_fabrik(300, rng),
        "us_per_iteration": {f"{r}/{c}": us_per_iteration(r, c) for r, c in
                             (("nao", "left_arm"), ("panda", "arm"), ("armar3", "TorsoRightArm"))},
    }
    print(f"{'case':42} {'solver':16} {'success':>8} {'mean it':>8} {'median':>7} {'p90':>6} {'viol':>5}")
    for group in ("al11_comparison", "robots"):
        for case, rows in result[group].items():
            for solver, row in rows.items():
                if solver in ("ours", "plain_no_limits", "al11_points"):
                    print(f"{case:42} {solver:16} {row['success_rate']:8.3f} {row['mean_iterations'] or 0:8.1f} "
                          f"{row['median_iterations'] or 0:7.0f} {row['p90_iterations'] or 0:6.0f} "
                          f"{row.get('limit_violations', ''):>5}")
    row = result["nao_digest_point_fabrik"]
    print(f"{'nao/left_arm digest 3-point FABRIK':42} {'no limits':16} {row['success_rate']:8.3f} "
          f"{row['mean_iterations']:8.1f} {row['median_iterations']:7.0f} {'':6} {row['limit_violations']:>5}")
    for chain, us in result["us_per_iteration"].items():
        print(f"{chain:42} {us:.2f} us per iteration")
    atomic_write_json(args.out, result)
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
