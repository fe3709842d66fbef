"""Exact certification with and without covering-ball bounds on MotionBenchMaker Panda paths.

Plans each problem with RRT-Connect on MBM's balls (certification off), then certifies the
path twice with the exact certifier: with the padded (covering) balls as distance bounds, and
with coal alone. Both verdicts must agree. Reports medians of time, coal queries and measured
configurations, and the median per-path speed-up, as JSON.

    NUMBA_NUM_THREADS=1 python benchmarks/mbm/certify_bounds.py --limit 8
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from prehensile import robots
from prehensile.benchmarking.mbm import MBMSettings, PreparedProblem, benchmark_spheres, load_problems
from prehensile.benchmarking.stats import machine, versions
from prehensile.planning import RRTConnectSettings, rrt_connect
from prehensile.planning.certify import ExactCertifier
from prehensile.storage import atomic_write_json

MBM = Path(__file__).resolve().parents[2].parent / "shared" / "bench" / "mbm" / "panda"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--limit", type=int, default=8, help="problems per scenario")
    parser.add_argument("--json", type=Path, default=Path("benchmarks/results/certify_bounds.json"))
    args = parser.parse_args()
    model = robots.load(str(MBM / "panda.urdf"), str(MBM / "panda.srdf"))
    spheres = benchmark_spheres(model, MBM / "panda_spherized.urdf")
    settings = MBMSettings(time_budget_s=2.0)
    rows = []
    for number, problem in enumerate(load_problems(MBM / "problems.tar.bz2", model, args.limit)):
        prepared = PreparedProblem(model, spheres, problem, settings)
        ctx = prepared.ctx
        result = rrt_connect(ctx, prepared.q_start, prepared.q_goal,
                             RRTConnectSettings(time_budget_s=2.0, certify=False), np.random.default_rng(number))
        if not result.success:
            continue
        coal_only = ExactCertifier(ctx.collision_model, ctx.obstacles, ctx.T_world_base, ctx.acm)
        for _ in range(2):  # the second round is timed warm
            bounded, plain = ctx.certifier.certify(result.path, ctx.certify_resolution), \
                coal_only.certify(result.path, ctx.certify_resolution)
        if bounded.ok != plain.ok:
            raise AssertionError(f"{problem.scenario} {problem.index}: verdicts differ")
        rows.append([bounded.time_s, plain.time_s, bounded.distance_queries, plain.distance_queries,
                     bounded.configurations_checked, plain.configurations_checked])
    a = np.array(rows)
    medians = np.median(a, axis=0)

    def pair(k: int, scale: float = 1.0) -> dict:
        return {"covering_bounds": scale * float(medians[k]), "coal_only": scale * float(medians[k + 1])}

    report = {"paths": len(a), "median_ms": pair(0, 1e3), "median_queries": pair(2), "median_configurations": pair(4),
              "paired_median_speedup": float(np.median(a[:, 1] / a[:, 0])), "machine": machine(),
              "versions": versions()}
    atomic_write_json(args.json, report)
    print({k: v for k, v in report.items() if k not in ("machine", "versions")})


if __name__ == "__main__":
    main()
