"""The ``prehensile`` command: a thin layer over the library.

Commands::

    prehensile robot info NAME|PATH [--srdf SRDF] [--json]
    prehensile fk NAME|PATH [--q v1 v2 ...] [--link L] [--json]
    prehensile check SCENE [--exact | --spheres] [--json]
    prehensile demo [--out DIR]

Bad input (any :class:`~prehensile.errors.PrehensileError`) prints one red line and exits
with code 2, any other error (a bug) its traceback with code 3; ``check`` exits 0 when the
scene is collision-free and 1 when something collides.
"""

from __future__ import annotations

from pathlib import Path
from typing import List, Optional

import typer
from rich.table import Table

from prehensile.cli import robot as robot_cmd
from prehensile.cli.app import (EXIT_COLLIDING, EXIT_FREE, SRDF_OPTION, app, console, echo_json, extra_values,
                                handles_errors)

robot_app = typer.Typer(help="Inspect robot models.", no_args_is_help=True)
app.add_typer(robot_app, name="robot")


def _fmt(value: float | None, digits: int = 4, unlimited: str = "inf") -> str:
    """``value`` with ``digits`` decimals; ``unlimited`` for None (no limit)."""
    return unlimited if value is None else f"{value:.{digits}f}"


@robot_app.command("info")
@handles_errors
def robot_info(
    robot: str = typer.Argument(..., metavar="ROBOT",
                                help="Bundled robot name (see `prehensile robot list`) or model file path."),
    srdf: Optional[Path] = SRDF_OPTION,
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of tables."),
) -> None:
    """Degrees of freedom, joints and limits, mimic joints, chains, end effectors and preshapes."""
    info = robot_cmd.robot_info(robot_cmd.load_robot(robot, srdf))
    if as_json:
        echo_json(info)
        return
    console.print(f"[bold]{info['name']}[/]  ({info['source']}; SRDF: {info['srdf'] or 'none'})")
    console.print(f"dof: {info['dof']}   links: {info['n_links']}   root: {info['root_link']}")
    joints = Table("#", "joint", "type", "lower", "upper", "lower (deg)", "upper (deg)", "velocity", title="joints")
    for j in info["joints"]:
        deg = (_fmt(j.get("lower_deg"), 1, "-inf"), _fmt(j.get("upper_deg"), 1)) if "lower_deg" in j else ("-", "-")
        unit = "m" if j["type"] == "prismatic" else "rad"
        joints.add_row(str(j["index"]), j["name"], j["type"], f"{_fmt(j['lower'], unlimited='-inf')} {unit}",
                       f"{_fmt(j['upper'])} {unit}",
                       *deg, _fmt(j["velocity"], 2))
    console.print(joints)
    if info["mimic_joints"]:
        mimics = Table("mimic joint", "follows", "multiplier", "offset", title="mimic joints (not in q)")
        for m in info["mimic_joints"]:
            mimics.add_row(m["name"], m["follows"], _fmt(m["multiplier"], 3), _fmt(m["offset"], 3))
        console.print(mimics)
    if info["chains"]:
        chains = Table("chain", "base", "tip", "joints", title="chains")
        for c in info["chains"]:
            chains.add_row(c["name"], c["base_link"], c["tip_link"], ", ".join(c["joints"]))
        console.print(chains)
    if info["end_effectors"]:
        eefs = Table("end effector", "tcp", "gcp", "chain", "fingers", "preshapes", title="end effectors")
        for e in info["end_effectors"]:
            eefs.add_row(e["name"], e["tcp_link"], e["gcp_link"], e["chain"], ", ".join(e["finger_joints"]),
                         ", ".join(e["preshapes"]))
        console.print(eefs)


@robot_app.command("list")
@handles_errors
def robot_list() -> None:
    """The bundled robots."""
    from prehensile import robots

    for name in robots.available():
        typer.echo(name)


@app.command("fk", context_settings={"allow_extra_args": True, "ignore_unknown_options": True})
@handles_errors
def fk(
    ctx: typer.Context,
    robot: str = typer.Argument(..., metavar="ROBOT", help="Bundled robot name or model file path."),
    q: Optional[List[str]] = typer.Option(None, "--q", metavar="V...",
                                          help="Joint values (rad or m): --q v1 v2 ... (default neutral)."),
    link: Optional[str] = typer.Option(None, "--link", help="Only this link (default: all links)."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of a table."),
) -> None:
    """Forward kinematics: world poses of the links with the base at the origin."""
    values = extra_values(ctx.args, q, "--q", "joint values")
    model = robot_cmd.load_robot(robot)
    result = robot_cmd.link_poses(model, robot_cmd.parse_q(model, values), link)
    if as_json:
        echo_json(result)
        return
    table = Table("link", "x (m)", "y (m)", "z (m)", "roll (rad)", "pitch (rad)", "yaw (rad)",
                  title=f"{model.name} at q = [{', '.join(f'{v:.4g}' for v in result['q'])}]")
    for name, pose in result["links"].items():
        table.add_row(name, *(f"{v:.4f}" for v in pose["position"]), *(f"{v:.4f}" for v in pose["rpy"]))
    console.print(table)


@app.command("check")
@handles_errors
def check(
    scene: str = typer.Argument(..., metavar="SCENE", help="YAML scene file or bundled scene name (e.g. demo)."),
    exact: bool = typer.Option(True, "--exact/--spheres", help="Exact meshes (coal) or the sphere models."),
    as_json: bool = typer.Option(False, "--json", help="Print JSON instead of tables."),
) -> None:
    """Check every robot of a scene at its configuration: self-collisions and robot vs world.

    Exit code 0 when collision-free, 1 when something collides, 2 on bad input, 3 on a bug.
    """
    from prehensile.cli.plan_cmd import scene_path
    from prehensile.scene import check_scene, load_scene
    from prehensile.scene.files import robot_goals

    path = scene_path(scene)
    loaded = load_scene(path)
    robot_goals(path, loaded)  # a bad goal is a bad scene, here as for plan
    result = check_scene(loaded, "exact" if exact else "spheres")
    if as_json:
        echo_json({"scene": str(scene), **result.to_dict()})
    else:
        print_check(loaded.source, result)
    raise typer.Exit(EXIT_FREE if result.free else EXIT_COLLIDING)


def print_check(source: str, result) -> None:
    """Rich tables of a :class:`~prehensile.scene.check.SceneCheck`."""
    console.print(f"{source} ({result.method})", soft_wrap=True)  # a path, not a title wrapped mid-word
    table = Table("robot", "link", "touches", "kind", "depth (mm)")
    for r in result.robots:
        if r.free:
            table.add_row(r.robot, "-", "[green]free[/]", "", "")
        elif not r.contacts:  # the balls of the robot's root meet the world: not attributed to a link
            table.add_row(r.robot, "[red]?[/]", "[red]colliding[/] (no link named; use --exact)", "", "")
        for c in r.contacts:
            depth = f"{1000 * c.depth:.1f}" if result.method == "exact" else "-"  # the balls measure no depth
            table.add_row(r.robot, f"[red]{c.link}[/]", c.other, c.kind, depth)
    console.print(table)
    status = "[green]collision-free[/]" if result.free else "[bold red]colliding[/]"
    console.print(f"scene is {status}")


@app.command("demo")
@handles_errors
def demo(
    out: Path = typer.Option(Path("prehensile-demo"), "--out", help="Folder for demo.png and demo.json."),
) -> None:
    """Load every bundled robot and the bundled scene, check it and draw it."""
    from prehensile import robots
    from prehensile.scene import bundled_scene_path, check_scene, load_scene
    from prehensile.storage import atomic_write_files, check_writable, json_bytes
    from prehensile.viz import scene_image

    check_writable(out, "--out", folder=True)
    models = []
    for name in robots.available():
        model = robots.load(name)
        models.append({"name": name, "dof": model.dof, "n_links": model.n_links})
        console.print(f"loaded [bold]{name}[/]: {model.dof} dof, {model.n_links} links")
    path = bundled_scene_path("demo")
    scene = load_scene(path)
    result = check_scene(scene, "exact")
    print_check(path.name, result)
    report = {"scene": str(path), "bundled_robots": models, **result.to_dict()}
    image = scene_image(scene, result.colliding_links, result.colliding_bodies(),
                        title="prehensile demo: colliding links in red")
    png, written = atomic_write_files({out / "demo.png": image, out / "demo.json": json_bytes(report)})
    console.print(f"wrote {png} and {written}")


if __name__ == "__main__":  # pragma: no cover
    app()


# command modules register themselves on `app` / `bench_app` when imported
from prehensile.cli import bench_mbm, plan_cmd  # noqa: E402,F401
from prehensile.cli import bench_ik, ik_cmd  # noqa: E402,F401
