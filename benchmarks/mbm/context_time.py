"""Time to prepare a MotionBenchMaker problem for planning: its context and exact certifier.

``PreparedProblem`` builds the problem's ``PlanningContext`` (configuration space, sphere
checker, motion tables) and its exact certifier, as ``prehensile bench mbm`` does before each
timed query; the scene files are read beforehand. Reported: the median and 95th percentile over
every ``--step``-th of the 400 Panda problems (the first preparation, which builds what is
shared by every context of the robot, is left out).

    NUMBA_NUM_THREADS=1 python benchmarks/mbm/context_time.py --step 4

Needs ../shared (the MotionBenchMaker Panda problems).
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from prehensile import robots
from prehensile.benchmarking import mbm

MBM = Path(__file__).resolve().parents[3] / "shared" / "bench" / "mbm" / "panda"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--step", type=int, default=4, help="time every step-th problem")
    args = parser.parse_args()
    model = robots.load(str(MBM / "panda.urdf"), str(MBM / "panda.srdf"))
    spheres = mbm.benchmark_spheres(model, str(MBM / "panda_spherized.urdf"), False, None)
    settings = mbm.MBMSettings()
    problems = mbm.load_problems(MBM / "problems.tar.bz2", model)
    mbm.PreparedProblem(model, spheres, problems[0], settings)  # what every context of the robot shares
    times = []
    for problem in problems[::args.step]:
        start = time.perf_counter()
        mbm.PreparedProblem(model, spheres, problem, settings)
        times.append(time.perf_counter() - start)
    print(f"{len(times)} problems: median {1e3 * np.median(times):.2f} ms, "
          f"p95 {1e3 * np.percentile(times, 95):.2f} ms per prepared problem")


if __name__ == "__main__":
    main()
