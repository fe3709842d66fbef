"""Write MotionBenchMaker-style problems (MoveIt scene/request YAML pairs) for any robot group:
a table, a shelf board above it and a post, placed in front of the group's base, with a start
and a goal that are valid on the exact geometry and not joined by a free straight motion.

    python benchmarks/mbm/shelf_problems.py armar3 RightArm /tmp/armar3_shelf --count 10
    prehensile bench mbm /tmp/armar3_shelf --robot armar3 --compare-ompl

The table's centre is ``--distance`` m from the group's base along ``--forward`` (a
horizontal world direction; default +y, ARMAR-III's front; the Panda's is +x) and ``--drop``
m below the base, moved by up to 5 cm per axis from problem to problem; the boxes are sized
for an arm of about 0.5-1 m reach. Problems go to OUT/shelf_ROBOT_GROUP/.
"""

from __future__ import annotations

import argparse
from itertools import islice
from pathlib import Path

import numpy as np
import yaml

from prehensile import robots
from prehensile.collision.world import Obstacle
from prehensile.errors import PrehensileError
from prehensile.kinematics.forward import link_pose
from prehensile.model.geometry import Box
from prehensile.planning import PlanningContext
from prehensile.spatial import make_pose

BOXES = {"table": ((0.0, 0.1, 0.0), (0.6, 0.5, 0.04)),  # name: (offset from the table centre, size) in m,
         "board": ((0.0, 0.15, 0.5), (0.5, 0.3, 0.02)),  # with +y pointing away from the robot
         "post": ((0.3, 0.1, 0.25), (0.04, 0.04, 0.5))}


def shelf(table: np.ndarray, yaw: float) -> list[Obstacle]:
    """The boxes around the table centre (3,) (m), turned by ``yaw`` (rad) about the world z-axis."""
    c, s = np.cos(yaw), np.sin(yaw)
    R = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    return [Obstacle(name, Box(size), make_pose(R, table + R @ np.array(offset)))
            for name, (offset, size) in BOXES.items()]


def samples(model, group: str, ctx: PlanningContext, rng: np.random.Generator, tries: int):
    """Up to ``tries`` random configurations (dof,) of the group, the other joints at the
    context's ``q_ref``, each with whether it is valid on the balls and free on the exact geometry."""
    arm = model.chain_q_indices(group)
    for _ in range(tries):
        q = ctx.space.q_ref.copy()
        q[arm] = model.random_configurations(rng)[arm]
        yield q, bool(ctx.is_valid(q) and ctx.exact.is_free(q))


def problem(model, group: str, ctx: PlanningContext, rng: np.random.Generator, tries: int = 2000):
    """(start, goal) (dof,) valid on the exact geometry, with a blocked straight motion; None if not found."""
    ends = list(islice((q for q, valid in samples(model, group, ctx, rng, tries) if valid), 2))
    return None if len(ends) < 2 or ctx.check_motion(*ends) else tuple(ends)


def why_no_free_configuration(model, group: str, rng: np.random.Generator, tries: int = 200) -> str:
    """"" if one of ``tries`` random configurations of the group (the other joints neutral) is
    valid without obstacles; else why the first is not."""
    ctx = PlanningContext(model, [], joints=list(model.chain(group).joint_names), q_ref=model.neutral_configuration())
    first = None
    for q, valid in samples(model, group, ctx, rng, tries):
        if valid:
            return ""
        first = q if first is None else first
    return ctx.why_invalid(first)  # never "" for a configuration that is not valid


def write(folder: Path, k: int, model, group: str, obstacles: list[Obstacle], yaw: float, start: np.ndarray,
          goal: np.ndarray) -> None:
    names = list(model.joint_names)
    joints = [names[i] for i in model.chain_q_indices(group)]
    state = {"joint_state": {"name": names, "position": model.neutral_configuration().tolist()}}
    scene = {"name": f"shelf{k}", "robot_model_name": model.name, "robot_state": state, "world": {
        "collision_objects": [{"id": o.name, "primitives": [{"type": "box", "dimensions": list(o.shape.size)}],
                               "primitive_poses": [{"position": o.T_world_shape[:3, 3].tolist(),
                                                    "orientation": [0.0, 0.0, float(np.sin(yaw / 2)),
                                                                    float(np.cos(yaw / 2))]}]} for o in obstacles]}}
    request = {"group_name": group, "start_state": {"joint_state": {"name": names, "position": start.tolist()}},
               "goal_constraints": [{"joint_constraints": [{"joint_name": j, "position": float(goal[names.index(j)])}
                                                           for j in joints]}]}
    folder.mkdir(parents=True, exist_ok=True)
    (folder / f"scene{k:04d}.yaml").write_text(yaml.safe_dump(scene))
    (folder / f"request{k:04d}.yaml").write_text(yaml.safe_dump(request))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("robot", help="bundled robot name or robot file")
    parser.add_argument("--srdf", type=Path, help="SRDF of the robot (default: <stem>.srdf next to its file)")
    parser.add_argument("group", help="SRDF group (chain) to plan")
    parser.add_argument("out", type=Path, help="output folder (problems go to OUT/shelf_ROBOT_GROUP/)")
    parser.add_argument("--count", type=int, default=10, help="problems to write")
    parser.add_argument("--forward", type=float, nargs=2, default=(0.0, 1.0), metavar=("X", "Y"),
                        help="horizontal direction from the base to the table")
    parser.add_argument("--distance", type=float, default=0.45, help="table centre from the group's base (m)")
    parser.add_argument("--drop", type=float, default=0.45, help="table below the group's base (m)")
    parser.add_argument("--scenes", type=int, default=200, help="give up after COUNT x SCENES scenes tried")
    parser.add_argument("--seed", type=int, default=1, help="seed of the scene offsets and configurations")
    args = parser.parse_args()
    if args.count < 1 or args.scenes < 1:
        parser.error("--count and --scenes must be at least 1")
    try:
        model = robots.load(args.robot, srdf=args.srdf)
        if args.group not in model.chains:
            parser.error(f"robot '{model.name}' has no group '{args.group}'; groups: {', '.join(model.chains)}")
        why = why_no_free_configuration(model, args.group, np.random.default_rng(args.seed))
    except PrehensileError as error:  # a robot file or mesh that does not load
        raise SystemExit(f"error: {error}") from None
    if why:
        raise SystemExit(f"error: no random configuration of group '{args.group}' is valid even without obstacles "
                         f"(the other joints neutral); the first: {why}")
    chain = model.chain(args.group)
    base = link_pose(model, model.neutral_configuration(), chain.base_link)[:3, 3]
    forward = np.array([args.forward[0], args.forward[1], 0.0])
    if not np.linalg.norm(forward) > 0:
        parser.error("--forward must be a nonzero horizontal direction")
    forward /= np.linalg.norm(forward)
    folder = args.out / f"shelf_{model.name}_{args.group}"
    yaw = float(np.arctan2(forward[1], forward[0]) - np.pi / 2)
    rng, k = np.random.default_rng(args.seed), 0
    for _ in range(args.scenes * args.count):
        if k == args.count:
            break
        table = base + args.distance * forward + np.array([0.0, 0.0, -args.drop]) + rng.uniform(-0.05, 0.05, 3)
        obstacles = shelf(table, yaw)
        ctx = PlanningContext(model, obstacles, joints=list(chain.joint_names), q_ref=model.neutral_configuration())
        ends = problem(model, args.group, ctx, rng)
        if ends is not None:
            k += 1
            write(folder, k, model, args.group, obstacles, yaw, *ends)
    if k:
        print(f"wrote {k} problems to {folder}")
    if k < args.count:
        raise SystemExit(f"found only {k} of {args.count} problems in {args.scenes * args.count} scenes: the start and "
                         "goal must be free and their straight motion blocked; try another --distance, --drop or "
                         "--forward (the boxes may be out of the group's reach)")


if __name__ == "__main__":
    main()
