"""``prehensile bench ik``: our IK solvers and the peers (pinocchio DLS, ikpy) on the same targets."""

from __future__ import annotations

import shlex
import sys
from pathlib import Path
from typing import List, Optional

import typer
from rich.progress import BarColumn, MofNCompleteColumn, Progress, TextColumn, TimeElapsedColumn
from rich.table import Table

from prehensile.cli.app import bench_app, check_seed, console, err_console, handles_errors


def split_names(values: List[str] | None) -> tuple[str, ...]:
    """Names from repeated and/or comma-separated options ("none" or "" for no names)."""
    names = [name.strip() for value in values or [] for name in value.split(",")]
    return tuple(dict.fromkeys(name for name in names if name and name != "none"))


@bench_app.command("ik")
@handles_errors
def bench_ik(
    robot: str = typer.Option(..., "--robot", help="Bundled robot name or URDF path."),
    base: str = typer.Option(..., "--base", help="Base link of the chain."),
    tip: str = typer.Option(..., "--tip", help="Tip link of the chain (the tool frame)."),
    n: int = typer.Option(10_000, "--n", help="Number of random reachable targets."),
    method: Optional[List[str]] = typer.Option(None, "--method", metavar="METHOD",
                                               help="Our solvers, repeatable or comma list: "
                                               "dls, pinv, transpose, fabrik (position only), analytic (NAO arms). "
                                               "Default: dls."),
    seed: int = typer.Option(0, "--seed", help="Seed of the targets and the restarts."),
    budget: float = typer.Option(0.005, "--budget", help="Time budget per target (s)."),
    peers: List[str] = typer.Option(["pinocchio,ikpy"], "--peers", help="Peers, comma list: pinocchio, ikpy "
                                    "(or none)."),
    ikpy_targets: int = typer.Option(200, "--ikpy-targets", help="ikpy runs on the first N targets only."),
    json_out: Optional[Path] = typer.Option(None, "--json", help="Write the report (JSON) to this file."),
) -> None:
    """Solve n reachable targets of a chain with our IK solvers and the peers'.

    The targets are reachable poses of the chain base -> tip, solved from the neutral
    configuration. Reports success (checked by our FK: 0.1 mm, 1 mrad), time per target and
    iterations per solver, and our time relative to the peers'.
    """
    from prehensile import robots
    from prehensile.benchmarking.ik import IKBenchSettings, run_ik_bench
    from prehensile.storage import atomic_write_json, check_writable

    check_seed(seed)
    if json_out is not None:
        check_writable(json_out, "--json")
    settings = IKBenchSettings(n=n, methods=split_names(method) or ("dls",), peers=split_names(peers), seed=seed,
                               time_budget_s=budget, ikpy_targets=ikpy_targets)
    model = robots.load(robot)
    with Progress(TextColumn("{task.description}"), BarColumn(), MofNCompleteColumn(), TimeElapsedColumn(),
                  console=err_console, transient=True) as bar:
        tasks: dict[str, int] = {}

        def progress(name: str, done: int, total: int) -> None:
            if name not in tasks:
                tasks[name] = bar.add_task(name, total=total)
            bar.update(tasks[name], completed=done)

        report = run_ik_bench(model, base, tip, settings, progress)
    report["command"] = shlex.join(["prehensile", *sys.argv[1:]])
    print_report(report)
    if json_out is not None:
        atomic_write_json(json_out, report)
        console.print(f"wrote {json_out}")


def _num(value: float | None) -> str:
    return "-" if value is None else f"{value:.0f}" if value >= 1000 else f"{value:.3g}"


def print_report(report: dict) -> None:
    """One row per solver: success, times, iterations and the ratios to the peers."""
    chain = report["chain"]
    tol = report["tolerance"]
    table = Table("solver", "targets", "success", "in budget", "mean ms", "median ms", "p95 ms", "iterations",
                  "mean / pinocchio", "mean / ikpy",
                  title=f"IK on {report['robot']} {chain['base']} -> {chain['tip']} ({len(chain['joints'])} DoF), "
                        f"budget {1e3 * report['time_budget_s']:g} ms")
    for name, m in report["methods"].items():
        r = report["ratios"].get(name, {})
        label = f"{name}*" if m["position_only"] else name
        table.add_row(label if m["kind"] == "ours" else f"[dim]{label}[/]", str(m["targets"]),
                      f"{100 * m['success_rate']:.2f} %", f"{100 * m['within_budget_rate']:.2f} %",
                      _num(m["mean_ms"]), _num(m["median_ms"]), _num(m["p95_ms"]), _num(m["iterations"]),
                      _num(r.get("mean_vs_pinocchio")), _num(r.get("mean_vs_ikpy_subset")))
    console.print(table)
    batch = report["methods"].get("analytic", {}).get("batch")
    if batch:
        console.print(f"analytic, batched: {batch['us_per_target']:.2f} us per target with all solutions "
                      f"({batch['solutions_mean']:.2f} per target, {100 * batch['success_rate']:.2f} % solved)")
    console.print(f"success = within the limits and {1e3 * tol['position_m']:g} mm / {1e3 * tol['rotation_rad']:g} "
                  "mrad by our FK (* position only); ratios = our time / the peer's on the same targets (below 1: "
                  "ours faster)")
    if "ikpy" in report["methods"]:
        console.print(f"ikpy: {report['methods']['ikpy']['note']}")
