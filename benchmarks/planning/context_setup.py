"""Time setting up planning in a new scene: PlanningContext, exact checker and certifier.

    NUMBA_NUM_THREADS=1 python benchmarks/planning/context_setup.py --scenes 20

The bundled Panda (its meshes) in ``--scenes`` random scenes of three to six boxes. The first
scene of a process also prepares the robot's exact geometry (coal BVHs and convex hulls of its
meshes, :func:`~prehensile.collision.exact.robot_parts`); every later scene shares it and
builds only what depends on the obstacles. Prints the first scene's time and the median over
the others, per part. No peer: MoveIt builds its planning scene in another process.
"""

from __future__ import annotations

import argparse
import time

import numpy as np

from prehensile import robots
from prehensile.collision import Obstacle
from prehensile.model.geometry import Box
from prehensile.planning import PlanningContext
from prehensile.spatial import make_pose


def random_boxes(rng: np.random.Generator) -> list[Obstacle]:
    """Three to six boxes (5-40 cm sides) 0.3-0.8 m in front of the robot."""
    return [Obstacle(f"box{k}", Box(tuple(rng.uniform(0.05, 0.4, 3))),
                     make_pose(position=[rng.uniform(0.3, 0.8), rng.uniform(-0.5, 0.5), rng.uniform(0.0, 0.8)]))
            for k in range(rng.integers(3, 7))]


def setup_times(model, obstacles: list[Obstacle]) -> dict[str, float]:
    """Seconds to build the context, then its exact certifier, then its exact checker."""
    times, begun = {}, time.perf_counter()
    ctx = PlanningContext(model, obstacles, joints="arm")
    times["context"] = time.perf_counter() - begun
    for part in ("certifier", "exact"):
        begun = time.perf_counter()
        getattr(ctx, part)
        times[part] = time.perf_counter() - begun
    return times


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", type=int, default=20)
    args = parser.parse_args()
    model = robots.load("panda")
    rng = np.random.default_rng(0)
    PlanningContext(robots.load("nao"), random_boxes(rng), joints="left_arm").certifier  # compile kernels elsewhere
    runs = [setup_times(model, random_boxes(rng)) for _ in range(max(args.scenes, 2))]
    for part in runs[0]:
        later = np.median([run[part] for run in runs[1:]])
        print(f"{part:10s} first scene {1e3 * runs[0][part]:7.1f} ms, later scenes median {1e3 * later:6.1f} ms")
    total = [sum(run.values()) for run in runs]
    later = np.median(total[1:])
    print(f"{'total':10s} first scene {1e3 * total[0]:7.1f} ms, later scenes median {1e3 * later:6.1f} ms")


if __name__ == "__main__":
    main()
