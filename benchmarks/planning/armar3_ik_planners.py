"""J+-RRT vs IK-RRT on ARMAR-III, beside Vahrenkamp 2011 Table 4.1.

Scenes (grasps given by hand, as the issue allows until the grasp planner exists): a cup on
a table in front of the robot, 15 side grasps of the right hand (5 approach directions x 3
heights, pre-grasp poses); "obstacle" adds a box next to the cup and a bar above it.

- grasp, 10 DoF (hip + right arm): J+-RRT and IK-RRT from the rest pose to any grasp.
- hand-over, 17 DoF (hip + both arms): the cup, held in the right hand, is brought to a
  pose where the left hand takes it with any of its 15 grasps. "free": the object pose is
  free, as in the thesis (Regrasp-J+-RRT and Regrasp-IK-RRT); "upright": the cup must stay
  near upright in a box in front of the chest (Regrasp-IK-RRT only: J+-RRT has no region).

Times are planning times (search incl. IK sampling, plus shortcutting); certification is
reported separately, and so is the one-time setup of the hand-over goal sampler (reachability
samples, their self-collision filter, grasp pairs). Run:
``NUMBA_NUM_THREADS=1 python benchmarks/planning/armar3_ik_planners.py [--runs 20]``
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

from prehensile import robots
from prehensile.benchmarking.stats import machine, time_summary
from prehensile.collision import Obstacle
from prehensile.collision.spheres import generate_sphere_model
from prehensile.ik import ChainSolver, ObjectRegion
from prehensile.model.geometry import Box, Cylinder
from prehensile.planning import AttachedObject, PlanningContext
from prehensile.planning.ik_rrt import IKRRTSettings, grasp_sampler, ik_rrt, regrasp_sampler
from prehensile.planning.jplus_rrt import JPlusRRTSettings, jplus_rrt, regrasp_jplus_rrt
from prehensile.spatial import invert, make_pose
from prehensile.storage import atomic_write_json

THESIS_MS = {("J+-RRT", False): 2032, ("J+-RRT", True): 18390, ("IK-RRT", False): 140, ("IK-RRT", True): 480,
             ("Regrasp-J+-RRT", False): 1662, ("Regrasp-J+-RRT", True): 5192,
             ("Regrasp-IK-RRT", False): 278, ("Regrasp-IK-RRT", True): 469}
UPRIGHT = ObjectRegion((-0.15, 0.45, 1.0), (0.15, 0.7, 1.3), (-0.2, -0.2, -0.4), (0.2, 0.2, 0.4))
CUP = Cylinder(0.04, 0.2)
T_WORLD_CUP = make_pose(position=[0.3, 0.65, 0.9])  # ARMAR-III faces +y


def side_grasps(heading: float = 0.0) -> np.ndarray:
    """15 grasps T_cup_tcp (15, 4, 4): the TCP z axis (approach) horizontal toward the cup axis,
    at headings ``heading`` + (-60 ... 60) deg from +y (0: reaching forward; pi/2: from the
    left), 11 cm out (pre-grasp: the fingers clear the cup), at three heights."""
    out = []
    for a in np.linspace(-np.pi / 3, np.pi / 3, 5) + heading:
        for h in (-0.03, 0.0, 0.03):
            z = np.array([np.sin(a), np.cos(a), 0.0])
            x = np.array([0.0, 0.0, -1.0])
            out.append(make_pose(np.column_stack([x, np.cross(z, x), z]), -0.11 * z + [0.0, 0.0, h]))
    return np.array(out)


def obstacles(with_obstacle: bool) -> list[Obstacle]:
    table = Obstacle("table", Box((1.2, 0.6, 0.05)), make_pose(position=[0.0, 0.8, 0.775]))
    if not with_obstacle:
        return [table]
    return [table, Obstacle("box", Box((0.1, 0.3, 0.3)), make_pose(position=[0.45, 0.7, 0.95])),
            Obstacle("bar", Box((0.6, 0.05, 0.05)), make_pose(position=[0.2, 0.55, 1.25]))]


def grasp_runs(model, spheres, with_obstacle: bool, runs: int) -> dict:
    world = obstacles(with_obstacle) + [Obstacle("cup", CUP, T_WORLD_CUP)]
    ctx = PlanningContext(model, world, joints="TorsoRightArm", spheres=spheres)
    solver = ChainSolver(model, "TorsoRightArm")
    q0 = model.neutral_configuration()
    targets = T_WORLD_CUP @ side_grasps()
    planners = {
        "J+-RRT": lambda seed: jplus_rrt(ctx, q0, targets, settings=JPlusRRTSettings(time_budget_s=60.0), rng=seed),
        "IK-RRT": lambda seed: ik_rrt(ctx, q0, grasp_sampler(ctx, solver, targets, q0),
                                      IKRRTSettings(time_budget_s=60.0), rng=seed),
    }
    for plan in planners.values():
        plan(runs)  # warm-up: compilation and caches, not timed
    return {name: summarize([plan(seed) for seed in range(runs)]) for name, plan in planners.items()}


def hand_over_runs(model, spheres, with_obstacle: bool, runs: int) -> dict:
    right_grasp = side_grasps()[7]
    hand_links = tuple(n for n in model.link_names if n.endswith(("_L", "_L_J0", "_L_J1", "_R_J0", "_R_J1"))
                       and any(k in n for k in ("Hand", "Thumb", "Index", "Middle", "Ring", "Pinky", "TCP", "GCP")))
    cup = AttachedObject("cup", "TCP_R", CUP, invert(right_grasp), touch_links=hand_links)
    ctx = PlanningContext(model, obstacles(with_obstacle), joints="TorsoBothArms", spheres=spheres, attached=[cup])
    arms = [ChainSolver(model, "LeftArm"), ChainSolver(model, "RightArm")]
    q0 = model.neutral_configuration()
    grasps = [side_grasps(np.pi / 2), right_grasp[None]]  # the left hand comes from the left
    started = time.perf_counter()
    samplers = {region: regrasp_sampler(ctx, arms, grasps, region, q0, free="Torso") for region in (None, UPRIGHT)}
    setup_s = time.perf_counter() - started
    ik_settings = IKRRTSettings(time_budget_s=60.0)
    planners = {
        ("free", "Regrasp-J+-RRT"): lambda seed: regrasp_jplus_rrt(ctx, q0, arms, grasps, free="Torso",
                                                                  settings=JPlusRRTSettings(time_budget_s=60.0),
                                                                  rng=seed),
        ("free", "Regrasp-IK-RRT"): lambda seed: ik_rrt(ctx, q0, samplers[None], ik_settings, rng=seed),
        ("upright", "Regrasp-IK-RRT"): lambda seed: ik_rrt(ctx, q0, samplers[UPRIGHT], ik_settings, rng=seed),
    }
    for plan in planners.values():
        plan(runs)  # warm-up: compilation and caches, not timed
    return {key: {**summarize([plan(seed) for seed in range(runs)]), "sampler_setup_s": setup_s}
            for key, plan in planners.items()}


def summarize(results) -> dict:
    ok = [r for r in results if r.success]
    plan = [r.stats.plan_time_s + r.stats.simplify_time_s for r in ok]
    return {"solved": len(ok), "runs": len(results),
            "plan": time_summary(plan), "certify": time_summary([r.stats.certify_time_s for r in ok]),
            "ik_solutions": float(np.mean([r.stats.ik_solutions for r in ok])) if ok else None,
            "statuses": sorted({r.status.value for r in results})}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--runs", type=int, default=20)
    parser.add_argument("--out", type=Path, default=Path(__file__).parents[1] / "results" / "armar3_ik_planners.json")
    args = parser.parse_args()
    model = robots.load("armar3")
    spheres = generate_sphere_model(model, max_radius=0.04)  # the balls of the published runs (320; default 292)
    started = time.perf_counter()
    rows = []
    for with_obstacle in (False, True):
        tables = {("grasp, 10 DoF", planner): summary
                  for planner, summary in grasp_runs(model, spheres, with_obstacle, args.runs).items()}
        hand_over = hand_over_runs(model, spheres, with_obstacle, args.runs)
        tables.update({(f"hand-over {variant}, 17 DoF", planner): summary
                       for (variant, planner), summary in hand_over.items()})
        for (task, planner), summary in tables.items():
            thesis = THESIS_MS[planner, with_obstacle]
            mean = summary["plan"]["mean_ms"]
            rows.append({"task": task, "planner": planner, "obstacle": with_obstacle, **summary,
                         "thesis_mean_ms": thesis, "speedup_vs_thesis": thesis / mean if mean else None})
            print(f"{task:26s} {planner:15s} obstacle={with_obstacle!s:5s} "
                  f"solved {summary['solved']}/{summary['runs']} mean {mean} ms (thesis {thesis} ms)")
    atomic_write_json(args.out, {"rows": rows, "runs": args.runs, "machine": machine(),
                                 "wall_s": time.perf_counter() - started})
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()
