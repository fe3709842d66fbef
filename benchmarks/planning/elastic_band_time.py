"""Time the elastic band (Vahrenkamp 2011 B.3) on a Panda path under a shelf board.

    NUMBA_NUM_THREADS=1 python benchmarks/planning/elastic_band_time.py --runs 5

The arm reaches from beside a board (0.5 x 1.2 m, 0.35 m high) in front of a back wall to
below it; RRT-Connect (seed 3) plans the path, which the band subdivides to 5 cm and pushes
5 cm from the obstacles. Prints the waypoints, the median time of ``--runs`` bands and the
smallest exact clearance from the world over the subdivided path's waypoints, before and after.
No peer: MoveIt and OMPL have no elastic band to compare with.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from prehensile import robots
from prehensile.collision import Obstacle
from prehensile.model.geometry import Box
from prehensile.planning import PlanningContext, elastic_band, rrt_connect
from prehensile.planning.elastic_band import ElasticBandSettings
from prehensile.spatial import make_pose

START = [-1.286, -1.4323, 1.9123, -2.5194, -1.0114, 2.5319, 0.2336, 0.02]
GOAL = [-0.1669, 0.6623, -0.9333, -0.2884, 2.0847, 1.1362, -2.6719, 0.02]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=5)
    args = parser.parse_args()
    panda = robots.load("panda")
    obstacles = [Obstacle("board", Box((0.5, 1.2, 0.02)), make_pose(position=[0.55, 0.0, 0.35])),
                 Obstacle("back", Box((0.02, 1.2, 1.0)), make_pose(position=[0.81, 0.0, 0.5]))]
    ctx = PlanningContext(panda, obstacles, joints="arm")
    path = rrt_connect(ctx, np.array(START), np.array(GOAL), rng=3).path
    elastic_band(ctx, path[:2])  # compile the kernels it uses
    times, band = [], path
    for _ in range(args.runs):
        begun = time.perf_counter()
        band = elastic_band(ctx, path)
        times.append(time.perf_counter() - begun)

    def clearance(p: np.ndarray) -> float:
        """Smallest distance (m) of the robot to the world over the waypoints p (N, dof)."""
        return min(pair.distance for q in p for pair in ctx.exact.closest_points(q))

    subdivided = elastic_band(ctx, path, ElasticBandSettings(max_iterations=0))
    print(f"path {len(path)} waypoints -> band {len(band)}; median {np.median(times):.3f} s over {args.runs} runs; "
          f"clearance from the world {1e3 * clearance(subdivided):.1f} -> {1e3 * clearance(band):.1f} mm")


if __name__ == "__main__":
    main()
