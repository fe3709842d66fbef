"""``prehensile bench mbm``: our planner (and OMPL's) on MoveIt / MotionBenchMaker problems."""

from __future__ import annotations

import shlex
from pathlib import Path
from typing import Optional

import typer
from rich.markup import escape
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Column, Table

from prehensile.cli.app import (BALL_RADIUS_OPTION, SRDF_OPTION, bench_app, check_ball_radius, check_budget,
                                check_seed, console, err_console, handles_errors)
from prehensile.errors import PrehensileError, missing_file


@bench_app.command("mbm")
@handles_errors
def bench_mbm(
    problems: Path = typer.Argument(..., metavar="PROBLEMS",
                                    help="Folder or .tar.bz2 of MoveIt sceneNNNN.yaml / requestNNNN.yaml pairs."),
    robot: str = typer.Option(..., "--robot", help="Robot URDF (or a bundled robot name): the one the problems "
                              "were made for; another model plans another problem."),
    spheres: Optional[Path] = typer.Option(None, "--spheres", help="Spherized URDF whose balls to plan with "
                                           "(default: balls generated from the meshes)."),
    pad: bool = typer.Option(False, "--pad/--no-pad", help="--no-pad: plan on the spherized URDF's balls as they "
                             "are and, when a path fails the exact certification, again with the balls of the "
                             "links that collided padded to cover the meshes; --pad: plan on padded balls only."),
    ball_radius: Optional[float] = BALL_RADIUS_OPTION,
    srdf: Optional[Path] = SRDF_OPTION,
    planner: str = typer.Option("rrt_connect", "--planner", help="Our planner: rrt_connect (to the goal "
                                 "configuration) or, to the pose that configuration gives the group's tip (or to "
                                 "a request's position and orientation constraints), ik_rrt or jplus_rrt."),
    compare_ompl: bool = typer.Option(False, "--compare-ompl", help="Also run OMPL's RRT-Connect on every problem "
                                      "(beside --planner rrt_connect)."),
    budget: float = typer.Option(1.0, "--budget", help="Search time limit per problem and planner (s)."),
    seed: int = typer.Option(0, "--seed", help="Random seed."),
    limit: int = typer.Option(0, "--limit", help="At most N problems per scenario (0: all)."),
    json_out: Optional[Path] = typer.Option(None, "--json", help="Write the full report (JSON) to this file."),
) -> None:
    """Plan every MotionBenchMaker problem of a folder or archive, optionally with OMPL beside.

    Reports solved, median / p95 planning time (search + simplification), path length,
    certification time and exactly-colliding paths, per scenario and overall.
    """
    from prehensile.benchmarking.mbm import PLANNERS, MBMSettings, benchmark_spheres, run_mbm
    from prehensile.cli.robot import load_robot
    from prehensile.storage import atomic_write_json, check_writable

    check_budget(budget)
    check_seed(seed)
    if limit < 0:
        raise PrehensileError(f"--limit: must be >= 0 (0: all problems), got {limit}")
    if planner not in PLANNERS:
        raise PrehensileError(f"--planner: '{planner}' is not available; valid: {', '.join(PLANNERS)}")
    settings = MBMSettings(planner=planner, time_budget_s=budget, seed=seed, limit=limit, compare_ompl=compare_ompl)
    if json_out is not None:
        check_writable(json_out, "--json")
    if not problems.exists():
        raise PrehensileError(f"{problems}: no such folder or archive of MoveIt problems")
    if spheres is not None and not spheres.is_file():
        raise PrehensileError(f"--spheres {spheres}: {missing_file(spheres)}")
    check_ball_radius(ball_radius)
    if pad and spheres is None:
        raise PrehensileError("--pad pads the balls of --spheres: give a spherized URDF (generated balls cover the "
                              "meshes already)")
    if spheres is not None and ball_radius is not None:
        raise PrehensileError("--ball-radius sizes generated balls: give it or --spheres, not both")
    model = load_robot(robot, srdf)
    sphere_model = benchmark_spheres(model, spheres, pad, ball_radius)
    # shown once the problems have loaded: an error before leaves stderr with its one line
    bar = Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                   console=err_console, transient=True)
    task = bar.add_task("compiling", total=None)

    def progress(done: int, total: int, run: dict | None) -> None:
        if run is None:
            bar.start()
        bar.update(task, completed=done, total=total,
                   description="compiling" if run is None else f"{run['scenario']} {run['index']:04d}")

    try:
        report = run_mbm(problems, model, sphere_model, settings, progress)
    finally:
        if bar.live.is_started:
            bar.stop()
    options = {"--robot": robot, "--srdf": srdf, "--spheres": spheres, "--ball-radius": ball_radius,
               "--planner": planner, "--budget": budget, "--seed": seed, "--limit": limit, "--json": json_out}
    words = ["prehensile", "bench", "mbm", str(problems)] + ["--compare-ompl"] * compare_ompl + ["--pad"] * pad
    report["command"] = shlex.join(words + [str(w) for k, v in options.items() if v is not None for w in (k, v)])
    report["robot"].update(urdf=str(robot), srdf=model.srdf_source,
                           spherized_urdf=None if spheres is None else str(spheres),
                           sphere_model="generated" if spheres is None else "padded" if pad
                           else "as given, padded where certification fails")
    print_report(report)
    if json_out is not None:
        atomic_write_json(json_out, report)
        console.print(f"wrote {json_out}")


def _ms(value: float | None) -> str:
    return "-" if value is None else f"{value:.3g}" if value < 10 else f"{value:.0f}"


def _x(value: float | None) -> str:
    return "-" if value is None else f"{value:.1f}x"


def print_report(report: dict) -> None:
    """A rich table: per scenario and overall one row for ours and, when run, one for OMPL."""
    ompl = report.get("ompl")
    table = Table(Column("scenario", no_wrap=True), "planner", "solved", "median ms", "p95 ms", "path m",
                  "certify ms", "colliding", *(("speed-up median / p95 / paired",) if ompl else ()),
                  title=f"{report['settings']['planner']} on {report['problems']}")
    for name in [*report["scenarios"], "overall"]:
        pick = (lambda part: part["overall"] if name == "overall" else part["scenarios"][name])  # noqa: E731
        label = "[bold]overall[/]" if name == "overall" else name
        rows = [("ours", pick(report))] + ([("OMPL", pick(ompl))] if ompl else [])
        for k, (planner, s) in enumerate(rows):
            cells = [label if k == 0 else "", planner, f"{s['solved']}/{s['total']}", _ms(s["median_ms"]),
                     _ms(s["p95_ms"]), _ms(s["path_length"]), _ms(s["certify_median_ms"]), str(s["colliding_paths"])]
            if ompl:
                r = pick({"overall": report["ratios"], "scenarios": report["ratios"]["scenarios"]})
                cells.append(f"{_x(r['median_speedup'])} / {_x(r['p95_speedup'])} / {_x(r['paired_median_speedup'])}"
                             if k == 0 else "")
            table.add_row(*cells, end_section=k == len(rows) - 1 and bool(ompl))
    console.print(table)
    statuses = "; ".join(f"{name}: " + ", ".join(f"{k} {v}" for k, v in summary["statuses"].items())
                         for name, summary in (("ours", report["overall"]), ("OMPL", ompl and ompl["overall"]))
                         if summary)
    console.print(f"{statuses}. Times: search + simplification, over solved problems; path m: "
                  "workspace-weighted length (no robot point travels farther); colliding: returned paths the exact "
                  "meshes reject"
                  + ("; speed-up: OMPL's time / ours" if ompl else ""))
    for name, summary in (("ours", report["overall"]), ("OMPL", ompl["overall"] if ompl else None)):
        if summary and summary["ends_elsewhere"]:
            console.print(f"[red]{name}: {summary['ends_elsewhere']} paths start or end elsewhere than their request "
                          "asks[/] (counted unsolved)")
    checked = [run["ours"]["goal_satisfied"] for run in report["runs"] if run["ours"]["goal_satisfied"] is not None]
    if checked:
        console.print(f"{'' if all(checked) else '[yellow]'}pose goals: {sum(checked)} of {len(checked)} paths end "
                      "within the requests' position and orientation constraints (the others count as unsolved)")
    reasons: dict[tuple[str, str], str] = {}  # (status, why an end was unusable) -> the first problem
    for run in report["runs"]:
        if run["ours"].get("reason"):
            reasons.setdefault((run["ours"]["status"], run["ours"]["reason"]), f"{run['scenario']} #{run['index']}")
    for (status, reason), first in list(reasons.items())[:3]:
        console.print(f"[yellow]{status}[/] (first: {first}): {escape(reason)}")
