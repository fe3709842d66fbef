"""``prehensile ik``: solve one IK query of a chain from the command line.

Exit codes: 0 solved, 1 no solution (the status is printed), 2 bad input, 3 a bug.
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import numpy as np
import typer
from rich.table import Table

from prehensile.cli.app import (SRDF_OPTION, app, check_budget, check_seed, console, echo_json, extra_values,
                                handles_errors)
from prehensile.errors import PrehensileError
from prehensile.ik import METHODS as JACOBIAN_METHODS
from prehensile.ik import ChainSolver, CompleteIKSettings, JacobianIKSettings, solve_ik_complete
from prehensile.ik.analytic_nao import nao_arm_ik
from prehensile.ik.fabrik import fabrik
from prehensile.kinematics import link_pose
from prehensile.model.robot_model import RobotModel
from prehensile.spatial import matrix_to_rpy, rpy_to_matrix

METHODS = (*JACOBIAN_METHODS, "fabrik", "analytic")
EXIT_SOLVED, EXIT_NO_SOLUTION = 0, 1


def parse_target(values: List[str]) -> np.ndarray:
    """A position (3,) from ``x y z`` (m) or a pose (4, 4) from ``x y z roll pitch yaw`` (m, rad)."""
    if len(values) not in (3, 6):
        got = f"got {len(values)}: {' '.join(values)}" if values else "got none"
        raise PrehensileError(f"--target: expected 3 values (x y z, m) or 6 (x y z roll pitch yaw; m, rad), {got}")
    try:
        numbers = np.array([float(v) for v in values])
    except ValueError:
        raise PrehensileError(f"--target: expected numbers, got {' '.join(values)}") from None
    if not np.all(np.isfinite(numbers)):
        raise PrehensileError(f"--target: contains NaN or infinite values: {' '.join(values)}")
    if len(numbers) == 3:
        return numbers
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rpy_to_matrix(numbers[3:]), numbers[:3]
    return pose


def solve_query(model: RobotModel, chain: str, target: np.ndarray, method: str, seed: int, budget: float):
    """Solve a position (3,) or pose (4, 4) target of ``chain`` with ``method``; an IKResult.

    The solver is called once first on the tip pose of the neutral configuration, so that
    loading its compiled kernels is neither in the budget nor in the reported time.
    """
    if method not in METHODS:
        raise PrehensileError(f"--method: unknown IK method '{method}'; valid: {', '.join(METHODS)}")
    check_budget(budget)
    position_only = target.shape == (3,)
    if method == "analytic" and position_only:
        raise PrehensileError("--method analytic solves poses: give --target x y z roll pitch yaw")
    spec = model.chain(chain)  # an unknown chain: the message lists the chains
    if method == "fabrik":
        def solve(goal):
            return fabrik(model, chain, goal if position_only else goal[:3, 3],
                          target_orientation=None if position_only else goal[:3, :3])
    elif method == "analytic":
        def solve(goal):
            return nao_arm_ik(model, chain, goal)
    else:
        solver = ChainSolver(model, chain, settings=JacobianIKSettings(method=method, position_only=position_only))

        def solve(goal):
            return solve_ik_complete(solver, goal, rng=seed, settings=CompleteIKSettings(time_budget_s=budget))

    neutral = link_pose(model, model.neutral_configuration(), spec.tip_link)
    solve(neutral[:3, 3] if position_only else neutral)
    return solve(target)


def out_of_reach(model: RobotModel, chain: str, position: np.ndarray) -> str | None:
    """Why the tip cannot reach ``position`` (3,) (m, root frame) with the other joints at their
    neutral values, or None if it may: the target lies farther from the chain's base link than
    the offsets between the chain's links (and prismatic travel) add up to."""
    spec = model.chain(chain)
    path = model.path_to_root(spec.tip_link)
    below = path[: path.index(model.link_index(spec.base_link))]  # the tip up to the link below the base
    reach = float(np.sum(np.linalg.norm(model.joint_origin[below, :3, 3], axis=1) + model.joint_travel[below]))
    base = link_pose(model, model.neutral_configuration(), spec.base_link)[:3, 3]
    distance = float(np.linalg.norm(position - base))
    if distance <= reach:
        return None
    return (f"out of reach: the target is {distance:.3f} m from {spec.base_link}, the base of chain '{chain}', "
            f"whose tip reaches at most {reach:.3f} m from it")


def report(model: RobotModel, chain: str, method: str, target: np.ndarray, result) -> dict:
    """JSON-ready summary of an IKResult: chain joint values by name, all solutions, errors."""
    joints = model.chain(chain).joint_names
    index = [model.joint_index(j) for j in joints]
    position_only = target.shape == (3,)
    return {
        "robot": model.name,
        "chain": chain,
        "method": method,
        "target": {"position": (target if position_only else target[:3, 3]).tolist(),
                   "rpy": None if position_only else matrix_to_rpy(target[:3, :3]).tolist()},
        "status": result.status.value,
        "success": result.success,
        "joints": dict(zip(joints, result.q[index].tolist())),
        "solutions": [dict(zip(joints, q[index].tolist())) for q in result.solutions],
        "position_error_m": result.position_error,
        "rotation_error_rad": None if position_only else result.rotation_error,
        "iterations": result.iterations,
        "restarts": result.restarts,
        "time_s": result.time_s,
        "reason": None if result.success else out_of_reach(model, chain, target if position_only else target[:3, 3]),
    }


@app.command("ik", context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
@handles_errors
def ik(
    ctx: typer.Context,
    robot: str = typer.Argument(..., metavar="ROBOT", help="Bundled robot name or model file path."),
    chain: str = typer.Option(..., "--chain", help="Chain of the robot (see `prehensile robot info`)."),
    srdf: Optional[Path] = SRDF_OPTION,
    target: Optional[List[str]] = typer.Option(None, "--target", metavar="X Y Z [R P Y]",
                                               help="x y z (m): position only; x y z roll pitch "
                                               "yaw (m, rad): full pose of the chain's tip in the robot's root."),
    method: str = typer.Option("dls", "--method", help=f"One of {', '.join(METHODS)}."),
    seed: int = typer.Option(0, "--seed", help="Seed of the random restarts."),
    budget: float = typer.Option(0.1, "--budget", help="Time budget (s) of the Jacobian methods."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of tables."),
) -> None:
    """Inverse kinematics of one chain from the neutral configuration.

    Jacobian methods restart from random configurations within the budget. Exit code 0 when
    solved, 1 when not, 2 on bad input, 3 on a bug.
    """
    from prehensile.cli.robot import load_robot

    check_seed(seed)
    goal = parse_target(extra_values(ctx.args, target, "--target", "the target"))
    model = load_robot(robot, srdf)
    result = solve_query(model, chain, goal, method, seed, budget)
    data = report(model, chain, method, goal, result)
    if as_json:
        echo_json(data)
    else:
        print_result(data)
    raise typer.Exit(EXIT_SOLVED if result.success else EXIT_NO_SOLUTION)


def print_result(data: dict) -> None:
    """Status, joint values (one column per solution), errors, iterations and time."""
    solutions = data["solutions"] or [data["joints"]]
    heading = "solution" if data["success"] else "best reached"
    table = Table("joint", *(f"{heading} {k + 1} (rad | m)" if len(solutions) > 1 else f"{heading} (rad | m)"
                             for k in range(len(solutions))), title=f"{data['robot']} {data['chain']} ({data['method']})")
    for joint in data["joints"]:
        table.add_row(joint, *(f"{s[joint]:.6f}" for s in solutions))
    console.print(table)
    colour = "green" if data["success"] else "red"
    rotation = data["rotation_error_rad"]
    errors = f"position error {1e3 * data['position_error_m']:.4f} mm" + (
        "" if rotation is None else f", rotation error {1e3 * rotation:.4f} mrad")
    console.print(f"status [bold {colour}]{data['status']}[/]; {errors}; {data['iterations']} iterations, "
                  f"{data['restarts']} restarts, {1e3 * data['time_s']:.3f} ms")
    if data["reason"]:
        console.print(data["reason"])
