"""OMPL's RRT-Connect alone on the MotionBenchMaker Panda problems at a fixed joint-space segment.

`prehensile bench mbm --compare-ompl` gives OMPL the segment length of our 5 mm workspace
guarantee; this runs OMPL (the same peer, checker, budget and seed) with Euclidean segments of
``--segment`` rad instead (the issue's reference setting: 1/32 rad), checks every path on the
exact meshes as the benchmark does, and writes the per-problem records and their summary.

    NUMBA_NUM_THREADS=1 python benchmarks/mbm/ompl_segment.py --segment 0.03125
"""

from __future__ import annotations

import argparse
import dataclasses
from pathlib import Path

import numpy as np

from prehensile import robots
from prehensile.benchmarking import mbm
from prehensile.benchmarking.stats import machine, versions
from prehensile.storage import atomic_write_json

MBM = Path(__file__).resolve().parents[2].parent / "shared" / "bench" / "mbm" / "panda"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segment", type=float, default=1 / 32, help="OMPL's segment length (rad, Euclidean)")
    parser.add_argument("--budget", type=float, default=5.0, help="search budget per problem (s)")
    parser.add_argument("--limit", type=int, default=0, help="problems per scenario (0: all)")
    parser.add_argument("--json", type=Path, default=Path("benchmarks/results/mbm_panda_ompl_segment.json"))
    args = parser.parse_args()
    model = robots.load(str(MBM / "panda.urdf"), str(MBM / "panda.srdf"))
    spheres = mbm.benchmark_spheres(model, MBM / "panda_spherized.urdf")
    problems = mbm.load_problems(MBM / "problems.tar.bz2", model, args.limit)
    settings = mbm.MBMSettings(time_budget_s=args.budget, compare_ompl=True)
    weights = mbm.PreparedProblem(model, spheres, problems[0], settings).ctx.space.weights
    # the workspace resolution whose segment (resolution / |w|_2, ompl_peer.segment_fraction) is --segment rad
    settings = dataclasses.replace(settings, resolution=args.segment * float(np.linalg.norm(weights)))
    mbm.warm_up(model, spheres, problems[0], settings)  # compiles the sphere checker before timing
    runs = []
    for problem in problems:
        prepared = mbm.PreparedProblem(model, spheres, problem, settings)
        runs.append({"scenario": problem.scenario, "index": problem.index, "ompl": mbm.run_ompl(prepared, settings)})
    summary = mbm.summarize([run["ompl"] for run in runs])
    atomic_write_json(args.json, {"benchmark": "mbm_ompl_segment", "segment_rad": args.segment,
                                  "settings": dataclasses.asdict(settings), "overall": summary,
                                  "machine": machine(), "versions": versions(), "runs": runs})
    print(f"OMPL RRT-Connect, {args.segment:.4g} rad segments: {summary['solved']}/{summary['total']} solved, "
          f"median {summary['median_ms']:.3g} ms, p95 {summary['p95_ms']:.3g} ms, "
          f"{summary['collision_checks_median']:.0f} states (median), {summary['colliding_paths']} colliding paths")


if __name__ == "__main__":
    main()
